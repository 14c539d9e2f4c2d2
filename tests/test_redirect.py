"""Hand redirection: virtual objects stay where a level puts them and the hand is led to one
prop."""

import json
import math

import numpy as np
import pytest
import trimesh

from pinchmatch import (MatchSettings, PinchSettings, analyze_spec, candidate_poses, evaluate_pairs,
                        match_scene)
from pinchmatch.match.redirect import quaternion_matrix
from pinchmatch.mesh.manifest import object_specs

from conftest import assert_bad_input, run_cli
from levels import Z_UP_IN_Y_UP, standing_can, tabletop_level

SETTINGS = PinchSettings(count=200, seed=0)
PROP = ('[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, height_mm = '
        '66 }\n'
        f'pose = {{ position_mm = [0, 0, 0], quaternion_xyzw = {Z_UP_IN_Y_UP} }}\n')


@pytest.fixture(scope="module")
def kitchen(tmp_path_factory):
    """One can-sized prop at the origin; cans and a box on the table around it, near and far (m)."""
    folder = tmp_path_factory.mktemp("kitchen")
    box = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    box.apply_translation([0.0, 0.025, 0.0])
    tabletop_level(folder / "kitchen.glb", [("can_near", standing_can(), (0.02, 0.0, 0.0)),
                                           ("box_near", box, (-0.01, 0.0, 0.015)),
                                           ("can_far", standing_can(), (0.3, 0.0, -0.2)),
                                           ("can_left", standing_can(), (-0.25, 0.0, 0.05))])
    (folder / "props.toml").write_text(PROP)
    return folder


def _run(capsys, kitchen, out, *extra):
    code, _, err = run_cli(capsys, "match", "--tangible", kitchen / "props.toml", "--virtual",
                           kitchen / "kitchen.glb", "--split", "nodes", "--count", 200, "-o", out,
                           "--no-view", "--jobs", 1, *extra)
    assert code == 0, err
    return {m["virtual"]: m for m in json.loads((out / "matches.json").read_text())["matches"]}


def _angle(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return math.degrees(math.acos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1.0,
                                          1.0)))


@pytest.mark.parametrize("margin", [None, "5"])
def test_near_objects_are_redirected_far_ones_served_by_the_carousel(
    tmp_path, capsys, kitchen, margin):
    """Each object stays in the level, the hand redirected, unless no pair is within the budget (the
    far cans) or the carousel costs more than the margin less (both costs reported); with a margin
    of 5 JND both near objects stay."""
    extra = [] if margin is None else ["--carousel-margin-jnd", margin]
    matches = _run(capsys, kitchen, tmp_path / "out", "--placement", "fixed", *extra)
    modes = {name: m["redirection"]["mode"] for name, m in matches.items()}
    assert modes["can_far"] == modes["can_left"] == "carousel"
    for name in ("can_far", "can_left"):
        assert matches[name]["redirection"]["redirect_cost"] is None  # nothing within the budget
    if margin is not None:
        assert modes["can_near"] == modes["box_near"] == "redirect"
    for name, m in matches.items():
        r = m["redirection"]
        redirected, carousel = r["redirect_cost"], r["carousel_cost"]
        assert carousel is not None and r["reason"]
        stays = redirected is not None and redirected <= carousel + (0.5 if margin is None else 5.0)
        assert r["mode"] == ("redirect" if stays else "carousel")
        assert m["cost"] == pytest.approx(redirected if stays else carousel, abs=1e-5)
    R = quaternion_matrix(Z_UP_IN_Y_UP)
    for name, m in matches.items():
        r = m["redirection"]
        start = np.array(r["hand_start_mm"])
        # the default: a user standing at the prop's table, 150 mm above it (the prop stands on y =
        # 0) and 300 mm in front of the middle of its footprint
        assert r["hand_start_mm"] == [0.0, 150.0, 300.0]
        # recomputed from the reported targets and the hand's start
        recomputed = _angle(np.array(r["physical_target_mm"]) - start,
                            np.array(r["virtual_target_mm"]) - start)
        assert r["angle_deg"] == pytest.approx(recomputed, abs=0.01)
        assert r["offset_mm"] == pytest.approx(np.linalg.norm(np.subtract(r["virtual_target_mm"],
                                                                          r["physical_target_mm"])),
                                                                          abs=0.01)
        # the physical target is the tangible pose's midpoint, placed by the prop's pose
        mid = np.mean([m["tangible_pose"]["p1_mm"], m["tangible_pose"]["p2_mm"]], axis=0)
        assert np.allclose(R @ mid, r["physical_target_mm"], atol=0.01)
        if r["mode"] == "redirect":
            assert r["angle_deg"] <= 4.5 and 0.94 <= r["gain"] <= 1.14
            recomputed_gain = np.linalg.norm(np.subtract(
                r["virtual_target_mm"], start)) / np.linalg.norm(
                np.subtract(r["physical_target_mm"], start))
            assert r["gain"] == pytest.approx(recomputed_gain, abs=1e-3)
    # a can beside its twin: the hand barely turned, and it is felt as its twin is (the mass where
    # the level holds it, not where a registration would turn it: the pinch must sit on both cans
    # alike)
    assert matches["can_near"]["cost"] < min(1.0, matches["box_near"]["cost"])


