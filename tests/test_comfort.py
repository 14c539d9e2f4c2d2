"""A prop standing on a table is pinched from where the user stands: from the user's half, or from
above; every angle re-measured here in the level's frame from the prop's pose (the code measures in
the prop's)."""

import dataclasses
import json
import math

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from pinchmatch import PinchSettings, analyze_spec, candidate_poses
from pinchmatch.config import FAR_SIDE_MIN_ELEVATION_DEG
from pinchmatch.errors import ConfigError
from pinchmatch.config import MatchSettings
from pinchmatch.match.comfort import approach_angles, comfort_score, comfortable, comfortable_poses
from pinchmatch.mesh.manifest import object_specs

from conftest import run_cli
from levels import tabletop_level

TABLE_Y_MM = 760.0
TURN = Rotation.from_euler("y", 35, degrees=True) * Rotation.from_euler("x", -90, degrees=True)
POSITION_MM = np.array([140.0, TABLE_Y_MM + 100.0, -60.0])


def _world_angles(points, h, user):
    """(elevation, azimuth) of approaches h (k, 3) at grasps (k, F, 3), both in the prop's frame,
    seen in the level (y up) from ``user``: turned by the pose first."""
    R = TURN.as_matrix()
    hw, mid = h @ R.T, points.mean(axis=1) @ R.T + POSITION_MM
    elevation = np.degrees(np.arcsin(np.clip(hw[:, 1], -1, 1)))
    flat, to_user = hw * [1, 0, 1], (user - mid) * [1, 0, 1]
    cos = np.einsum("kd,kd->k", flat, to_user) / np.linalg.norm(
        flat, axis=1) / np.linalg.norm(to_user, axis=1)
    return elevation, np.degrees(np.arccos(np.clip(cos, -1, 1)))


@pytest.fixture(scope="module")
def bottle(tmp_path_factory):
    """A bottle (z-up STL in mm, its origin at its middle) standing on a table in a y-up level, off
    the origin and turned 35 degrees about the vertical, and its candidates."""
    folder = tmp_path_factory.mktemp("bottle")
    trimesh.creation.cylinder(radius=33.0, height=200.0, sections=64).export(folder / "bottle.stl")
    (folder / "props.toml").write_text(
        '[[object]]\nfile = "bottle.stl"\nname = "bottle"\n'
        f"pose = {{ position_mm = {POSITION_MM.tolist()}, quaternion_xyzw = "
        f"{TURN.as_quat().tolist()} }}\n")
    spec = object_specs([str(folder / "props.toml")], option="--tangible")[0].standing("auto")
    prop = candidate_poses(analyze_spec(spec), settings=PinchSettings(count=200, seed=0))
    return folder, prop


def test_the_angles_are_the_level_s_seen_from_the_user(bottle):
    """Random approaches at the bottle's pinches, a user on a random side: the same angles as worked
    out in the level's frame."""
    _, prop = bottle
    rng = np.random.default_rng(5)
    h = rng.normal(size=(len(prop), 3))
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    for user in ([500.0, 900.0, 700.0], [-800.0, 1500.0, -300.0]):
        elevation, azimuth = approach_angles(prop.obj, prop.pinches.points, h, user)
        expected = _world_angles(prop.pinches.points, h, np.array(user))
        np.testing.assert_allclose(elevation, expected[0], atol=1e-7)
        np.testing.assert_allclose(azimuth, expected[1], atol=1e-6)


def test_where_the_user_stands_is_kept_per_prop_and_user_as_worked_out(bottle):
    """The user in the prop's frame, asked again for each of three users (the default among them)
    in turn: each time what the prop's pose and the default start give, never another user's."""
    from pinchmatch.config import Redirect
    from pinchmatch.match.comfort import user_in_prop
    from pinchmatch.match.redirect import hand_start

    _, prop = bottle
    default = hand_start(prop.obj.spec, Redirect(), prop.obj.loaded.mesh.vertices)
    users = [None, (500.0, 900.0, 700.0), [-800.0, 1500.0, -300.0], None, (500.0, 900.0, 700.0)]
    seen = [user_in_prop(prop.obj, u) for u in users]
    for u, got in zip(users, seen):
        world = default if u is None else np.array(u)
        np.testing.assert_allclose(got, TURN.as_matrix().T @ (world - POSITION_MM), atol=1e-9)
        assert not got.flags.writeable
    assert not np.allclose(seen[0], seen[1]) and not np.allclose(seen[1], seen[2])


