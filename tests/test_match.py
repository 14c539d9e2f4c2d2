import dataclasses
import itertools
import json

import numpy as np
import pytest
import trimesh

from pinchmatch.errors import ConfigError
from pinchmatch.match import search as search_module
from pinchmatch.grasp.analysis import analyze_object
from pinchmatch.cli.commands import example_mesh_path
from pinchmatch.match.cost import CRITERIA, DEFAULT_CRITERIA, separable_terms
from pinchmatch.match.scene import assign_one_to_one, match_scene
from pinchmatch.match.search import MatchSettings, cost_model, evaluate_pairs
from pinchmatch.match.candidates import candidate_poses
from pinchmatch.match.reference import reference_pose
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.mesh.manifest import ObjectSpec
from pinchmatch.mesh import vessels
from pinchmatch.mesh.shapes import ellipsoid
from pinchmatch.runner.study import PARTS, TANGIBLE_HEIGHTS_MM, run_study

from conftest import random_rigid, run_cli, transformed


@pytest.fixture(scope="module")
def example():
    return candidate_poses(analyze_object(example_mesh_path()), settings=PinchSettings(count=300))


@pytest.fixture(scope="module")
def study(demo):
    return demo.study


def moved_copy(tmp_path, mesh, seed, name):
    """The mesh rotated, translated and re-triangulated (every triangle split in four)."""
    R, t = random_rigid(seed)
    copy = transformed(mesh.subdivide(), R, t)
    path = tmp_path / name
    copy.export(path)
    return path, R, t


def patch_disagreement_mm(tangible, virtual, choice, radius_mm=8.0):
    """Largest distance from the registered virtual surface to the tangible's, over both contact
    patches."""
    X = choice.transform
    ctx = virtual.obj.context
    worst = 0.0
    for k in range(2):
        near = ctx.tree.query_ball_point(virtual.pinches.points[choice.v_pose, k], radius_mm)
        moved = ctx.sample.points[near] @ X[:3, :3].T + X[:3, 3]
        _, distance, _ = tangible.obj.context.closest_points(moved)
        worst = max(worst, float(distance.max()))
    return worst


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_an_object_matched_against_a_moved_retriangulated_copy_gets_the_same_place(
    tmp_path, example, seed):
    """The copy's candidates are the original's pinches carried over, then snapped, checked and
    described again on the re-triangulated copy: the same places exist on both, at new triangles."""
    path, R, t = moved_copy(tmp_path, trimesh.load(example_mesh_path()), seed, "copy.stl")
    p = example.pinches.points @ R.T + t
    copy = candidate_poses(analyze_object(path, up="z"), given=(p[:, 0], p[:, 1]))
    # a few sit on a rule's boundary (friction cone, clearance)
    assert len(copy) >= 0.95 * len(example)
    scene = match_scene([example], [copy])
    best = scene.matches[0].best
    # refinement may add poses on the example
    (tangible,), virtual = scene.objects(scene.matches[0])
    assert best.cost < 1e-4  # in JND: nothing a hand could tell
    assert patch_disagreement_mm(tangible, virtual, best) < 0.5
    assert abs(np.linalg.det(best.transform[:3, :3]) - 1.0) < 1e-9
    # the pinch lines meet: midpoints coincide
    vp = virtual.pinches.points[best.v_pose] @ best.transform[:3, :3].T + best.transform[:3, 3]
    np.testing.assert_allclose(vp.mean(axis=0), tangible.pinches.points[best.t_pose].mean(axis=0),
                               atol=1e-6)


def test_an_ellipsoid_registers_onto_its_moved_copy_sampled_anew(tmp_path):
    """Poses sampled independently on both: the best pair still puts the surfaces together."""
    mesh = ellipsoid((40.0, 25.0, 15.0), faces=5000).mesh
    mesh.export(tmp_path / "e.stl")
    original = candidate_poses(analyze_object(tmp_path / "e.stl"),
                               settings=PinchSettings(count=1000))
    path, R, t = moved_copy(tmp_path, mesh, 7, "copy.stl")
    copy = candidate_poses(analyze_object(path), settings=PinchSettings(count=1000, seed=3))
    scene = match_scene([original], [copy])
    (tangible,), virtual = scene.objects(scene.matches[0])
    # refinement lowers the felt cost; the registered patches still agree within a millimetre
    assert patch_disagreement_mm(tangible, virtual, scene.matches[0].best) < 1.0


def test_a_pose_against_itself_costs_nothing_and_registers_to_the_identity(example):
    idx = np.arange(len(example))
    result = evaluate_pairs(example, example, idx, idx,
                            model=cost_model(MatchSettings(), [example]))
    np.testing.assert_allclose(result.cost, 0.0, atol=1e-9)
    np.testing.assert_allclose(result.transform, np.broadcast_to(np.eye(4), result.transform.shape),
                               atol=1e-6)
    assert not result.flipped.any()