def test_the_redirection_term_changes_the_choice_and_the_search_stays_exact(kitchen):
    T = [candidate_poses(analyze_spec(s), settings=SETTINGS)
         for s in object_specs([kitchen / "props.toml"], option="--tangible")]
    V = [candidate_poses(analyze_spec(s), settings=SETTINGS)
         for s in object_specs([kitchen / "kitchen.glb"], option="--virtual", split="nodes")]
    box = next(v for v in V if v.name == "box_near")
    fixed = MatchSettings(placement="fixed", refine=False, landing_mm=0.0, top_k=0)
    registered = MatchSettings(refine=False, landing_mm=0.0, top_k=0)
    chosen = match_scene(T, [box], settings=fixed).matches[0].best
    plain = match_scene(T, [box], settings=registered).matches[0].best
    # brute force over every pose pair, with the redirection: the search's best is the least
    it, iv = np.repeat(np.arange(len(T[0])), len(box)), np.tile(np.arange(len(box)), len(T[0]))
    every = evaluate_pairs(T[0], box, it, iv, redirect=fixed.redirect)
    assert chosen.cost == pytest.approx(float(every.cost.min()), rel=1e-9)
    # the registered choice, held to the fixed placement, costs more or needs more redirection
    k = int(np.flatnonzero((it == plain.t_pose) & (iv == plain.v_pose))[0])
    assert every.cost[k] >= chosen.cost
    assert (chosen.t_pose, chosen.v_pose) != (plain.t_pose, plain.v_pose)
    assert every.redirect_terms[k].sum() > chosen.redirect_terms.sum()


def test_keep_upright_still_holds_for_the_carousel(tmp_path, capsys, kitchen):
    matches = _run(capsys, kitchen, tmp_path / "out", "--placement", "fixed", "--keep-upright")
    assert all(not m["flipped"] for m in matches.values())


