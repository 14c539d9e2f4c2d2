"""Landing tolerance: a match's cost when the fingers land a few millimetres off their targets."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pinchmatch.grasp.analysis import analyze_object
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.match.candidates import candidate_poses
from pinchmatch.match.felt import FeltTables, felt_cost
from landing_reference import landing, landing_pinches
from pinchmatch.match.landing import disc_offsets
from pinchmatch.match.scene import match_scene
from pinchmatch.match.search import MatchSettings
from pinchmatch.mesh.shapes import box, cylinder, sphere

SETTINGS = PinchSettings(count=200)


def given(tmp_path, name, mesh, p1, p2):
    path = tmp_path / f"{name}.stl"
    mesh.export(path)
    return candidate_poses(analyze_object(path), settings=SETTINGS,
                           given=(np.array([p1], float), np.array([p2], float)))


def matched(tangible, virtual, **options):
    scene = match_scene([tangible], [virtual], settings=MatchSettings(**options),
                        pinch_settings=SETTINGS)
    vm = scene.matches[0]
    return scene, vm


def test_the_disc_holds_the_target_and_rings_inside_the_radius():
    offsets = disc_offsets(5.0, (6, 12))
    assert len(offsets) == 19 and np.allclose(offsets[0], 0.0)
    radii = np.linalg.norm(offsets, axis=1)
    assert np.allclose(np.sort(np.unique(np.round(radii, 9))), [0.0, 2.5, 5.0])


def test_on_flat_parallel_faces_the_landing_costs_what_the_match_costs(tmp_path):
    """Box against a larger box with the same 40 mm slab, pinched off-centre (the mass offsets
    differ, so the match costs something): every landing slides both pinches alike on flat faces."""
    virtual = given(tmp_path, "small", box((60.0, 40.0, 30.0), subdivide_mm=4.0).mesh,
                    (10.0, -20.0, 0.0), (10.0, 20.0, 0.0))
    tangible = given(tmp_path, "large", box((90.0, 40.0, 50.0), subdivide_mm=4.0).mesh,
                     (25.0, -20.0, 0.0), (25.0, 20.0, 0.0))
    _, vm = matched(tangible, virtual)
    land = vm.landing
    assert vm.best.cost > 1e-3  # the mass offsets differ
    assert land.cost_nominal == pytest.approx(vm.best.cost, rel=1e-9)
    assert land.landings > 100 and land.missed == 0
    assert land.cost_worst == pytest.approx(land.cost_nominal, rel=1e-6)
    assert land.cost_mean == pytest.approx(land.cost_nominal, rel=1e-6)


def test_every_landing_is_within_the_radius_and_the_axis_tolerance(tmp_path):
    virtual = given(tmp_path, "s", sphere(20.0, faces=20000).mesh, (0.0, -20.0, 0.0),
                    (0.0, 20.0, 0.0))
    points, _ = landing_pinches(virtual, 0, False, 5.0, 14.0)
    target = virtual.pinches.points[0]
    assert np.allclose(points[0], target)
    # on the surface, within the radius (a little more: the ring is put back on the curved surface)
    assert (np.linalg.norm(points - target, axis=2) <= 5.0 * 1.05).all()
    assert np.allclose(np.linalg.norm(points, axis=2), 20.0, atol=0.05)
    axis = points[:, 1] - points[:, 0]
    cos = axis @ (target[1] - target[0]) / np.linalg.norm(axis, axis=1) / 40.0
    assert (np.degrees(np.arccos(np.clip(cos, -1, 1))) <= 14.0 + 1e-9).all()
    assert len(points) > 200


def test_a_sphere_on_a_cylinder_costs_more_off_target_and_the_worst_is_the_brute_forces(tmp_path):
    """A ball pinched across a diameter, shown on a cylinder pinched across its own, kmin left out
    (the flat direction along the cylinder would dwarf the rest): on target they agree; off target
    the widths, normals and tilt part. The worst landing of the reported pattern matches a brute
    force over a dense polar grid of the tolerance disc (both fingers, every pair within the axis
    tolerance)."""
    virtual = given(tmp_path, "ball", sphere(20.0, faces=20000).mesh, (0.0, -20.0, 0.0),
                    (0.0, 20.0, 0.0))
    tangible = given(tmp_path, "rod", cylinder(20.0, 80.0, faces=20000).mesh, (0.0, -20.0, 0.0),
                     (0.0, 20.0, 0.0))
    scene, vm = matched(tangible, virtual, weights={"kmin": 0.0})
    # the felt cost: each object's own landing table, matched through the registration
    land = vm.landing
    assert land.cost_nominal == pytest.approx(vm.best.cost_nominal, rel=1e-9)
    assert vm.best.cost == pytest.approx(land.cost_mean, rel=1e-9)  # ranked by the expected cost
    assert land.cost_nominal < 0.05  # on target: nothing a hand could tell
    assert (land.cost_worst > land.cost_nominal + 0.1 and land.cost_worst > land.cost_mean
            > land.cost_nominal)
    (T,), V = scene.objects(vm)
    # the exact closing-line pattern (fingers closing on the prop along each seen landing's line)
    # ...
    pattern = landing(T, V, vm.best, scene.model, settings=SETTINGS)
    brute = landing(T, V, vm.best, scene.model, settings=SETTINGS, rings=(8, 16, 24, 32, 40))
    assert brute.landings > 10 * pattern.landings
    assert brute.cost_worst >= pattern.cost_worst - 1e-9  # the grid holds the pattern's rings
    assert pattern.cost_worst >= 0.9 * brute.cost_worst
    assert pattern.cost_mean == pytest.approx(brute.cost_mean, rel=0.15)
    # ... and the felt cost, from the landing tables with no new geometry, agree on the worst
    # landing
    assert land.cost_worst == pytest.approx(pattern.cost_worst, rel=0.2)


def test_a_zero_radius_is_the_match_itself(tmp_path):
    virtual = given(tmp_path, "ball", sphere(20.0, faces=20000).mesh, (0.0, -20.0, 0.0),
                    (0.0, 20.0, 0.0))
    tangible = given(tmp_path, "rod", cylinder(20.0, 80.0, faces=20000).mesh, (0.0, -20.0, 0.0),
                     (0.0, 20.0, 0.0))
    scene, vm = matched(tangible, virtual, landing_mm=0.0)
    assert vm.landing.cost_worst == pytest.approx(vm.best.cost, rel=1e-9)
    (T,), V = scene.objects(vm)
    exact = landing(T, V, vm.best, scene.model, settings=SETTINGS, radius_mm=0.0)
    assert exact.cost_worst == exact.cost_mean == vm.best.cost_nominal and exact.landings == 1
    assert (exact.p_noticed_worst == pytest.approx(vm.best.p_noticed) and 0.0
            <= exact.p_noticed_worst <= 1.0)


def test_robust_ranking_puts_the_steadier_choice_first(tmp_path):
    """On a ball, every pinch lands alike; on a box, a pinch near an edge lands worse than one at
    the middle of its faces: ranked by the worst landing, a middle pinch comes first."""
    mesh = box((60.0, 40.0, 40.0), subdivide_mm=4.0).mesh
    path = tmp_path / "b.stl"
    mesh.export(path)
    obj = analyze_object(path)
    p1 = np.array([[0.0, -20.0, 0.0], [24.0, -20.0, 14.0]])
    p2 = np.array([[0.0, 20.0, 0.0], [24.0, 20.0, 14.0]])
    both = candidate_poses(obj, settings=SETTINGS, given=(p1, p2))
    ball = given(tmp_path, "ball", sphere(20.0, faces=20000).mesh, (0.0, -20.0, 0.0),
                 (0.0, 20.0, 0.0))
    scene, plain = matched(both, ball, top_k=1, distinct_mm=1.0, rank="nominal")
    _, steady = matched(both, ball, top_k=1, distinct_mm=1.0, rank="worst")
    _, expected = matched(both, ball, top_k=1, distinct_mm=1.0)
    (T,), V = scene.objects(plain)
    picks = [plain.best] + plain.alternatives
    tables = FeltTables(5.0, SETTINGS)
    felt = {c.t_pose: felt_cost(T, V, c, scene.model, tables) for c in picks}
    exact = {c.t_pose: landing(T, V, c, scene.model, settings=SETTINGS).cost_worst for c in picks}
    # near the edges a finger lands past them
    assert exact[1] > exact[0] and felt[1].worst > felt[0].worst
    assert felt[1].expected > felt[0].expected
    assert steady.best.t_pose == 0 and steady.best.cost == pytest.approx(felt[0].worst)
    assert steady.landing.cost_worst == pytest.approx(felt[0].worst)
    assert [c.t_pose for c in [steady.best] + steady.alternatives] == sorted(
        felt, key=lambda t: felt[t].worst)
    assert expected.best.t_pose == 0 and expected.best.cost == pytest.approx(felt[0].expected)


def _turned(mesh, R, t):
    out = mesh.copy()
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = R, t
    out.apply_transform(M)
    return out


def test_landings_on_a_turned_moved_copy_land_where_the_targets_are(tmp_path):
    """The virtual object is the tangible turned by a generic rotation and moved off the origin:
    every landing on it, carried into the tangible's frame by the match's placement, lands on the
    same spot of the tangible (nothing missed, nothing felt). A landing carried by the transpose of
    the rotation (or by a placement inverted) lands metres off and misses."""
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("zyx", [37.0, -24.0, 61.0], degrees=True).as_matrix()
    t = np.array([140.0, -60.0, 85.0])
    mesh = box((60.0, 40.0, 30.0), subdivide_mm=4.0).mesh
    tangible = given(tmp_path, "t", mesh, (6.0, -20.0, 3.0), (6.0, 20.0, 3.0))
    p1, p2 = R @ np.array([6.0, -20.0, 3.0]) + t, R @ np.array([6.0, 20.0, 3.0]) + t
    virtual = given(tmp_path, "v", _turned(mesh, R, t), p1, p2)
    scene, vm = matched(tangible, virtual)
    X = vm.best.transform
    assert np.allclose(X[:3, :3], R.T, atol=1e-6) and np.allclose(X[:3, 3], -R.T @ t, atol=1e-4)
    land = vm.landing
    assert land.missed == 0 and land.landings > 100
    assert land.cost_worst < 1e-3
    # an oracle that does not call the landing: the landing points, placed by hand, lie on the
    # tangible
    points, _ = landing_pinches(virtual, vm.best.v_pose, vm.best.swapped, 5.0, 14.0)
    placed = (points.reshape(-1, 3) - t) @ R  # R^T (x - t), row-wise
    assert np.abs(tangible.obj.loaded.mesh.nearest.signed_distance(placed)).max() < 1e-3


def test_a_finger_that_lands_on_nothing_is_noticed_and_counted(tmp_path):
    """A 4 mm bar felt for a wide block seen: landings a few mm beside the targets close on air.
    Each miss counts as a landing noticed for certain, in the mean and the worst."""
    from pinchmatch.match.landing import MISS_JND

    small = PinchSettings(count=200, patch_radius_mm=1.5)
    objects = []
    for name, mesh in (("block", box((60.0, 40.0, 40.0), subdivide_mm=2.0).mesh),
                       ("bar", box((4.0, 40.0, 4.0), subdivide_mm=0.5).mesh)):
        mesh.export(tmp_path / f"{name}.stl")
        obj = analyze_object(tmp_path / f"{name}.stl", patch_radius_mm=1.5)
        objects.append(candidate_poses(obj, settings=small, given=(np.array([[0.0, -20.0, 0.0]]),
                                                                    np.array([[0.0, 20.0, 0.0]]))))
    virtual, tangible = objects
    scene = match_scene([tangible], [virtual],
                        settings=MatchSettings(weights={"kmin": 0.0, "kmax": 0.0, "mass": 0.0}),
                        pinch_settings=small)
    vm = scene.matches[0]
    land = vm.landing
    assert land.missed > land.landings // 2  # most of the disc lies beside a 4 mm bar
    assert land.p_noticed_worst == 1.0 and land.as_dict()["noticeable_worst"]
    miss = float(scene.model.pool(np.array([MISS_JND ** 2] + [0.0] * 7)))
    assert land.cost_worst >= miss
    # most of the landing distribution misses
    assert land.cost_mean >= 0.8 * miss > land.cost_nominal
    # plain numbers, as JSON holds them
    assert type(land.missed) is int and type(land.landings) is int
    json.dumps(land.as_dict())
    # the closing-line reference counts them the same way
    (T,), V = scene.objects(vm)
    exact = landing(T, V, vm.best, scene.model, settings=small)
    assert (type(exact.missed) is int and exact.missed > exact.landings // 2
            and exact.p_noticed_worst == 1.0)
    assert exact.cost_worst >= miss and exact.cost_mean >= exact.missed / exact.landings * miss
    json.dumps(exact.as_dict())


def test_the_landing_weights_are_the_truncated_gaussians_masses():
    from pinchmatch.match.felt import ring_weights

    w = ring_weights(5.0)
    assert len(w) == 25 and w.sum() == pytest.approx(1.0)
    sigma = 2.5  # half the radius
    def mass(a, b):
        return np.exp(-a * a / (2 * sigma ** 2)) - np.exp(-b * b / (2 * sigma ** 2))
    total = mass(0.0, 5.0)
    assert w[0] == pytest.approx(mass(0.0, 1.25) / total)
    assert w[1:9] == pytest.approx(np.full(8, mass(1.25, 3.75) / total / 8))
    assert w[9:] == pytest.approx(np.full(16, mass(3.75, 5.0) / total / 16))


def test_the_ranked_best_is_the_brute_forces_best_over_every_pair(tmp_path):
    """Where the ranked set holds every pair (few given poses), the best by the expected cost is the
    best of a brute force over every pose pair, each scored by the same felt cost."""
    from pinchmatch.match.search import Choice, evaluate_pairs

    mesh = box((60.0, 40.0, 40.0), subdivide_mm=4.0).mesh
    mesh.export(tmp_path / "b.stl")
    t_given = (np.array([[0.0, -20.0, 0.0], [24.0, -20.0, 14.0], [-20.0, -20.0, -12.0]]),
               np.array([[0.0, 20.0, 0.0], [24.0, 20.0, 14.0], [-20.0, 20.0, -12.0]]))
    T = candidate_poses(analyze_object(tmp_path / "b.stl"), settings=SETTINGS, given=t_given)
    ball = sphere(20.0, faces=20000).mesh
    ball.export(tmp_path / "ball.stl")
    v_given = (np.array([[0.0, -20.0, 0.0], [-20.0, 0.0, 0.0], [0.0, 0.0, -20.0]]),
               np.array([[0.0, 20.0, 0.0], [20.0, 0.0, 0.0], [0.0, 0.0, 20.0]]))
    V = candidate_poses(analyze_object(tmp_path / "ball.stl"), settings=SETTINGS, given=v_given)
    scene = match_scene([T], [V], settings=MatchSettings(top_k=0, distinct_mm=0.0),
                        pinch_settings=SETTINGS)
    best = scene.matches[0].best
    it, iv = np.repeat(np.arange(len(T)), len(V)), np.tile(np.arange(len(V)), len(T))
    r = evaluate_pairs(T, V, it, iv, model=scene.model)
    tables = FeltTables(5.0, SETTINGS)
    expected = [felt_cost(T, V,
                          Choice(0, 0, int(it[k]), int(iv[k]), float(r.cost[k]), r.terms[k],
                                 bool(r.swapped[k]),
                                       r.transform[k], bool(r.flipped[k]), r.mass_delta_mm[k]),
                                       scene.model,
                          tables).expected for k in range(len(it))]
    k = int(np.argmin(expected))
    assert (best.t_pose, best.v_pose) == (int(it[k]), int(iv[k]))
    assert best.cost == pytest.approx(expected[k], rel=1e-9)
    assert best.cost_nominal == pytest.approx(float(r.cost[k]), rel=1e-9)


@pytest.mark.parametrize("thick_mm", [12.0, 6.0])
def test_a_landing_table_weighs_exactly_the_pairs_within_the_axis_tolerance(tmp_path, thick_mm):
    """A slab 12 or 6 mm thin, pinched across: landing 5 mm off on either face turns the axis by up
    to 40 (or 59) degrees; on the thinner one even one finger 2.5 mm off leaves the tolerance. The
    pairs weighed are those within 14 degrees, recomputed here from the landing points."""
    from pinchmatch.match.felt import landing_table, ring_weights

    half = thick_mm / 2.0
    block = given(tmp_path, "slab", box((60.0, thick_mm, 40.0), subdivide_mm=2.0).mesh,
                  (0.0, -half, 0.0), (0.0, half, 0.0))
    table = landing_table(block, 0, 5.0, SETTINGS)
    assert table.hit.all() and len(table.weights) == 625
    axis = table.points[:, 1] - table.points[:, 0]
    angle = np.degrees(np.arccos(np.clip(axis[:, 1] / np.linalg.norm(axis, axis=1), -1.0, 1.0)))
    assert ((table.weights > 0) == (angle <= 14.0 + 1e-9)).all()
    assert 0 < (table.weights > 0).sum() < 625
    w = ring_weights(5.0)
    i, j = np.divmod(np.arange(625), 25)
    np.testing.assert_allclose(table.weights[table.weights > 0], (w[i] * w[j])[table.weights > 0])


def test_a_landing_table_is_made_once_per_object_whichever_candidates_ask(tmp_path, monkeypatch):
    """A turned, moved, re-meshed sphere: every candidate's stored patch is the one a fresh fit at
    its contact gives (the landing tables take a target's patch from its candidate); a later match
    asking for the same contacts through other candidates (refinement's grown list) gets the tables
    made already; an object keeps its newest tables only."""
    from scipy.spatial.transform import Rotation

    import pinchmatch.match.felt as felt
    from pinchmatch.grasp.pinches import patches
    from pinchmatch.match.candidates import extend

    mesh = sphere(30.0).mesh
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = Rotation.from_euler("yxz", [-48.0, 71.0, 16.0],
                                              degrees=True).as_matrix(), [85.0, -410.0, 33.0]
    mesh.apply_transform(M)
    (tmp_path / "ball.stl").write_bytes(mesh.export(file_type="stl"))
    c = candidate_poses(analyze_object(tmp_path / "ball.stl"), settings=SETTINGS)
    context = c.obj.context
    fresh = patches(context, c.pinches.points, context.face_normals[c.pinches.face_index], SETTINGS)
    for mine, theirs in (("normals", "normal"), ("kappa_max_per_m",) * 2, ("kappa_min_per_m",) * 2,
                         ("dir_max",) * 2):
        np.testing.assert_array_equal(getattr(c.pinches,
                                              mine).reshape(getattr(fresh, theirs).shape),
                                              getattr(fresh, theirs))
    made = []
    real = felt.landing_tables
    monkeypatch.setattr(felt, "landing_tables", lambda cands, poses, *a,
                        **k: made.append(len(poses))
                        or real(cands, poses, *a, **k))
    first = FeltTables(5.0, SETTINGS)
    first.prefetch(c, range(10))
    grown = extend(c, c.pinches.subset(np.array([2, 7])))
    later = FeltTables(5.0, SETTINGS)
    for pose, same in ((len(c), 2), (len(c) + 1, 7)):
        np.testing.assert_array_equal(later.table(grown, pose).rows, first.table(c, same).rows)
    assert made == [10]
    np.testing.assert_array_equal(first.table(c, 0).rows, real(c, [0], 5.0, SETTINGS).rows[0])
    monkeypatch.setattr(felt, "LANDING_MEMO_POSES", 4)
    later.prefetch(c, range(10, 16))
    assert made == [10, 6] and len(later._store(c)) == 4
    np.testing.assert_array_equal(later.table(c, 0).rows, real(c, [0], 5.0, SETTINGS).rows[0])
    assert made == [10, 6, 1]


@pytest.mark.parametrize("turn_deg", [(0.0, 0.0), (35.0, -90.0), (-120.0, -90.0)])
def test_under_fixed_placement_the_felt_cost_turns_the_mass_offset_as_the_level_holds_the_object(
        tmp_path, turn_deg):
    """A box of the level (off its centre, so its mass pulls sideways) pinched through the hand's
    warp onto a prop posed in the level, turned about the level's up (and stood from its file's +Z):
    the felt cost on target is the match's own, and the exact reference (the mass offset turned by
    the prop's pose, worked out in the test) agrees with it on target and over the landings."""
    import trimesh
    from scipy.spatial.transform import Rotation

    from levels import tabletop_level
    from pinchmatch.grasp.analysis import analyze_prop, analyze_spec
    from pinchmatch.mesh.manifest import object_specs

    block = trimesh.creation.box(extents=(0.07, 0.03, 0.04))
    block.apply_translation([0.02, 0.015, 0.0])  # its mass off the node's origin
    tabletop_level(tmp_path / "level.glb", [("block", block, (0.35, 0.9, -0.2))])
    turn = Rotation.from_euler("y", turn_deg[0], degrees=True) * Rotation.from_euler(
        "x", turn_deg[1], degrees=True)
    (tmp_path / "props.toml").write_text(
        '[[object]]\nname = "prop"\nshape = { kind = "box", size_mm = [60, 30, 40] }\nmass_g = '
        '180\n'
        f"pose = {{ position_mm = [300.0, 900.0, -200.0], quaternion_xyzw = "
        f"{turn.as_quat().tolist()} }}\n")
    (spec,) = object_specs([tmp_path / "level.glb"], option="--virtual", split="nodes")
    V = candidate_poses(analyze_spec(spec.standing("auto")), settings=SETTINGS)
    (prop,) = object_specs([tmp_path / "props.toml"], option="--tangible")
    T = candidate_poses(analyze_prop(prop), settings=SETTINGS)
    scene = match_scene([T], [V],
                        settings=MatchSettings(placement="fixed", top_k=1,
                                               carousel_margin_jnd=100.0), pinch_settings=SETTINGS)
    vm = scene.matches[0]
    # stays in the level, the hand warped
    assert vm.best is not None and vm.best.redirect_terms is not None
    (T,), V = scene.objects(vm)  # the candidates the search grew
    # its first landing: the target itself
    pattern = landing(T, V, vm.best, scene.model, settings=SETTINGS)
    assert pattern.cost_nominal == pytest.approx(vm.best.cost_nominal, rel=1e-9, abs=1e-12)
    assert vm.landing.cost_nominal == pytest.approx(vm.best.cost_nominal, rel=1e-9, abs=1e-12)
    assert vm.landing.cost_worst == pytest.approx(pattern.cost_worst, rel=0.2)


def test_the_noticeable_criteria_over_the_landings_are_judged_in_jnd_under_any_normalisation(
        tmp_path):
    """A sphere pinched on a cylinder: the felt cost of one choice under a range-normalised model
    names the same noticeable criteria, with the same chances of being noticed, as under the JND
    model: noticing is judged in JNDs, whatever scale the ranking uses."""
    from pinchmatch.match.search import cost_model

    T = given(tmp_path, "cyl", cylinder(15.0, 60.0, faces=8000).mesh, (-15.0, 0.0, 0.0),
              (15.0, 0.0, 0.0))
    V = given(tmp_path, "ball", sphere(18.0, faces=8000).mesh, (-18.0, 0.0, 0.0), (18.0, 0.0, 0.0))
    _, vm = matched(T, V)
    choice = vm.best
    felt = {}
    for normalize in ("jnd", "range"):
        model = cost_model(MatchSettings(normalize=normalize), [T, V])
        felt[normalize] = felt_cost(T, V, choice, model, FeltTables(5.0, SETTINGS))
    assert (felt["jnd"].criteria_noticeable and felt["jnd"].criteria_noticeable
            == felt["range"].criteria_noticeable)
    assert felt["range"].p_noticed_expected == pytest.approx(
        felt["jnd"].p_noticed_expected, rel=1e-9)