def test_swapping_p1_and_p2_in_the_inputs_changes_no_cost(example, tmp_path):
    obj = example.obj
    p = example.pinches.points[:40]
    given = candidate_poses(obj, given=(p[:, 0], p[:, 1]))
    swapped = candidate_poses(obj, given=(p[:, 1], p[:, 0]))
    model = cost_model(MatchSettings(), [example])
    it = np.repeat(np.arange(len(example)), len(given))
    iv = np.tile(np.arange(len(given)), len(example))
    a = evaluate_pairs(example, given, it, iv, model=model)
    b = evaluate_pairs(example, swapped, it, iv, model=model)
    np.testing.assert_allclose(a.cost, b.cost, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(a.transform, b.transform, atol=1e-6)
    assert (a.swapped != b.swapped).all()


def order_free_mm(a, b) -> float:
    """The test's own oracle for two pinches (2, 3): the larger contact displacement, in the better
    order."""
    direct = max(np.linalg.norm(a[0] - b[0]), np.linalg.norm(a[1] - b[1]))
    crossed = max(np.linalg.norm(a[0] - b[1]), np.linalg.norm(a[1] - b[0]))
    return float(min(direct, crossed))


def test_pinch_distance_with_literals():
    a = np.array([[0.0, 0.0, 0.0], [40.0, 0.0, 0.0]])
    assert search_module.pinch_distance(a[None], a)[0] == 0.0
    # the same pinch, fingers swapped
    assert search_module.pinch_distance(a[::-1][None], a)[0] == 0.0
    moved = a + [0.0, 3.0, 0.0]
    assert search_module.pinch_distance(moved[None], a)[0] == pytest.approx(3.0)
    assert search_module.pinch_distance(moved[::-1][None], a)[0] == pytest.approx(3.0)
    one = a.copy()
    one[1] += [0.0, 0.0, 5.0]  # one contact 5 mm away: the larger displacement
    assert search_module.pinch_distance(one[::-1][None], a)[0] == pytest.approx(5.0)
    # in the direct order too
    assert search_module.pinch_distance(one[None], a)[0] == pytest.approx(5.0)


@pytest.mark.parametrize("keep_upright", [False, True])
@pytest.mark.parametrize("normalize", ["jnd", "range"])
def test_the_pooled_search_finds_the_exact_minimum(example, tmp_path, monkeypatch, keep_upright,
                                                   normalize):
    mesh = ellipsoid((30.0, 22.0, 14.0), faces=1300).mesh
    mesh.export(tmp_path / "e.stl")
    virtual = candidate_poses(analyze_object(tmp_path / "e.stl"), settings=PinchSettings(count=120))
    monkeypatch.setattr(search_module, "MIN_POOL", 7)  # force the pool to grow
    monkeypatch.setattr(search_module, "MAX_POOL", 7)
    # the search is exact on target: ranked on target here (--rank nominal)
    settings = MatchSettings(normalize=normalize, keep_upright=keep_upright, top_k=4,
                             distinct_mm=10.0, rank="nominal")
    scene = match_scene([example], [virtual], settings=settings)
    # with the refined poses: exact within them
    (example,), virtual = scene.objects(scene.matches[0])
    it = np.repeat(np.arange(len(example)), len(virtual))
    iv = np.tile(np.arange(len(virtual)), len(example))
    brute = evaluate_pairs(example, virtual, it, iv, model=scene.model, keep_upright=keep_upright)
    vm = scene.matches[0]
    assert vm.best.cost == pytest.approx(brute.cost.min(), rel=1e-9, abs=1e-12)
    assert scene.cost_matrix[0, 0] == pytest.approx(brute.cost.min(), rel=1e-9, abs=1e-12)
    if keep_upright:
        assert not vm.best.flipped and not any(a.flipped for a in vm.alternatives)
    picks = [vm.best] + vm.alternatives
    assert len(picks) == 5
    costs = [c.cost for c in picks]
    assert costs == sorted(costs)
    for a, b in itertools.combinations(picks, 2):  # alternatives are different places
        dt = order_free_mm(example.pinches.points[a.t_pose], example.pinches.points[b.t_pose])
        dv = order_free_mm(virtual.pinches.points[a.v_pose], virtual.pinches.points[b.v_pose])
        assert dt >= 10.0 or dv >= 10.0
    # the second pick is the cheapest pair that is not a near duplicate of the first
    far = np.array([
        order_free_mm(example.pinches.points[i], example.pinches.points[vm.best.t_pose]) >= 10.0
        or order_free_mm(virtual.pinches.points[j], virtual.pinches.points[vm.best.v_pose]) >= 10.0
        for i, j in zip(it, iv)
    ])
    assert picks[1].cost == pytest.approx(brute.cost[far].min(), rel=1e-9)


def test_kept_upright_an_upside_down_copy_grows_past_pools_of_flipped_pairs(
    example, tmp_path, monkeypatch):
    # the cheapest separable pairs of the example against itself turned over are its own places,
    # which register only upside down: a 5-pair pool holds nothing allowed and must grow
    R = trimesh.transformations.rotation_matrix(np.pi, [1.0, 0.0, 0.0])[:3, :3]
    path = tmp_path / "over.stl"
    transformed(trimesh.load(example_mesh_path(), force="mesh"), R, np.zeros(3)).export(path)
    virtual = candidate_poses(analyze_object(path), settings=PinchSettings(count=300))
    monkeypatch.setattr(search_module, "MIN_POOL", 5)
    monkeypatch.setattr(search_module, "MAX_POOL", 5)
    settings = MatchSettings(keep_upright=True, top_k=0, rank="nominal")
    scene = match_scene([example], [virtual], settings=settings)
    # with the refined poses: exact within them
    (example,), virtual = scene.objects(scene.matches[0])
    it = np.repeat(np.arange(len(example)), len(virtual))
    iv = np.tile(np.arange(len(virtual)), len(example))
    brute = evaluate_pairs(example, virtual, it, iv, model=scene.model, keep_upright=True)
    free = evaluate_pairs(example, virtual, it, iv, model=scene.model, keep_upright=False)
    assert free.cost.min() < brute.cost.min()  # upright costs something here
    assert np.isfinite(brute.cost.min())
    assert scene.cost_matrix[0, 0] == pytest.approx(brute.cost.min(), rel=1e-9, abs=1e-12)
    best = scene.matches[0].best
    assert best.cost == pytest.approx(brute.cost.min(), rel=1e-9, abs=1e-12) and not best.flipped


def with_mass(candidates, mass_g: float):
    """The same candidates, their object given a mass (as a manifest's ``mass_g`` would)."""
    spec = candidates.obj.spec or ObjectSpec(str(candidates.obj.loaded.path))
    obj = dataclasses.replace(candidates.obj, spec=dataclasses.replace(spec, mass_g=mass_g))
    return dataclasses.replace(candidates, obj=obj)


@pytest.mark.parametrize("tight", [False, True])
@pytest.mark.parametrize("pooling", ["quick", "sum"])
def test_the_pooled_lower_bound_holds_for_every_pair_with_unequal_masses(
    example, tmp_path, pooling, tight):
    """The bound the search pools by (the separable sum's, or the pooled one) never exceeds a pair's
    exact cost, whatever the mass ratio: every pair the pool leaves out costs at least its tau, and
    each pooled pair's bound is at most its cost."""
    from pinchmatch.match.candidates import mass_ratio

    mesh = ellipsoid((30.0, 22.0, 14.0), faces=1300).mesh
    mesh.export(tmp_path / "e.stl")
    virtual = candidate_poses(analyze_object(tmp_path / "e.stl"), settings=PinchSettings(count=60))
    rng = np.random.default_rng(11)
    ratios = []
    for m_t, factor in zip(rng.uniform(20.0, 400.0, 4), [0.1, 10.0, *rng.uniform(0.1, 10.0, 2)]):
        T, V = with_mass(example, float(m_t)), with_mass(virtual, float(m_t * factor))
        ratios.append(mass_ratio(T, V))
        model = cost_model(MatchSettings(pooling=pooling), [T, V])
        it, iv, bound, tau = search_module.pool_pairs(T, V, model, 50, 64, tight)
        exact = evaluate_pairs(T, V, np.repeat(np.arange(len(T)), len(V)),
                               np.tile(np.arange(len(V)), len(T)), model=model).cost.reshape(
                                   len(T), len(V))
        left_out = np.ones(exact.shape, dtype=bool)
        left_out[it, iv] = False
        assert (exact[left_out] >= tau * (1 - 1e-9)).all(), (m_t, factor)
        assert (bound <= exact[it, iv] * (1 + 1e-9) + 1e-12).all()
    assert min(ratios) == pytest.approx(0.1) and max(ratios) == pytest.approx(10.0)


@pytest.mark.parametrize("tight_after", [0, search_module.TIGHT_AFTER])
@pytest.mark.parametrize("pooling", ["quick", "sum"])
def test_the_pooled_search_with_masses_on_both_sides_equals_brute_force(
    example, tmp_path, monkeypatch, pooling,
                                                                        tight_after):
    mesh = ellipsoid((30.0, 22.0, 14.0), faces=1300).mesh
    mesh.export(tmp_path / "e.stl")
    virtual = with_mass(candidate_poses(analyze_object(tmp_path / "e.stl"),
                                        settings=PinchSettings(count=120)), 10.0)
    tangible = with_mass(example, 100.0)
    monkeypatch.setattr(search_module, "MIN_POOL", 7)  # force the pool to grow
    monkeypatch.setattr(search_module, "MAX_POOL", 7)
    # 0: every pool by the pooled bound
    monkeypatch.setattr(search_module, "TIGHT_AFTER", tight_after)
    scene = match_scene([tangible], [virtual],
                        settings=MatchSettings(pooling=pooling, top_k=2, distinct_mm=10.0,
                                                                      rank="nominal"))
    # with the refined poses: exact within them
    (tangible,), virtual = scene.objects(scene.matches[0])
    it = np.repeat(np.arange(len(tangible)), len(virtual))
    iv = np.tile(np.arange(len(virtual)), len(tangible))
    brute = evaluate_pairs(tangible, virtual, it, iv, model=scene.model)
    best = scene.matches[0].best
    assert best.cost == pytest.approx(brute.cost.min(), rel=1e-9, abs=1e-12)
    k = int(np.argmin(brute.cost))
    assert (best.t_pose, best.v_pose) == (int(it[k]), int(iv[k]))
    unweighed = match_scene([example], [with_mass(virtual, None)],
                            settings=MatchSettings(pooling=pooling, rank="nominal"))
    # the masses change the answer's cost
    assert unweighed.matches[0].best.cost != pytest.approx(best.cost)


def test_a_ball_against_a_box_is_bounded_closely_by_the_pooled_bound(tmp_path):
    """Every pose of a ball alike, the width apart: one criterion dominates, where the separable
    sum's bound lies a third below the cost and the pooled bound within a few per cent of it; a
    search that has to evaluate nearly every pair by the first closes by the second with few."""
    from pinchmatch.match.cost import pair_cost_blocks, pooled_bound_blocks
    from pinchmatch.mesh.shapes import box, sphere

    sphere(30.0, faces=2000).mesh.export(tmp_path / "ball.stl")
    box((60.0, 40.0, 20.0), subdivide_mm=6.0).mesh.export(tmp_path / "block.stl")
    ball, block = (candidate_poses(analyze_object(tmp_path / f"{n}.stl"),
                                   settings=PinchSettings(count=80))
                   for n in ("ball", "block"))
    model = cost_model(MatchSettings(), [ball, block])
    exact = evaluate_pairs(ball, block, np.repeat(np.arange(len(ball)), len(block)),
                           np.tile(np.arange(len(block)), len(ball)),
                           model=model).cost.reshape(len(ball), len(block))
    (_, loose, _), = pair_cost_blocks(ball.table, block.table, model, block_rows=len(ball),
                                      with_swapped=False)
    (_, pooled), = pooled_bound_blocks(ball.table, block.table, model, block_rows=len(ball))
    assert (pooled <= exact * (1 + 1e-9)).all()
    assert (np.median(pooled / exact) > 0.95
            and np.median(model.bound_from_separable(loose) / exact) < 0.75)
    it, iv, _, tau = search_module.pool_pairs(ball, block, model, 200, 64, True)
    assert tau > exact.min()  # 200 of 6,400 pairs prove the best


def test_the_mass_lower_bound_never_exceeds_the_exact_mass_term(example, tmp_path):
    mesh = ellipsoid((30.0, 22.0, 14.0), faces=1300).mesh
    mesh.export(tmp_path / "e.stl")
    virtual = candidate_poses(analyze_object(tmp_path / "e.stl"), settings=PinchSettings(count=80))
    model = cost_model(MatchSettings(), [example, virtual])
    it = np.repeat(np.arange(len(example)), len(virtual))
    iv = np.tile(np.arange(len(virtual)), len(example))
    exact = evaluate_pairs(example, virtual, it, iv, model=model)
    v_rows = virtual.table[iv]
    v_rows = np.where(exact.swapped[:, None, None], v_rows[:, ::-1], v_rows)
    bound = separable_terms(example.table[it], v_rows, model)[:, 7]
    assert (bound <= exact.terms[:, 7] + 1e-9).all()
    assert (exact.terms[:, 7] > bound + 1e-3).any()  # the bound is not the exact term


def brute_force_assignment(cost):
    m, n = cost.shape
    best = (-1, np.inf, None)
    for targets in itertools.product(range(-1, n), repeat=m):
        used = [t for t in targets if t >= 0]
        if (len(used) != len(set(used))
            or any(not np.isfinite(cost[j, t]) for j, t in enumerate(targets) if t >= 0)):
            continue
        served, total = len(used), sum(cost[j, t] for j, t in enumerate(targets) if t >= 0)
        if served > best[0] or (served == best[0] and total < best[1] - 1e-12):
            best = (served, total, targets)
    return best


@pytest.mark.parametrize("shape", [(3, 3), (4, 2), (2, 4), (5, 3)])
@pytest.mark.parametrize("seed", range(4))
def test_one_to_one_assignment_equals_brute_force(shape, seed):
    rng = np.random.default_rng(seed)
    cost = rng.uniform(0, 10, shape)
    cost[rng.random(shape) < 0.2] = np.inf  # forbidden pairs (no upright registration)
    assigned = assign_one_to_one(cost)
    served, total, _ = brute_force_assignment(cost)
    used = assigned[assigned >= 0]
    assert len(set(used.tolist())) == len(used) == served
    assert sum(cost[j, t] for j, t in enumerate(assigned) if t >= 0) == pytest.approx(total)


def test_one_to_one_in_a_scene_gives_each_tangible_to_one_virtual_object(example, tmp_path):
    mesh = ellipsoid((30.0, 22.0, 14.0), faces=1300).mesh
    mesh.export(tmp_path / "e.stl")
    egg = candidate_poses(analyze_object(tmp_path / "e.stl"), settings=PinchSettings(count=80))
    scene = match_scene([example, egg], [egg, example, egg],
                        settings=MatchSettings(one_to_one=True, top_k=1))
    tangibles = [vm.best.tangible if vm.best else None for vm in scene.matches]
    assert sorted(t for t in tangibles if t is not None) == [0, 1]
    # each object goes to its own kind
    assert tangibles[1] == 0 and 1 in (tangibles[0], tangibles[2])
    left = [vm for vm in scene.matches if vm.best is None]
    assert len(left) == 1 and "another virtual object" in left[0].reason
    for vm in scene.matches:
        if vm.best:
            assert all(a.tangible == vm.best.tangible for a in vm.alternatives)


def test_the_reference_of_an_object_on_itself_is_the_same_pinch_at_no_cost(example):
    model = cost_model(MatchSettings(), [example])
    ref = reference_pose(example, 5, example, model)
    assert ref.reason is None and ref.cost == pytest.approx(0.0, abs=1e-6)
    np.testing.assert_allclose(ref.pinches.points[0], example.pinches.points[5], atol=1e-6)


def test_study_vo1_maps_each_part_to_itself_and_ours_never_costs_more_than_ref(study):
    rows = study.rows
    assert len(rows) == 18
    assert {(r["tangible_part"], r["virtual"]) for r in rows} == {
        (p, v) for p in PARTS for v in range(1, 7)}
    for r in rows:
        if r["virtual"] == 1:
            assert r["ours"]["part"] == r["tangible_part"]
            assert (r["ours"]["height_mm"]
                    == pytest.approx(TANGIBLE_HEIGHTS_MM[PARTS.index(r["tangible_part"])], abs=0.5))
            assert r["ours"]["cost"] == pytest.approx(0.0, abs=1e-6) and not r["ours"]["flipped"]
        # the stacks share their axis: the fingers always meet the VO
        assert r["ref"]["cost"] is not None
        assert r["ours"]["cost"] <= r["ref"]["cost"] + 1e-6
        # each is optimal for its own model
        assert r["paper"]["cost_paper"] <= r["ours"]["cost_paper"] + 1e-6
        assert r["paper"]["cost_paper"] <= r["ref"]["cost_paper"] + 1e-6


def test_study_flips_a_virtual_object_where_the_part_sits_at_the_other_end(study):
    # VO4 (cube / cone / cylinder) has the cylinder on top: the cylinder pose is found there,
    # flipped
    row = next(r for r in study.rows if r["tangible_part"] == "cylinder" and r["virtual"] == 4)
    assert row["ours"]["part"] == "cylinder" and row["ours"]["flipped"]


def test_match_cli_writes_matches_json(tmp_path, capsys):
    mesh = ellipsoid((30.0, 22.0, 14.0), faces=1300).mesh
    mesh.export(tmp_path / "e.stl")
    out = tmp_path / "out"
    code, stdout, err = run_cli(capsys, "match", "--tangible", example_mesh_path(), "--virtual",
                                tmp_path / "e.stl",
                            example_mesh_path(), "--count", 150, "--top-k", 2, "--figures", "-o",
                            out)
    assert code == 0, err
    doc = json.loads((out / "matches.json").read_text())
    assert doc["schema"] == "pinchmatch.matches/1" and doc["settings"]["top_k"] == 2
    assert len(doc["matches"]) == 2 and len(doc["cost_matrix"]["values"]) == 2
    m = doc["matches"][1]
    for key in ("virtual", "tangible", "cost", "criteria", "tangible_pose", "virtual_pose",
                "transform_virtual_to_tangible", "position_mm", "quaternion_xyzw", "flipped",
                "contact_offset_mm", "alternatives", "reference"):
        assert key in m
    assert set(m["criteria"]) == set(DEFAULT_CRITERIA)
    assert 0.0 <= m["p_noticed"] <= 1.0 and m["noticeable"] == (m["p_noticed"] >= 0.5)
    assert all({"contribution", "jnd", "noticeable", "weight"} <= set(v)
               for v in m["criteria"].values())
    assert len(m["alternatives"]) == 2
    T = np.array(m["transform_virtual_to_tangible"])
    assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0, abs=1e-5)
    assert m["reference"]["cost"] == pytest.approx(0.0, abs=1e-3)  # the example on itself
    assert "virtual" in stdout and "wrote" in stdout
    # the summary names every object with its pose count, and every output
    for obj in doc["tangibles"] + doc["virtuals"]:
        assert obj["name"] in stdout
    assert (f"{len(doc['matches'])} glTF scenes" in stdout and "figures" in stdout
            and "index.html" in stdout)
    assert sorted(p.name for p in (out / "scenes").glob("*.glb")) == ["e.glb", "example_prop.glb"]
    assert (out / "figures" / "cost_matrix.png").is_file() and (out / "index.html").is_file()