def test_a_pose_with_the_registered_placement_says_where_the_user_reaches_from(
    tmp_path, capsys, kitchen):
    """Registered, nothing is redirected, and the prop's pose is used, not ignored: it stands the
    prop on the level's table with the user in front (+Z), so every pinch is reached from the user's
    half or from above 35 degrees, which the reported angles say and which the prop's file frame
    alone (no pose) cannot say."""
    code, out, err = run_cli(capsys, "match", "--tangible", kitchen / "props.toml", "--virtual",
                             kitchen / "kitchen.glb", "--split", "nodes", "--count", 200, "-o",
                             tmp_path / "a", "--no-view", "--jobs", 1)
    assert code == 0, err
    assert "ignored" not in " ".join((out + err).split())
    a = {m["virtual"]: m
         for m in json.loads((tmp_path / "a" / "matches.json").read_text())["matches"]}
    assert all("redirection" not in m for m in a.values())
    R = quaternion_matrix(Z_UP_IN_Y_UP)
    for m in a.values():
        for choice in [m] + m["alternatives"]:
            pose = choice["tangible_pose"]
            h = R @ np.array(pose["approach"])  # into the level
            mid = R @ (np.array(pose["p1_mm"]) + pose["p2_mm"]) / 2.0
            elevation = math.degrees(math.asin(h[1]))
            toward = np.array([h[0], 0.0, h[2]]) @ (np.array([0.0, 150.0, 300.0]) - mid * [1, 0, 1])
            assert toward >= -1e-9 or elevation >= 35.0, (m["virtual"], elevation)


@pytest.mark.parametrize("pose, words", [
    ("pose = { position_mm = [0, 0, 0], quaternion_xyzw = [0, 0, 0, 2] }", "is not a rotation"),
    ("pose = { position_mm = [0, 0] }", "position_mm must be three numbers"),
    ("pose = { where = [0, 0, 0] }", "must be a table of position_mm"),
])
def test_a_pose_that_is_not_a_rigid_motion_is_one_line(tmp_path, capsys, kitchen, pose, words):
    props = tmp_path / "props.toml"
    props.write_text('[[object]]\nname = "p"\nshape = { kind = "cylinder", diameter_mm = 54, '
                     'height_mm = 66 }\n'
                     + pose + "\n")
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", props, "--virtual",
                           kitchen / "kitchen.glb", "--split", "nodes", "--placement", "fixed",
                           "-o", out)
    assert_bad_input(code, err, str(props), "pose", words)
    assert not out.exists()


@pytest.mark.parametrize("extra, words", [
    (["--hand-start", "0,30,0"], "lies inside the prop can_prop"),
    (["--hand-start", "0,3e,0"], "give three numbers X,Y,Z"),
    (["--hand-start", "0,0,1e9"], "within 100000 mm"),
    (["--hand-start", "0,0,99000"], "beyond an arm's reach (1000 mm)"),
    (["--max-redirect-deg", "0"], "--max-redirect-deg"),
    (["--redirect-threshold-deg", "100"], "--redirect-threshold-deg"),
])
def test_bad_redirection_options_are_one_line(tmp_path, capsys, kitchen, extra, words):
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", kitchen / "props.toml", "--virtual",
                           kitchen / "kitchen.glb", "--split", "nodes", "--placement", "fixed",
                           *extra, "-o", out)
    assert_bad_input(code, err, words)
    assert not out.exists()


def test_placement_options_under_registered_placement_are_noted_as_ignored(
    tmp_path, capsys, kitchen):
    out = tmp_path / "out"
    code, out_text, err = run_cli(capsys, "match", "--tangible", kitchen / "props.toml",
                                  "--virtual", kitchen / "kitchen.glb", "--split", "nodes",
                                  "--nodes", "can*", "--count", "60", "--hand-start", "0,150,300",
                           "--gain-range", "0.9,1.2", "--no-view", "-o", out)
    assert code in (0, 3), err
    assert ("--hand-start, --gain-range are used with --placement fixed only; "
            "ignored" in " ".join((out_text + err).split()))


def test_fixed_placement_needs_a_level(tmp_path, capsys, kitchen):
    can = tmp_path / "can.stl"
    trimesh.creation.cylinder(radius=27.0, height=66.0).export(can)
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", kitchen / "props.toml", "--virtual", can,
                           "--placement", "fixed", "-o", out)
    assert_bad_input(code, err, str(can), "not a level's node", "--split nodes")
    assert not out.exists()


