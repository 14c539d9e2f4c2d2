"""The steady search: pose pairs found by the expected cost of their landings, then ranked by the
felt cost."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pinchmatch.grasp.analysis import analyze_object
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.match.candidates import candidate_poses
from pinchmatch.match.cost import CostModel, pair_cost_blocks, pair_costs
from pinchmatch.match.felt import FeltTables, felt_cost, landing_moments, landing_tables
from pinchmatch.match.scene import match_scene
from pinchmatch.match.search import Choice, MatchSettings, evaluate_pairs
from pinchmatch.match.steady import MOMENT_RINGS, expected_terms
from pinchmatch.mesh.shapes import box, cylinder, sphere

SETTINGS = PinchSettings(count=200)
ROTATION = Rotation.from_euler("zyx", [37.0, -61.0, 23.0], degrees=True).as_matrix()
OFFSET = np.array([140.0, -75.0, 910.0])


def _exported(tmp_path, name, mesh, *, turned=False):
    mesh = mesh.copy()
    if turned:
        M = np.eye(4)
        M[:3, :3], M[:3, 3] = ROTATION, OFFSET
        mesh.apply_transform(M)
    path = tmp_path / f"{name}.stl"
    mesh.export(path)
    return path


def _tables(rng, n):
    """A feature table of n random poses in plausible units, some ρ undefined, and a variance per
    entry. As every feature table (and its landings' moments) has them, the pose columns and the
    lever arm are the same in both patches' rows, their variances too."""
    table = np.stack([rng.uniform(10, 80, n), rng.uniform(0, 60, n), rng.uniform(0, 40, n)],
                     axis=1)[:, None, :]
    patch = np.stack([rng.uniform(0, 30, (n, 2)), rng.uniform(0, 90, (n, 2)),
                      rng.uniform(0, 80, (n, 2)), rng.uniform(-20, 40, (n, 2)),
                      rng.uniform(-30, 30, (n, 2)),
                      np.repeat(rng.uniform(0, 40, (n, 1)), 2, axis=1)], axis=-1)
    rows = np.concatenate([np.broadcast_to(table, (n, 2, 3)), patch], axis=-1).copy()
    rows[rng.random((n, 2)) < 0.2, 4] = np.nan
    var = rng.uniform(0, 25, rows.shape)
    var[:, 1, [0, 1, 2, 8]] = var[:, 0, [0, 1, 2, 8]]
    return rows, var


def test_the_spread_pass_is_the_expected_separable_cost_of_every_pair():
    """Σ a ((v - t)² + σ_t² + σ_v²) over the defined entries, in the better finger order, for
    every pair, against the sum written out pair by pair."""
    rng = np.random.default_rng(4)
    (t, t_var), (v, v_var) = _tables(rng, 7), _tables(rng, 5)
    model = CostModel()
    got = np.concatenate([c.copy() for _, c, _ in pair_cost_blocks(
        t, v, model, block_rows=3, spreads=(t_var, v_var))])
    a = model.column_weights() / model.scales(t) ** 2  # (7, 2, 9)
    want = np.empty((7, 5))
    for i in range(7):
        for j in range(5):
            orders = []
            for vv, vr in ((v[j], v_var[j]), (v[j][::-1], v_var[j][::-1])):
                ok = ~np.isnan(t[i]) & ~np.isnan(vv)
                orders.append(float((a[i] * ((vv - t[i]) ** 2 + t_var[i] + vr))[ok].sum()))
            want[i, j] = min(orders)
    assert got == pytest.approx(want, rel=1e-9, abs=1e-9)
    plain, _ = pair_costs(t, v, model)
    assert (got > plain).all()  # the spread only adds
    zero = np.concatenate([c.copy() for _, c, _ in pair_cost_blocks(
        t, v, model, spreads=(0 * t_var, 0 * v_var))])
    assert np.array_equal(zero, plain)


def test_expected_terms_are_the_mean_contribution_of_independent_draws():
    """Draw each entry of both rows from normal distributions with the moments' means and variances:
    the mean of the drawn contributions tends to the expected terms (the scales held at the
    tangible's mean)."""
    rng = np.random.default_rng(8)
    (t, t_var), (v, v_var) = _tables(rng, 1), _tables(rng, 1)
    t[..., 4], v[..., 4] = 30.0, 50.0  # every entry defined
    model = CostModel()
    want = expected_terms((t, t_var), (v, v_var), 1.0, model)[0]
    draws = 200_000
    td = t + rng.standard_normal((draws, 2, 9)) * np.sqrt(t_var)
    vd = v + rng.standard_normal((draws, 2, 9)) * np.sqrt(v_var)
    s = model.scales(t)
    # mean over draws, then over the two patches
    z = (((vd - td) / s) ** 2).mean(axis=0).mean(axis=0)
    assert want[:7] == pytest.approx([z[0], z[1], z[2], z[3], z[4], z[5], z[6]], rel=0.02)


def test_moments_are_the_weighted_moments_of_the_landing_tables(tmp_path):
    """Fitted at every landing point, the moments are the landing tables' weighted mean and variance
    over the landings that touch; on a grid of half the radius they stay close."""
    path = _exported(tmp_path, "rod", cylinder(20.0, 80.0, faces=8000).mesh, turned=True)
    C = candidate_poses(analyze_object(path), settings=PinchSettings(count=40, seed=3))
    mean, var = landing_moments(C, 5.0, SETTINGS, rings=MOMENT_RINGS)
    t = landing_tables(C, np.arange(len(C)), 5.0, SETTINGS, rings=MOMENT_RINGS)
    w = np.where(t.hit, t.weights, 0.0)[:, :, None, None] * ~np.isnan(t.rows)
    with np.errstate(invalid="ignore"):  # an entry undefined in every landing
        m = np.nansum(w * np.nan_to_num(t.rows), axis=1) / w.sum(axis=1)
        v = np.nansum(w * (np.nan_to_num(t.rows) - m[:, None]) ** 2, axis=1) / w.sum(axis=1)
    defined = (slice(None), slice(None), [0, 5, 6])  # width and both curvatures: defined everywhere
    assert mean[defined] == pytest.approx(m[defined], rel=1e-9, abs=1e-9)
    assert var[..., 5:7] == pytest.approx(v[..., 5:7], rel=1e-9, abs=1e-9)
    # a landing that misses adds 3 JND of width (5.75 % of it, at least 0.4 mm) for its share of the
    # weight
    missed = (t.weights * ~t.hit).sum(axis=1) / t.weights.sum(axis=1)
    width_jnd = np.maximum(0.0575 * m[..., 0], 0.4)
    assert var[..., 0] == pytest.approx(v[..., 0] + missed[:, None] * (3.0 * width_jnd) ** 2,
                                        rel=1e-9, abs=1e-9)
    assert missed.max() > 0  # some poses near the rod's ends
    g_mean, _ = landing_moments(C, 5.0, SETTINGS, rings=MOMENT_RINGS, patch_spacing_mm=2.5)
    assert np.abs(g_mean[..., 5] - mean[..., 5]).max() < 2.0  # per m, on a rod of 50 /m
    # where the fingers land does not depend on the grid
    assert np.array_equal(g_mean[..., 0], mean[..., 0])


def test_a_pinch_mid_side_lands_steadier_than_one_at_the_rim(tmp_path):
    """On a turned, moved rod, a pinch across the middle of its side lands on the side wherever the
    fingers land: its curvature and width hold. One 3 mm below the top rim lands past the rim on
    part of the ring: those landings miss, and its width spreads (3 JND per miss, for the misses'
    share of the weight)."""
    path = _exported(tmp_path, "rod", cylinder(20.0, 80.0, faces=20000).mesh, turned=True)
    obj = analyze_object(path)
    local = np.array([[[0.0, -20.0, 0.0], [0.0, 20.0, 0.0]],
                      [[0.0, -20.0, 37.0], [0.0, 20.0, 37.0]]])
    world = local @ ROTATION.T + OFFSET
    C = candidate_poses(obj, settings=SETTINGS, given=(world[:, 0], world[:, 1]))
    mean, var = landing_moments(C, 5.0, SETTINGS, rings=MOMENT_RINGS)
    assert mean[:, :, 5] == pytest.approx(50.0, rel=0.05)  # 1 / 20 mm
    assert mean[:, :, 0] == pytest.approx(40.0, abs=0.2)
    assert np.sqrt(var[:, :, 5]).max() < 1.0 and np.sqrt(var[0, :, 0]).max() < 0.5
    assert np.sqrt(var[1, :, 0]).min() > 3.0


@pytest.mark.parametrize("seed", [1, 2])
def test_the_ranked_best_is_the_brute_forces_best_over_the_sampled_pairs(tmp_path, seed):
    """Sampled poses of a block and a turned rod, refinement off: the match ranks a bounded set (the
    best on target and the steady search's), and a brute force that feels every sampled pair finds
    the same best. The seeds are ones whose samples' steadiest pair is not their best on target
    (checked last)."""
    block = candidate_poses(analyze_object(_exported(
        tmp_path, "block", box((50.0, 36.0, 30.0), subdivide_mm=3.0).mesh)),
                            settings=PinchSettings(count=40, seed=seed))
    rod = candidate_poses(analyze_object(_exported(tmp_path, "rod",
                                                   cylinder(16.0, 60.0, faces=8000).mesh,
                                                   turned=True)),
                          settings=PinchSettings(count=40, seed=seed))
    scene = match_scene([block], [rod], settings=MatchSettings(top_k=0, refine=False),
                        pinch_settings=SETTINGS)
    best = scene.matches[0].best
    it, iv = np.repeat(np.arange(len(block)), len(rod)), np.tile(np.arange(len(rod)), len(block))
    r = evaluate_pairs(block, rod, it, iv, model=scene.model)
    tables = FeltTables(5.0, SETTINGS)
    expected = np.array([felt_cost(block, rod,
                                   Choice(0, 0, int(it[k]), int(iv[k]), float(r.cost[k]),
                                          r.terms[k],
                                                      bool(r.swapped[k]), r.transform[k],
                                                      bool(r.flipped[k]), r.mass_delta_mm[k]),
                                                      scene.model, tables).expected
                         for k in range(len(it))])
    k = int(np.argmin(expected))
    assert len(it) > 1000  # far more pairs than the match feels
    assert best.cost == pytest.approx(expected[k], rel=1e-9)
    assert (best.t_pose, best.v_pose) == (int(it[k]), int(iv[k]))
    nominal = int(np.argmin(r.cost))
    assert expected[nominal] > expected[k]  # the best on target is not the steadiest


def test_the_steady_search_is_used_unless_ranked_on_target(tmp_path):
    """Ranked on target, the match is the search's best; ranked by the felt cost, never worse to
    feel."""
    ball = candidate_poses(analyze_object(_exported(tmp_path, "ball", sphere(22.0, faces=8000).mesh,
                                                    turned=True)),
                           settings=PinchSettings(count=60, seed=1))
    block = candidate_poses(analyze_object(_exported(
        tmp_path, "block", box((50.0, 36.0, 30.0), subdivide_mm=3.0).mesh)),
                            settings=PinchSettings(count=60, seed=1))
    on_target = match_scene([block], [ball], settings=MatchSettings(rank="nominal", refine=False),
                            pinch_settings=SETTINGS)
    felt = match_scene([block], [ball], settings=MatchSettings(refine=False),
                       pinch_settings=SETTINGS)
    a, b = on_target.matches[0], felt.matches[0]
    assert a.best.cost == a.best.cost_nominal == pytest.approx(float(on_target.cost_matrix[0, 0]))
    assert b.landing.cost_mean <= a.landing.cost_mean + 1e-12
    assert (b.best.cost == pytest.approx(b.landing.cost_mean) and b.best.cost_nominal
            >= a.best.cost_nominal - 1e-12)


def test_the_study_feels_each_rated_placement(tmp_path):
    """The rebuilt study gives each placement its expected cost over the landings: 0 where the parts
    are alike (the same object), and close to the cost on target when the fingers land within 0.2
    mm."""
    from pinchmatch.runner.study import run_study

    narrow = run_study(tmp_path / "narrow", match_settings=MatchSettings(landing_mm=0.2))
    for row in narrow.rows:
        for source in ("ours", "paper", "ref"):
            entry = row[source]
            if entry["cost"] is None:
                assert entry["cost_expected"] is None
                continue
            assert entry["cost_expected"] == pytest.approx(entry["cost"], rel=0.05, abs=1e-4)
            if entry["cost"] == 0:
                assert entry["cost_expected"] == pytest.approx(0.0, abs=1e-6)


def test_equivalent_props_are_listed_and_ties_go_to_the_prop_given_first(tmp_path, capsys):
    """Two copies of one block as props (two files): a rod is served by both alike, refined or not.
    The first given is chosen, the other listed as equivalent at the same cost as the first's best
    (the chosen pinch may be a more comfortable one within the band: 0.1 JND or 5 %); given the
    other way round, again the first. A ball, far costlier, is not listed."""
    from conftest import run_cli

    from pinchmatch.match.scene import EQUIVALENT_JND, equivalent_tangibles

    block = box((50.0, 36.0, 30.0), subdivide_mm=3.0).mesh
    _exported(tmp_path, "block_a", block)
    _exported(tmp_path, "block_b", block)
    _exported(tmp_path, "ball", sphere(40.0, faces=4000).mesh)
    _exported(tmp_path, "rod", cylinder(16.0, 60.0, faces=8000).mesh)
    for order, refine in ((("block_a", "block_b"), "on"), (("block_b", "block_a"), "on"),
                          (("block_a", "block_b"), "off")):
        out = tmp_path / f"out_{order[0]}_{refine}"
        code, stdout, err = run_cli(capsys, "match", "--tangible",
                                    *(tmp_path / f"{n}.stl" for n in order), tmp_path / "ball.stl",
                                    "--virtual", tmp_path / "rod.stl", "--count", 80, "--refine",
                                    refine, "-o", out, "--no-view", "--jobs", 1)
        assert code == 0, err
        doc = __import__("json").loads((out / "matches.json").read_text())
        (m,) = doc["matches"]
        assert m["tangible"] == f"{order[0]}.stl"
        listed = {e["tangible"]: e["cost"] for e in m["equivalent_tangibles"]}
        assert set(listed) == {f"{order[1]}.stl"}
        first, second = doc["cost_matrix"]["values"][0][:2]
        assert listed[f"{order[1]}.stl"] == first == second and EQUIVALENT_JND == 0.1
        assert first <= m["cost"] <= first + max(EQUIVALENT_JND, 0.05 * first)
        assert "served as well by another prop" in stdout + err
    best = Choice(0, 2, 0, 0, 1.0, np.zeros(8), False, np.eye(4), False, np.zeros(3))
    row = np.array([1.05, 1.2, 1.0, np.inf, 1.1])
    assert equivalent_tangibles(best, row) == [(0, 1.05), (4, 1.1)]
    assert equivalent_tangibles(None, row) == []


def test_the_felt_set_on_target_grows_with_the_count(tmp_path, monkeypatch):
    """128 distinct best pairs on target are felt up to the default count, in proportion above it (a
    denser sample holds more knife edges), at most 1,024; the row of each prop keeps its few."""
    from pinchmatch.match import ranking as scene_module
    from pinchmatch.match.search import Search

    assert [scene_module.ranked_choices(n) for n in (50, 1000, 1001, 4000, 100_000)] == [
        128, 128, 129, 512, 1024]
    ball = candidate_poses(analyze_object(_exported(tmp_path, "ball", sphere(22.0, faces=8000).mesh,
                                                    turned=True)),
                           settings=PinchSettings(count=60, seed=1))
    block = candidate_poses(analyze_object(_exported(
        tmp_path, "block", box((50.0, 36.0, 30.0), subdivide_mm=3.0).mesh)),
                            settings=PinchSettings(count=60, seed=1))
    asked = []
    real = Search.choices
    monkeypatch.setattr(Search, "choices", lambda self, j, allowed,
                        count: asked.append(count) or real(self, j, allowed, count))
    for count, want in ((1000, 128), (3000, 384)):
        asked.clear()
        match_scene([block], [ball], settings=MatchSettings(refine=False),
                    pinch_settings=PinchSettings(count=count))
        assert max(asked) == want and scene_module.ROW_CHOICES in asked


@pytest.mark.parametrize("masses_g", [(None, None), (80.0, 260.0), (300.0, 45.0)])
def test_every_pooled_pairs_key_is_its_expected_cost_in_the_tangibles_finger_order(
    tmp_path, masses_g):
    """The steady search's key of each pooled pair, recomputed here: the virtual pose's landing
    moments in the tangible's finger order (its two patches exchanged where the pair is swapped),
    each criterion's contribution of the means' difference plus both variances, the mass columns
    scaled by m_V / m_T (1, 3.25 and 0.15 here), the mass criterion exact on target plus its
    spread's contribution; pooled by the model. The pool holds swapped and unswapped pairs, and the
    moments are on the documented pattern (the target and 8 points at the acceptance radius)."""
    from pinchmatch.grasp.spread import other_order
    from pinchmatch.match.candidates import felt_table, mass_ratio
    from pinchmatch.match.cost import separable_terms
    from pinchmatch.match.search import Search, cost_model
    from pinchmatch.match.steady import SteadySearch, moments_of

    block = candidate_poses(analyze_object(_exported(
        tmp_path, "block", box((50.0, 36.0, 30.0), subdivide_mm=3.0).mesh),
                                           mass_g=masses_g[0]),
                                           settings=PinchSettings(count=60, seed=4))
    rod = candidate_poses(analyze_object(_exported(tmp_path, "rod",
                                                   cylinder(16.0, 60.0, faces=8000).mesh,
                                                   turned=True),
                                         mass_g=masses_g[1]),
                                         settings=PinchSettings(count=60, seed=4))
    settings = MatchSettings()
    model = cost_model(settings, [block, rod])
    steady = SteadySearch(Search([block], [rod], model, settings), [block], rod, 5.0, SETTINGS)
    (_, it, iv, r), key = steady.part(0)
    assert r.swapped.any() and (~r.swapped).any()
    mt, mv = moments_of(block, 5.0, SETTINGS), moments_of(rod, 5.0, SETTINGS)
    np.testing.assert_array_equal(mt[0],
                                  landing_moments(block, 5.0, SETTINGS, rings=(8,),
                                                  patch_spacing_mm=2.5)[0])
    ratio = mass_ratio(block, rod)
    assert ratio == pytest.approx(1.0 if masses_g[0] is None else masses_g[1] / masses_g[0])
    order = [other_order(2) if s else [0, 1] for s in r.swapped]
    v_mean = np.stack([mv[0][j][o] for j, o in zip(iv, order)])
    v_var = np.stack([mv[1][j][o] for j, o in zip(iv, order)])
    t_mean, t_var = mt[0][it], mt[1][it]
    spread = np.sqrt(np.nan_to_num(t_var) + np.nan_to_num(v_var) * np.where(
        np.isin(np.arange(9), [7, 8]), ratio * ratio, 1.0))
    terms = separable_terms(t_mean, felt_table(v_mean, ratio), model) + separable_terms(
        t_mean, t_mean + spread, model)
    terms[:, 7] = r.terms[:, 7] + separable_terms(t_mean, t_mean + spread, model)[:, 7]
    np.testing.assert_allclose(key, model.pool(terms, rest=r.rest_jnd), rtol=1e-9, atol=1e-12)