def test_match_cli_json_quiet_and_skips(tmp_path, capsys):
    args = ["match", "--tangible", example_mesh_path(), "--virtual", example_mesh_path(), "--count",
            120]
    code, stdout, err = (run_cli(capsys, *args, "-o", tmp_path / "a", "--json", "--no-view",
                                 "--no-figures"))
    assert code == 0, err
    # stdout: the document only
    assert json.loads(stdout) == json.loads((tmp_path / "a" / "matches.json").read_text())
    assert (tmp_path / "a" / "scenes" / "example_prop.glb").is_file()
    assert (not (tmp_path / "a" / "index.html").exists()
            and not (tmp_path / "a" / "figures").exists())
    code, stdout, err = run_cli(capsys, *args, "-o", tmp_path / "b", "-q")
    assert code == 0 and stdout == "" and err == ""
    assert (tmp_path / "b" / "index.html").is_file()
    # PNG figures only when asked: the page draws the bars
    assert not (tmp_path / "b" / "figures").exists()
    code, _, err = run_cli(capsys, *args, "-o", tmp_path / "c", "-q", "--figures", "--no-figures")
    assert code == 2 and "--figures and --no-figures" in err


def test_match_cli_paper_criteria_and_given_tangible_poses(tmp_path, capsys):
    poses = tmp_path / "poses.json"
    poses.write_text(json.dumps([{"p1_mm": [-20, 0, 20], "p2_mm": [20, 0, 20]},
                                 {"p1_mm": [-20, 0, 60], "p2_mm": [20, 0, 60]}]))
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", example_mesh_path(), "--tangible-poses",
                           poses,
                       "--virtual", example_mesh_path(), "--count", 100, "--criteria", "paper",
                       "--normalize", "range", "-q", "-o", out)
    assert code == 0, err
    doc = json.loads((out / "matches.json").read_text())
    assert doc["tangibles"][0]["pose_count"] == 2 and doc["tangibles"][0]["poses_given"]
    assert set(doc["matches"][0]["criteria"]) == set(CRITERIA[:7])
    assert doc["matches"][0]["tangible_pose"]["index"] in (0, 1)