def test_a_near_object_that_would_feel_wrong_in_place_goes_to_the_carousel(tmp_path, capsys):
    """A box beside a can-shaped prop can only be reached there through pinches that feel like a
    can; a box prop across the room serves it perfectly, brought by the carousel."""
    box = trimesh.creation.box(extents=(0.04, 0.04, 0.04))
    box.apply_translation([0.0, 0.02, 0.0])
    tabletop_level(tmp_path / "level.glb", [("box_near", box, (0.045, 0.0, 0.0))])
    (tmp_path / "props.toml").write_text(
        PROP + '[[object]]\nname = "box_prop"\nshape = { kind = "box", size_mm = [40, 40, 40] }\n'
        f'pose = {{ position_mm = [1000, 0, 0], quaternion_xyzw = {Z_UP_IN_Y_UP} }}\n')
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", tmp_path / "props.toml", "--virtual",
                           tmp_path / "level.glb", "--split", "nodes", "--placement", "fixed",
                           "--count", 200, "-o", out, "--no-view", "--jobs", 1)
    assert code == 0, err
    (m,) = json.loads((out / "matches.json").read_text())["matches"]
    assert m["redirection"]["mode"] == "carousel" and m["tangible"] == "box_prop"
    assert m["p_noticed"] < 0.5
    # in place, on the can, it would have been noticed: the redirected search's best
    T = [candidate_poses(analyze_spec(s), settings=SETTINGS)
         for s in object_specs([tmp_path / "props.toml"], option="--tangible")]
    (V,) = [candidate_poses(analyze_spec(s), settings=SETTINGS)
            for s in object_specs([tmp_path / "level.glb"], option="--virtual", split="nodes")]
    fixed = MatchSettings(placement="fixed", refine=False, landing_mm=0.0, top_k=0)
    it, iv = np.repeat(np.arange(len(T[0])), len(V)), np.tile(np.arange(len(V)), len(T[0]))
    in_place = evaluate_pairs(T[0], V, it, iv, redirect=fixed.redirect)
    assert float(in_place.cost[in_place.allowed].min()) >= 1.0


def test_the_hand_start_check_reads_props_in_the_run_s_units(tmp_path, capsys, kitchen):
    """A prop file in metres, its units given by --units only: the check before the run reads it so
    too."""
    can = trimesh.creation.cylinder(radius=0.027, height=0.066, sections=64)
    can.apply_translation([0.0, 0.0, 0.033])
    can.export(tmp_path / "can_m.stl")
    (tmp_path / "props.toml").write_text(f'[[object]]\nfile = "can_m.stl"\npose = {{ position_mm = '
                                         '[0, 0, 0], '
                                         f'quaternion_xyzw = {Z_UP_IN_Y_UP} }}\n')
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", tmp_path / "props.toml", "--virtual",
                           kitchen / "kitchen.glb", "--split", "nodes", "--placement", "fixed",
                           "--units", "m", "--count", 100, "-o", out, "--no-view", "--jobs", 1)
    assert code == 0, err
    code, _, err = run_cli(capsys, "match", "--tangible", tmp_path / "props.toml", "--virtual",
                           kitchen / "kitchen.glb", "--split", "nodes", "--placement", "fixed",
                           "--units", "m", "--hand-start", "0,30,0", "--count", 100, "-o",
                           tmp_path / "out2")
    assert_bad_input(code, err, "lies inside the prop")


def test_a_pose_s_quaternion_is_the_rotation_scipy_makes_of_it():
    from scipy.spatial.transform import Rotation

    q = np.array([0.3, -0.5, 0.2, 0.78])
    q /= np.linalg.norm(q)
    np.testing.assert_allclose(quaternion_matrix(q), Rotation.from_quat(q).as_matrix(), atol=1e-12)


