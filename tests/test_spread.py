"""The farthest-point spread order: blocks skipped by the metric bound change nothing."""

import numpy as np
import pytest

from pinchmatch.mesh import shapes
from pinchmatch.grasp.spread import Pool, spread_order


def plain_spread_order(points, count, nearest=None):
    """The farthest-point order with every distance updated at every pick (numpy)."""
    n = len(points)
    centred = points - points.reshape(-1, 3).mean(axis=0)
    a, b = centred.reshape(n, 6), centred[:, ::-1].reshape(n, 6)
    sq = (a * a).sum(axis=1)
    nearest = np.full(n, np.inf) if nearest is None else nearest.copy()
    current = int(np.argmax(nearest))
    chosen = []
    for _ in range(min(count, int((nearest >= 0).sum()))):
        chosen.append(current)
        d = sq + sq[current] - 2.0 * np.maximum(a @ a[current], b @ a[current])
        np.minimum(nearest, d, out=nearest)
        nearest[current] = -1.0
        current = int(np.argmax(nearest))
    return np.array(chosen, dtype=np.int64), nearest


def surface_pinches(n, seed):
    """Pinches whose contacts lie on a torus (the low-dimensional clouds sampling produces)."""
    mesh = shapes.torus(triangulation="regular", faces=4000).mesh
    rng = np.random.default_rng(seed)
    p1 = mesh.sample(n, seed=seed)
    p2 = mesh.sample(n, seed=seed + 1)
    return np.stack([p1, p2], axis=1) + rng.normal(0.0, 1e-3, (n, 2, 3))


@pytest.mark.parametrize("n, count", [(1, 1), (40, 40), (700, 250), (5000, 1200)])
def test_spread_order_matches_the_plain_loop(n, count):
    points = surface_pinches(n, seed=n)
    chosen, nearest = spread_order(points, count)
    expected, expected_nearest = plain_spread_order(points, count)
    np.testing.assert_array_equal(chosen, expected)
    np.testing.assert_allclose(nearest, expected_nearest, rtol=0, atol=1e-6)
    # continuing the order from where it stopped
    more, _ = spread_order(points, 50, nearest)
    expected_more, _ = plain_spread_order(points, 50, expected_nearest)
    np.testing.assert_array_equal(more, expected_more)


def test_spread_order_treats_both_finger_orders_as_one_pinch():
    rng = np.random.default_rng(3)
    base = rng.normal(0.0, 20.0, (300, 2, 3))
    points = np.concatenate([base, base[:, ::-1], base])  # every pinch three times, once swapped
    chosen, nearest = spread_order(points, 300)
    np.testing.assert_array_equal(chosen, plain_spread_order(points, 300)[0])
    # the 300 distinct pinches come first, one copy of each
    assert len(set(chosen % 300)) == 300
    # the copies left are at distance zero from a pick
    assert np.all(np.abs(nearest[nearest >= 0]) <= 1e-6)


def test_random_six_dimensional_cloud_matches_too():
    points = np.random.default_rng(7).normal(0.0, 30.0, (3000, 2, 3))
    chosen, nearest = spread_order(points, 400)
    expected, expected_nearest = plain_spread_order(points, 400)
    np.testing.assert_array_equal(chosen, expected)


def test_pool_keeps_one_order_across_added_candidates():
    points = surface_pinches(2000, seed=11)
    pool = Pool(points[:1200], np.zeros((1200, 2), np.int64), np.full(1200, np.inf))
    first = pool.pick(100)
    pool.add(points[1200:], np.zeros((800, 2), np.int64), points[first])
    second = pool.pick(100)
    picked = np.concatenate([points[first], pool.points[second]])
    # every later pick is at least as far from the earlier ones as any pinch left in the pool
    left = pool.nearest >= 0
    d_left = np.sqrt(pool.nearest[left].max())
    gaps = [np.min(np.minimum(np.linalg.norm((picked[:i] - picked[i]).reshape(i, 6), axis=1),
                              np.linalg.norm((picked[:i] - picked[i][::-1]).reshape(i, 6), axis=1)))
            for i in range(100, 200)]
    assert min(gaps) >= d_left - 1e-6


def test_a_round_is_planned_by_the_rounds_own_yield_once_there_is_one():
    from pinchmatch.grasp.rounds import PROBE_PICKS, SELECT_MARGIN, round_plan

    # the strata checked 1,000 and found 300 (rare widths, mostly where no hand gets); the probe
    # 256, 200
    want, local = round_plan(1000, 500, 1256, 1, rounds=(200, 256))
    assert want == int(np.ceil(SELECT_MARGIN * 1000 / (200 / 256))) and not local
    # before any round, the first probes by what the strata saw, and a low yield there means local
    # rounds
    want, local = round_plan(1000, 300, 1000, 0)
    assert want == PROBE_PICKS and local
    # a round's own low yield still turns to local draws
    assert round_plan(1000, 500, 1256, 2, rounds=(50, 256))[1]


def test_a_scanned_mug_checks_about_as_many_picks_as_it_needs(tmp_path, monkeypatch):
    """The YCB mug's width strata find few feasible pinches (most narrow candidates cross its wall),
    its spread finds many: the rounds after them check about what the count needs, not the strata's
    share."""
    import dataclasses
    import sys
    from pathlib import Path

    from pinchmatch import PinchSettings, analyze_object
    from pinchmatch.grasp import sampling

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from assets import ycb_objects

    [path] = ycb_objects(tmp_path, ["025_mug"])
    obj = analyze_object(path, units="mm")
    found = []
    check = sampling.PINCH.check

    def counting(*args, **kwargs):
        part = check(*args, **kwargs)
        found.append(len(part))
        return part

    monkeypatch.setattr(sampling, "PINCH", dataclasses.replace(sampling.PINCH, check=counting))
    pinches = sampling.sample_pinches(obj.context, settings=PinchSettings(count=1000, seed=0))
    assert len(pinches) == 1000
    assert sum(found) <= 1.25 * 1000