@pytest.mark.parametrize("argv, message", [
    (["--weights", "widht=1"], "did you mean 'width'"),
    (["--weights", "width=-2"], "needs a weight of 0 or more"),
    (["--criteria", "paper", "--weights", "mass=1"], "not part of --criteria paper"),
    (["--normalize", "zscore"], "invalid choice"),
    (["--top-k", "-1"], "--top-k"),
])
def test_match_cli_refuses_bad_options(tmp_path, capsys, argv, message):
    code, _, err = run_cli(capsys, "match", "--tangible", example_mesh_path(), "--virtual",
                           example_mesh_path(),
                       *argv, "-o", tmp_path / "out")
    assert code == 2 and message in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_match_cli_refuses_bad_pose_files(tmp_path, capsys):
    broken = tmp_path / "broken.json"
    broken.write_text('[{"p1_mm": [0, 0')
    code, _, err = run_cli(capsys, "match", "--tangible", example_mesh_path(), "--tangible-poses",
                           broken,
                       "--virtual", example_mesh_path(), "-o", tmp_path / "out")
    assert code == 2 and "broken.json: not valid JSON" in err
    infeasible = tmp_path / "infeasible.json"  # both fingers on the same face
    infeasible.write_text(json.dumps([{"p1_mm": [-20, -5, 60], "p2_mm": [-20, 5, 60]}]))
    code, _, err = run_cli(capsys, "match", "--tangible", example_mesh_path(), "--tangible-poses",
                           infeasible,
                       "--virtual", example_mesh_path(), "-o", tmp_path / "out")
    assert code == 2 and "infeasible.json: none of the 1 given poses is feasible" in err
    code, _, err = run_cli(capsys, "match", "--tangible", example_mesh_path(), example_mesh_path(),
                       "--tangible-poses", infeasible, "--virtual", example_mesh_path(), "-o",
                       tmp_path / "out")
    assert code == 2 and "got 1 files for 2 objects" in err
    assert not (tmp_path / "out").exists()