def test_the_redirection_s_terms_are_its_angles_in_threshold_units_squared(kitchen):
    from pinchmatch.match.redirect import Redirect, redirection

    (spec,) = object_specs([kitchen / "props.toml"], option="--tangible")
    rng = np.random.default_rng(0)
    t_points, v_points = (rng.normal(0, 20, (5, 2, 3)),
                          rng.normal(0, 20, (5, 2, 3)) + [60.0, 30.0, 0.0])
    r = redirection(analyze_spec(spec), t_points, v_points,
                    Redirect(threshold_deg=4.0, axis_threshold_deg=25.0))
    start = np.array([0.0, 150.0, 300.0])
    R = quaternion_matrix(Z_UP_IN_Y_UP)
    for k in range(5):
        physical = t_points[k] @ R.T
        angle = _angle(physical.mean(axis=0) - start, v_points[k].mean(axis=0) - start)
        turn = _angle(physical[1] - physical[0], v_points[k][1] - v_points[k][0])
        np.testing.assert_allclose(r.terms[k], [(angle / 4.0) ** 2, (turn / 25.0) ** 2], rtol=1e-6)


def test_a_warm_cache_from_the_registered_placement_gives_the_cold_fixed_answer(
    tmp_path, capsys, kitchen):
    """The refined poses and the results cached by a registered run are not reused by a fixed
    one."""
    cache = tmp_path / "cache"
    _run(capsys, kitchen, tmp_path / "registered", "--cache", cache)
    warm = _run(capsys, kitchen, tmp_path / "warm", "--cache", cache, "--placement", "fixed")
    cold = _run(capsys, kitchen, tmp_path / "cold", "--no-cache", "--placement", "fixed")
    assert json.dumps(warm, sort_keys=True) == json.dumps(cold, sort_keys=True)


def test_a_hand_start_given_as_an_array_is_kept_as_a_tuple_of_floats():
    settings = MatchSettings(placement="fixed", hand_start_mm=np.array([10, -20, 300]))
    assert type(settings.hand_start_mm) is tuple and settings.hand_start_mm == (10.0, -20.0, 300.0)
    assert all(type(c) is float for c in settings.hand_start_mm)
    hash(settings)  # a frozen record holds nothing mutable


@pytest.mark.parametrize("upside_down", [False, True])
def test_fixed_placement_weighs_the_mass_where_the_level_holds_the_object(tmp_path, upside_down):
    """A prop standing off the origin, turned 35 degrees about the level's up, or upside down: each
    pair's mass offset is the virtual object's as the level holds it, seen from the prop's frame
    (recomputed here from the contacts, the centres of mass and the prop's pose), never as a
    registration would turn it; ``flipped`` says whether the prop stands otherwise than the level's
    up."""
    from scipy.spatial.transform import Rotation

    folder = tmp_path / "level"
    folder.mkdir()
    tabletop_level(folder / "level.glb", [("can", standing_can(), (0.16, 0.0, -0.06))])
    turn = Rotation.from_euler("y", 35, degrees=True) * Rotation.from_euler(
        "x", 90 if upside_down else -90,
                                                                          degrees=True)
    (folder / "props.toml").write_text(
        '[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, height_mm = '
        '66 }\n'
        f"mass_g = 120\npose = {{ position_mm = [120, {66 if upside_down else 0}, -80], "
        f"quaternion_xyzw = {turn.as_quat().tolist()} }}\n")
    settings = PinchSettings(count=60)
    (T,) = [candidate_poses(analyze_spec(s), settings=settings)
            for s in object_specs([folder / "props.toml"], option="--tangible")]
    (V,) = [candidate_poses(analyze_spec(s), settings=settings)
            for s in object_specs([folder / "level.glb"], option="--virtual", split="nodes")]
    redirect = MatchSettings(placement="fixed", max_redirect_deg=90.0).redirect
    rng = np.random.default_rng(3)
    it, iv = rng.integers(0, len(T), 40), rng.integers(0, len(V), 40)
    result = evaluate_pairs(T, V, it, iv, redirect=redirect)
    R = turn.as_matrix()
    for k in range(len(it)):
        tp = T.pinches.points[it[k]]
        vp = V.pinches.points[iv[k]]
        expected = R.T @ (V.obj.props.com_mm - vp.mean(axis=0)) - (
            T.obj.props.com_mm - tp.mean(axis=0))
        assert np.allclose(result.mass_delta_mm[k], expected, atol=1e-6)
    assert (result.flipped == upside_down).all()
    registered = evaluate_pairs(T, V, it, iv)  # brought onto the prop: the registration turns it
    assert not np.allclose(registered.mass_delta_mm, result.mass_delta_mm, atol=1.0)