def test_comfortable_is_the_near_half_or_from_above():
    elevation = np.array([0.0, 0.0, 34.9, 35.0, 89.0, -5.0])
    azimuth = np.array([90.0, 90.1, 170.0, 170.0, 180.0, 10.0])
    assert comfortable(elevation, azimuth).tolist() == [True, False, False, True, True, True]
    assert FAR_SIDE_MIN_ELEVATION_DEG == 35.0


def test_a_prop_with_no_comfortable_pose_allows_every_pose(bottle):
    """Every approach turned to come level from behind (seen from a user on the +Z side): nothing
    else is feasible, so nothing is left out; one comfortable pose among them brings the rule
    back."""
    _, prop = bottle
    user = np.array([140.0, 900.0, 5000.0])
    R = TURN.as_matrix()
    behind = R.T @ np.array([0.0, 0.0, -1.0])
    away = dataclasses.replace(prop.pinches, approach=np.tile(behind, (len(prop), 1)))
    held = dataclasses.replace(prop, pinches=away)
    assert comfortable_poses(held, user) is None
    one = away.approach.copy()
    one[3] = R.T @ np.array([0.0, 0.0, 1.0])
    ok = comfortable_poses(dataclasses.replace(prop,
                                               pinches=dataclasses.replace(away, approach=one)),
                                               user)
    assert ok is not None and ok.tolist() == [k == 3 for k in range(len(prop))]


def test_a_bad_user_position_is_refused():
    for value in ([1.0, 2.0], [0.0, math.nan, 1.0], [2e5, 0.0, 0.0]):
        with pytest.raises(ConfigError, match="--user-at"):
            MatchSettings(user_mm=value)


def _level(folder):
    mug = trimesh.creation.cylinder(radius=0.04, height=0.09, sections=48)
    mug.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    mug.apply_translation([0.0, 0.045, 0.0])
    box = trimesh.creation.box(extents=(0.05, 0.03, 0.07))
    box.apply_translation([0.0, 0.015, 0.0])
    tabletop_level(folder / "level.glb", [("mug", mug, (0.2, TABLE_Y_MM / 1000, 0.1)),
                                          ("box", box, (-0.2, TABLE_Y_MM / 1000, 0.05))])


@pytest.mark.parametrize("user", [None, "140,1000,-900"])
def test_no_pinch_comes_from_the_far_side_below_35_degrees(tmp_path, capsys, bottle, user):
    """Best choices and alternatives, registered and fixed: approaches from the far half of the prop
    come from at least 35 degrees up, seen from the default user (the hand's start, +Z) or one
    standing behind the table."""
    folder, prop = bottle
    _level(folder)
    at = np.array([float(c) for c in user.split(",")]) if user else None
    for placement in ("registered", "fixed"):
        out = tmp_path / placement
        extra = ["--user-at", user] if user else []
        code, _, err = run_cli(capsys, "match", "--tangible", folder / "props.toml", "--virtual",
                               folder / "level.glb", "--split", "nodes", "--count", 200,
                               "--placement", placement, "--no-view", "--no-figures", "--jobs", 1,
                               "--no-cache", "-o", out, *extra)
        assert code == 0, err
        doc = json.loads((out / "matches.json").read_text())
        if at is None:
            world = prop.obj.loaded.mesh.vertices @ TURN.as_matrix().T + POSITION_MM
            low, high = world.min(axis=0), world.max(axis=0)
            at = np.array([(low[0] + high[0]) / 2, low[1] + 150.0, (low[2] + high[2]) / 2 + 300.0])
        checked = 0
        for m in doc["matches"]:
            for choice in [m] + m["alternatives"]:
                pose = choice["tangible_pose"]
                points = np.array([[pose["p1_mm"], pose["p2_mm"]]])
                elevation, azimuth = _world_angles(points, np.array([pose["approach"]]), at)
                assert (azimuth[0] <= 90.0 or elevation[0] >= 35.0), (
                    m["virtual"], elevation, azimuth)
                assert choice["approach_elevation_deg"] == pytest.approx(elevation[0], abs=0.01)
                assert choice["approach_azimuth_deg"] == pytest.approx(azimuth[0], abs=0.01)
                checked += 1
        assert checked >= 4