def test_demo_writes_the_study_and_the_scene(demo):
    study = json.loads((demo.out / "study.json").read_text())
    assert study["schema"] == "pinchmatch.study/1" and len(study["rows"]) == 18
    row = study["rows"][0]
    assert {"tangible_part", "virtual", "virtual_order", "ours", "paper", "ref"} <= set(row)
    assert {"part", "height_mm", "flipped", "cost", "cost_paper"} <= set(row["ours"])
    scene = json.loads((demo.out / "matches.json").read_text())
    assert len(scene["matches"]) == 6
    assert "cylinder/cube/cone" in demo.stdout
    flipped = sum(m["flipped"] for m in scene["matches"])
    assert (flipped and f"{flipped} of 6 placements turn the virtual object upside "
                        "down" in " ".join(demo.stdout.split()))
    assert "--keep-upright keeps every one upright" in " ".join(demo.stdout.split())


def test_demo_ends_with_scenes_page_and_figures(demo_out):
    assert len(list((demo_out / "scenes").glob("*.glb"))) == 6
    assert (demo_out / "index.html").is_file()
    assert (demo_out / "figures" / "study.png").is_file() and (
        demo_out / "figures" / "cost_matrix.png").is_file()
    assert len(list((demo_out / "figures" / "criteria").glob("*.png"))) == 6