def test_the_redirection_of_a_prop_standing_off_the_origin_turned_about_the_level_s_up(tmp_path):
    """The prop stands at (120, 0, -80) mm turned 35 degrees about the level's up: its targets in
    the level, the default hand start, the angle, offset and axis turn against an oracle that turns
    the contacts with scipy's Euler angles (not the pose's quaternion)."""
    from scipy.spatial.transform import Rotation

    from pinchmatch.match.redirect import Redirect, redirection

    turn = Rotation.from_euler("y", 35, degrees=True) * Rotation.from_euler("x", -90, degrees=True)
    (tmp_path / "props.toml").write_text(
        '[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, height_mm = '
        '66 }\n'
        f"pose = {{ position_mm = [120, 0, -80], quaternion_xyzw = {turn.as_quat().tolist()} }}\n")
    (spec,) = object_specs([tmp_path / "props.toml"], option="--tangible")
    rng = np.random.default_rng(4)
    t_points, v_points = (rng.normal(0, 20, (6, 2, 3)),
                          rng.normal(0, 20, (6, 2, 3)) + [180.0, 40.0, -60.0])
    r = redirection(analyze_spec(spec), t_points, v_points,
                    Redirect(threshold_deg=4.0, axis_threshold_deg=25.0))
    # the same turn, written another way
    R = Rotation.from_euler("YX", [35, -90], degrees=True).as_matrix()
    # 150 mm above the prop's table (the can stands on y = 0) and 300 mm in front of the middle of
    # its footprint
    start = np.array([120.0, 150.0, 220.0])
    np.testing.assert_allclose(r.hand_start_mm, start)
    for k in range(6):
        physical = t_points[k] @ R.T + [120.0, 0.0, -80.0]
        np.testing.assert_allclose(r.physical_target_mm[k], physical.mean(axis=0), atol=1e-9)
        angle = _angle(physical.mean(axis=0) - start, v_points[k].mean(axis=0) - start)
        axis_turn = _angle(physical[1] - physical[0], v_points[k][1] - v_points[k][0])
        assert r.angle_deg[k] == pytest.approx(angle, abs=1e-6)
        assert r.axis_turn_deg[k] == pytest.approx(axis_turn, abs=1e-6)
        assert r.offset_mm[k] == pytest.approx(np.linalg.norm(
            v_points[k].mean(axis=0) - physical.mean(axis=0)))


def _under_table(pose, normal, height, hand=(8.0, 8.0, 45.0)):
    """A pinch record of matches.json puts a fingertip, a finger or the hand below the plane (0.3 mm
    pad)."""
    tip_r, finger_r, length = hand
    p, n = np.array([pose["p1_mm"], pose["p2_mm"]]), np.array([pose["n1"], pose["n2"]])
    h = np.array(pose["approach"], dtype=float)
    tips = p + tip_r * n
    ends = tips + length * h
    return bool((tips @ normal - height < tip_r - 0.3 - 1e-6).any()
                or (ends @ normal - height < finger_r - 0.3 - 1e-6).any() or h @ normal < -1e-9)