def test_choices_that_feel_the_same_go_to_the_easiest_reach(bottle):
    """A can against its own twin: many pinches cost nothing; the best is the one a person reaches
    most easily (the comfort score is highest among the choices within the band), with its
    fingertips clear of the table."""
    from pinchmatch import Config, cost_model
    from pinchmatch.match.scene import match_one

    folder, prop = bottle
    config = Config(PinchSettings(count=200, seed=0), MatchSettings(top_k=3, refine=False))
    twin = candidate_poses(analyze_spec(object_specs(
        [str(folder / "props.toml")], option="--virtual")[0]),
                           settings=config.pinch)
    vm = match_one([prop], twin, config, model=cost_model(config.match, [prop, twin]))
    band = [c for c in [vm.best, *vm.alternatives] if c.cost <= vm.best.cost + 0.1]
    assert len(band) >= 2
    scores = [comfort_score(prop, c.t_pose) for c in band]
    assert scores[0] == max(scores)
    tips = prop.obj.context.support.heights(prop.pinches.points[vm.best.t_pose]
                                             + 8.0 * prop.pinches.normals[vm.best.t_pose]) - 8.0
    assert tips.min() >= 10.0


def test_the_summary_names_the_objects_pinched_from_behind():
    from pinchmatch.export.notes import comfort_note

    assert comfort_note([("cup", 60.0, 170.0), ("mouse", 10.0, 45.0), ("held", 0.0, None)]) is None
    note = comfort_note([("cup", 20.0, 170.0), ("mouse", 10.0, 45.0)])
    assert note.startswith("1 of 2 objects are pinched from behind") and "cup (170 deg" in note


def test_a_props_manifest_says_where_the_user_stands(tmp_path, capsys, bottle):
    """``user_mm`` at a props manifest's top level is the run's user (as --user-at, which overrides
    it): the approaches are judged from there; a bad one, or two manifests that disagree, are one
    line each."""
    folder, prop = bottle
    _level(folder)
    behind = [140.0, 1000.0, -900.0]
    manifest = tmp_path / "props.toml"
    manifest.write_text(f"user_mm = {behind}\n" + (folder / "props.toml").read_text().replace(
        'file = "bottle.stl"', f'file = "{folder / "bottle.stl"}"'))
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", manifest, "--virtual",
                           folder / "level.glb", "--split", "nodes", "--count", 200, "--no-view",
                           "--no-figures", "--jobs", 1, "--no-cache", "-o", out)
    assert code == 0, err
    doc = json.loads((out / "matches.json").read_text())
    assert doc["settings"]["user_mm"] == behind
    for m in doc["matches"]:
        pose = m["tangible_pose"]
        elevation, azimuth = _world_angles(np.array([[pose["p1_mm"], pose["p2_mm"]]]),
                                           np.array([pose["approach"]]), np.array(behind))
        assert m["approach_azimuth_deg"] == pytest.approx(azimuth[0], abs=0.01)
        assert azimuth[0] <= 90.0 or elevation[0] >= 35.0
    bad = tmp_path / "bad.toml"
    bad.write_text('user_mm = [1, "a", 3]\n' + manifest.read_text().split("\n", 1)[1])
    code, stdout, err = run_cli(capsys, "match", "--tangible", bad, "--virtual",
                                folder / "level.glb", "-o", tmp_path / "bad_out")
    assert (code == 2 and "user_mm" in err and "Traceback" not in err
            and len(err.strip().splitlines()) == 1), err
    other = tmp_path / "other.toml"
    other.write_text("user_mm = [0, 0, 900]\n"
                     + manifest.read_text().split("\n", 1)[1].replace('"bottle"', '"b2"'))
    code, stdout, err = run_cli(capsys, "match", "--tangible", manifest, other, "--virtual",
                                folder / "level.glb", "-o", tmp_path / "two_out")
    assert code == 2 and "puts the user elsewhere" in err, err