def test_demo_json_prints_the_study_document_it_writes(tmp_path, capsys, monkeypatch, demo):
    """``--json`` prints study.json; the session's study stands in for a second computation."""
    from pinchmatch.cli import commands

    monkeypatch.setattr(commands, "run_study", lambda *args, **kwargs: demo.study)
    code, stdout, err = (run_cli(capsys, "demo", "-o", tmp_path / "demo", "--json", "--no-view",
                                 "--no-figures"))
    assert code == 0, err
    doc = json.loads(stdout)
    assert doc["schema"] == "pinchmatch.study/1" and len(doc["rows"]) == 18
    assert doc["rows"] == json.loads((demo.out / "study.json").read_text())["rows"]
    assert (not (tmp_path / "demo" / "index.html").exists()
            and not (tmp_path / "demo" / "figures").exists())


def test_full_study_adds_sampled_candidates_and_only_gains(tmp_path, study):
    full = run_study(tmp_path / "full", full=True, settings=PinchSettings(count=300))
    assert all(len(f) > len(s) for f, s in zip(full.virtuals, study.virtuals))
    for row, base in zip(full.rows, study.rows):
        assert row["ours"]["cost"] <= base["ours"]["cost"] + 1e-9
        assert row["ours"]["cost"] <= row["ref"]["cost"] + 1e-6