@pytest.mark.parametrize("placement", ["fixed", "registered"])
def test_no_pinch_reaches_under_the_counter_or_the_prop_s_table(tmp_path, capsys, placement):
    """A level on a counter 900 mm up, a can prop (its file's origin at its middle, z up) posed
    where the level's can stands, turned 35 degrees: every best choice and alternative keeps
    fingertips, fingers and hand above the prop's table, and under --placement fixed the redirected
    ones above the counter too; planes worked out here from the pose and the vertices. With
    --support none the same run reaches under them."""
    from scipy.spatial.transform import Rotation

    box = trimesh.creation.box(extents=(0.05, 0.06, 0.04))
    box.apply_translation([0.0, 0.03, 0.0])
    tabletop_level(tmp_path / "level.glb", [("can", standing_can(), (0.12, 0.9, -0.08)),
                                            ("box", box, (0.19, 0.9, -0.05))])
    # mm, z up, centred on its middle
    prop = trimesh.creation.cylinder(radius=27.0, height=66.0, sections=64)
    prop.export(tmp_path / "can.stl")
    turn = Rotation.from_euler("y", 35, degrees=True) * Rotation.from_euler("x", -90, degrees=True)
    (tmp_path / "props.toml").write_text(
        '[[object]]\nfile = "can.stl"\nname = "can_prop"\n'
        f"pose = {{ position_mm = [120, 933, -80], quaternion_xyzw = {turn.as_quat().tolist()} "
        f"}}\n")
    up_in_prop = turn.inv().apply([0.0, 1.0, 0.0])
    prop_table = float((prop.vertices @ up_in_prop).min())
    under = {}
    for support in ("auto", "none"):
        out = tmp_path / f"out_{support}"
        code, _, err = run_cli(capsys, "match", "--tangible", tmp_path / "props.toml", "--virtual",
                               tmp_path / "level.glb", "--split", "nodes", "--placement", placement,
                               "--support", support, "--count", 150, "--max-redirect-deg", "30",
                               "-o", out, "--no-view", "--jobs", 1, "--no-cache")
        assert code == 0, err
        doc = json.loads((out / "matches.json").read_text())
        counted = []
        for m in doc["matches"]:
            for choice in [m] + m["alternatives"]:
                counted.append(_under_table(choice["tangible_pose"], up_in_prop, prop_table))
                if placement == "fixed" and m["redirection"]["mode"] == "redirect":
                    counted.append(_under_table(choice["virtual_pose"], np.array([0.0, 1.0, 0.0]),
                                                900.0))
        under[support] = sum(counted)
        if support == "auto":
            assert doc["tangibles"][0]["support"]["source"] == "pose"
            np.testing.assert_allclose(doc["tangibles"][0]["support"]["normal"], up_in_prop,
                                       atol=1e-6)
    assert under["auto"] == 0 and under["none"] > 0, under


def test_the_blockwise_budget_never_drops_an_allowed_pair_and_bounds_the_angle_s_term(tmp_path):
    """A prop turned about two axes and standing off the origin, virtual targets all around and some
    on the budget's edges: the blockwise pass keeps every pair the exact redirection allows, and its
    angle term is a lower bound of the exact one."""
    from scipy.spatial.transform import Rotation

    from pinchmatch.match.redirect import Redirect, pair_budget, redirection

    turn = Rotation.from_euler("zx", [28, -90], degrees=True)
    (tmp_path / "props.toml").write_text(
        '[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, height_mm = '
        '66 }\n'
        f"pose = {{ position_mm = [-140, 910, 65], quaternion_xyzw = {turn.as_quat().tolist()} "
        f"}}\n")
    (spec,) = object_specs([tmp_path / "props.toml"], option="--tangible")
    obj = analyze_spec(spec)
    rng = np.random.default_rng(11)
    t_points = rng.normal([0, 0, 33], 15, (30, 2, 3))
    redirect = Redirect(max_angle_deg=6.0, gain_range=(0.9, 1.2))
    R, p = quaternion_matrix(turn.as_quat()), np.array([-140.0, 910.0, 65.0])
    physical = (t_points.mean(axis=1) @ R.T + p)
    start = redirection(obj, t_points[:1], t_points[:1] @ R.T + p, redirect).hand_start_mm
    # virtual targets: around the physical ones, and on the edges of the angle and the gain
    near = physical[rng.integers(0, 30, 60)] + rng.normal(0, 25, (60, 3))
    edge = start + (physical[:20] - start) * 1.2
    v_mid = np.concatenate([near, edge])
    v_points = v_mid[:, None, :] + rng.normal(0, 10, (len(v_mid), 2, 3))
    v_points -= v_points.mean(axis=1, keepdims=True) - v_mid[:, None, :]
    block = pair_budget(obj, t_points.mean(axis=1), v_mid, redirect)
    term, ok = block(0, 30)
    it, iv = np.repeat(np.arange(30), len(v_mid)), np.tile(np.arange(len(v_mid)), 30)
    exact = redirection(obj, t_points[it], v_points[iv], redirect)
    allowed = exact.allowed.reshape(30, -1)
    assert allowed.any() and (~allowed).any()
    assert not (allowed & ~ok).any()  # never drops an allowed pair
    assert (term <= exact.terms[:, 0].reshape(30, -1) + 1e-12).all()
    assert (ok & ~allowed).sum() <= 0.02 * ok.size  # and keeps few that are not