#: the paper's algorithm's costs of its own poses and of the reference in the rebuilt study (Table
#: 2's 18 rows: tangible part, virtual object), as the version before probability summation wrote
#: them
PAPER_COSTS = [("cylinder", 1, 0.0, 0.0), ("cylinder", 2, 0.0017, 0.0017),
               ("cylinder", 3, 0.2337, 0.5604), ("cylinder", 4, 0.0021, 0.5626),
               ("cylinder", 5, 0.1949, 1.0059), ("cylinder", 6, 0.0037, 1.0035),
               ("cube", 1, 0.0, 0.0), ("cube", 2, 0.1751, 1.4428), ("cube", 3, 0.1472, 0.5617),
               ("cube", 4, 0.2159, 1.4462), ("cube", 5, 0.1981, 0.559), ("cube", 6, 0.0012, 0.0012),
               ("cone", 1, 0.0, 0.0), ("cone", 2, 0.3932, 1.4433), ("cone", 3, 0.0068, 0.0068),
               ("cone", 4, 0.3319, 1.0111), ("cone", 5, 0.003, 1.4423), ("cone", 6, 0.0057, 1.0061)]


def test_the_papers_algorithm_reproduces_its_own_costs_unchanged(study):
    """--criteria paper --normalize range --pooling sum is the paper's algorithm: whatever the
    default cost becomes, its poses and costs in the study stay what they were."""
    got = [(r["tangible_part"], r["virtual"], r["paper"]["cost_paper"], r["ref"]["cost_paper"])
           for r in study.rows]
    assert [g[:2] for g in got] == [e[:2] for e in PAPER_COSTS]
    np.testing.assert_allclose([g[2:] for g in got], [e[2:] for e in PAPER_COSTS], atol=6e-5)


@pytest.mark.parametrize("make", [vessels.cup, vessels.bowl])
def test_the_reference_of_an_object_on_itself_costs_nothing_across_walls_too(tmp_path, make):
    """Each finger closes from where it holds the tangible: on a rim pinch the finger inside the cup
    meets the inner wall, so a vessel on itself at the identity is its own reference, wall and body
    pinches alike."""
    make().export(tmp_path / "v.stl")
    settings = PinchSettings(count=120)
    c = candidate_poses(analyze_object(tmp_path / "v.stl"), settings=settings)
    model = cost_model(MatchSettings(), [c])
    width = np.linalg.norm(c.pinches.points[:, 1] - c.pinches.points[:, 0], axis=1)
    assert (width < 10.0).sum() >= 20  # pinches across a wall are among them
    for i in range(len(c)):
        ref = reference_pose(c, i, c, model, settings=settings)
        assert ref.cost == pytest.approx(0.0, abs=1e-9), (i, width[i])
        np.testing.assert_allclose(ref.pinches.points[0], c.pinches.points[i], atol=1e-6)


@pytest.mark.parametrize("landing_mm, ok",
                         [(0.0, True), (20.0, True), (-0.1, False), (20.5, False)])
def test_the_landing_radius_takes_its_documented_bounds_inclusive(landing_mm, ok):
    if ok:
        assert MatchSettings(landing_mm=landing_mm).landing_mm == landing_mm
    else:
        with pytest.raises(ConfigError, match="--landing-mm"):
            MatchSettings(landing_mm=landing_mm)


def test_evaluate_pairs_defaults_to_the_default_settings_model(example):
    i = np.arange(0, 40, 4)
    given = evaluate_pairs(example, example, i, i[::-1],
                           model=cost_model(MatchSettings(), [example, example]))
    default = evaluate_pairs(example, example, i, i[::-1])
    np.testing.assert_array_equal(default.cost, given.cost)


def test_fewer_distinct_pairs_than_asked_for_are_all_returned(tmp_path):
    """Three given poses on each side: nine pairs in all, fewer than top_k + 1 distinct ones."""
    mesh = trimesh.creation.box(extents=(60.0, 40.0, 20.0))
    path = tmp_path / "box.stl"
    mesh.export(path)
    p1 = np.array([[0.0, 0.0, 10.0], [30.0, 0.0, 0.0], [0.0, 20.0, 0.0]])
    p2 = np.array([[0.0, 0.0, -10.0], [-30.0, 0.0, 0.0], [0.0, -20.0, 0.0]])
    c = candidate_poses(analyze_object(path), settings=PinchSettings(count=10), given=(p1, p2))
    vm = match_scene([c], [c],
                     settings=MatchSettings(top_k=10, refine=False, landing_mm=0.0)).matches[0]
    assert vm.best.cost == pytest.approx(0.0, abs=1e-12)
    assert 1 <= len(vm.alternatives) < 10


def test_a_mass_known_on_one_side_only_leaves_the_masses_equal(example):
    from pinchmatch.match.candidates import mass_ratio

    assert mass_ratio(with_mass(example, 100.0), example) == 1.0
    assert mass_ratio(example, with_mass(example, 100.0)) == 1.0
    assert mass_ratio(with_mass(example, 100.0), with_mass(example, 25.0)) == 0.25