def test_an_object_behind_the_prop_on_the_line_of_sight_is_not_redirected_beyond_the_gain(
    tmp_path, capsys):
    """A can 150 mm behind the prop, nearly on the line from the hand's start: within a wide angle
    budget its reach would be 40 % longer than the felt one, beyond the gain range; a wider range
    redirects it."""
    folder = tmp_path / "level"
    folder.mkdir()
    tabletop_level(folder / "kitchen.glb", [("can_behind", standing_can(), (0.0, 0.0, -0.15))])
    (folder / "props.toml").write_text(PROP)
    common = ["--placement", "fixed", "--max-redirect-deg", "15", "--carousel-margin-jnd", "100"]
    strict = _run(capsys, folder, tmp_path / "strict", *common)
    wide = _run(capsys, folder, tmp_path / "wide", *common, "--gain-range", "0.5,2")
    assert strict["can_behind"]["redirection"]["mode"] == "carousel"
    assert strict["can_behind"]["redirection"]["redirect_cost"] is None
    r = wide["can_behind"]["redirection"]
    assert r["mode"] == "redirect" and r["gain"] > 1.14 and r["angle_deg"] <= 15


def test_select_with_the_fixed_placement_ranks_props_as_the_match_serves_them(
    tmp_path, capsys, kitchen):
    """Two posed props; under --placement fixed each object's cost on the chosen prop is what the
    match serves it with there (redirected, or by the carousel when that is cheaper by more than the
    margin). The row ranks a few choices per prop among all the shelf's, the match of the chosen
    prop alone more of them on it, so the match's cost is at most the row's, or within the band of
    choices that feel the same (the more comfortable first)."""
    props = tmp_path / "shelf.toml"
    props.write_text(PROP + PROP.replace('"can_prop"', '"far_prop"').replace(
        "[0, 0, 0]", "[600, 0, -400]"))
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "select", "--tangible", props, "--virtual",
                           kitchen / "kitchen.glb", "--split", "nodes", "--placement", "fixed",
                           "-k", "1", "--count", 120, "-o", out, "--no-view", "--jobs", 1)
    assert code == 0, err
    selection = json.loads((out / "selection.json").read_text())
    assert selection["settings"]["placement"] == "fixed"
    matches = {m["virtual"]: m for m in json.loads((out / "matches.json").read_text())["matches"]}
    for entry in selection["objects"]:
        m = matches[entry["virtual"]]
        assert m["tangible"] == entry["tangible"]
        assert m["cost"] <= entry["cost"] + max(0.1, 0.05 * entry["cost"]) + 1e-6
        r = m["redirection"]
        assert r["mode"] in ("redirect", "carousel") and r["carousel_cost"] is not None