def test_pinch_distance_in_literals_the_crossed_order_too():
    from pinchmatch.match.search import pinch_distance

    a = np.array([[[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]]])
    assert pinch_distance(a, a[0][::-1])[0] == 0.0
    assert pinch_distance(a, a[0] + [0.0, 3.0, 0.0])[0] == pytest.approx(3.0)
    # reversed, the second finger moved 5 mm and the first 1 mm: the larger, in the crossed order
    assert pinch_distance(a, np.array([[10.0, 5.0, 0.0], [0.0, 1.0, 0.0]]))[0] == pytest.approx(5.0)


def test_a_subset_keeps_poses_features_and_table_together(example):
    keep = [5, 1, 7]
    sub = example.subset(keep)
    np.testing.assert_array_equal(sub.features.width_mm, example.features.width_mm[keep])
    np.testing.assert_array_equal(sub.pinches.points, example.pinches.points[keep])
    np.testing.assert_array_equal(sub.table, example.table[keep])
    np.testing.assert_array_equal(sub.index, example.index[keep])


@pytest.mark.parametrize("seed", [0, 1])
def test_a_z_up_prop_and_a_y_up_object_report_the_turn_of_up_the_transform_makes(
    tmp_path, capsys, seed):
    """Mixed up axes: a z-up STL prop and a y-up GLB object (metres), off the origin.
    ``up_turn_deg`` and ``flipped`` are what the reported transform does to the object's up: two
    points along its up, carried by the 4x4 matrix as points (not its rotation applied to a vector),
    measured against the prop's up."""
    prop = trimesh.creation.box(extents=(60.0, 40.0, 90.0))  # mm, z up: tall along z
    prop.apply_translation([30.0, -20.0, 45.0])
    prop.export(tmp_path / "prop.stl")
    # metres, tall along z ...
    bottle = trimesh.creation.cylinder(radius=0.025, height=0.11, sections=40)
    # ... now along y
    bottle.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    bottle.apply_translation([0.2, 0.055, -0.1])
    bottle.export(tmp_path / "bottle.glb")
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", tmp_path / "prop.stl", "--virtual",
                           tmp_path / "bottle.glb", "--count", 200, "--seed", seed, "--no-cache",
                           "--no-view", "-o", out, "--jobs", 1)
    assert code == 0, err
    doc = json.loads((out / "matches.json").read_text())
    assert (doc["virtuals"][0]["up_vector"] == [0.0, 1.0, 0.0] and doc["tangibles"][0]["up_vector"]
            == [0.0, 0.0, 1.0])
    for m in [doc["matches"][0]] + doc["matches"][0]["alternatives"]:
        X = np.array(m["transform_virtual_to_tangible"])
        # the object's up, as points
        a, b = X @ [200.0, 0.0, -100.0, 1.0], X @ [200.0, 100.0, -100.0, 1.0]
        up = (b - a)[:3] / np.linalg.norm((b - a)[:3])
        turn = np.degrees(np.arccos(np.clip(up @ [0.0, 0.0, 1.0], -1.0, 1.0)))
        assert m["up_turn_deg"] == pytest.approx(turn, abs=0.02)
        assert m["flipped"] == bool(turn > 90.0)


def test_merged_candidates_are_given_only_when_both_lists_are(example):
    from pinchmatch.match.candidates import merge_candidates

    given = candidate_poses(example.obj, settings=PinchSettings(count=40),
                            given=(example.pinches.points[:3, 0], example.pinches.points[:3, 1]))
    both = merge_candidates(given, given)
    assert both.given and len(both) == 2 * len(given)
    mixed = merge_candidates(given, example)
    assert not mixed.given and not merge_candidates(example, given).given
    assert list(mixed.index[:3]) == [0, 1, 2] and mixed.index[3] == 3  # the second's indices follow


def test_no_feasible_given_pose_names_the_rules_each_breaks(example, tmp_path):
    from pinchmatch.errors import NoFeasiblePinchError

    p1 = example.pinches.points[:2, 0]  # two contacts on the surface, each pinched against itself
    with pytest.raises(NoFeasiblePinchError, match=r"pose 0 breaks width.*; pose 1 breaks width"):
        candidate_poses(example.obj, settings=PinchSettings(count=40), given=(p1, p1.copy()))


def test_every_tangible_is_allowed_unless_one_to_one():
    from pinchmatch.match.scene import allowed_tangibles

    matrix = np.array([[1.0, np.inf, 0.5], [0.2, 0.3, np.inf]])
    assert allowed_tangibles(matrix, MatchSettings()) == [([0, 1, 2], None), ([0, 1, 2], None)]
    assert allowed_tangibles(matrix, MatchSettings(one_to_one=True)) == [([2], None), ([0], None)]


def test_an_object_no_tangible_may_serve_is_assigned_none():
    matrix = np.array([[np.inf, np.inf], [0.4, 0.2], [0.1, np.inf]])
    assigned = assign_one_to_one(matrix)
    assert assigned.tolist() == [-1, 1, 0] and assigned.dtype == np.int64
    assert assign_one_to_one(np.full((2, 2), np.inf)).tolist() == [-1, -1]
