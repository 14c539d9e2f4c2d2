"""The width strata's mechanics, pinned: where a stratum begins and ends, how much each gets, and
when it stops (found its quota, spent its tries, or given up as unreachable)."""

from types import SimpleNamespace

import numpy as np
import pytest

from pinchmatch.config import WIDTH_JND_FLOOR_MM, WIDTH_JND_FRACTION
from pinchmatch.grasp import strata
from pinchmatch.grasp.spread import Pool


def test_widths_in_jnd_are_linear_below_the_knee_logarithmic_above_and_continuous():
    knee = WIDTH_JND_FLOOR_MM / WIDTH_JND_FRACTION
    w = np.array([0.0, 1.0, knee - 1e-9, knee, knee + 1e-9, 20.0, 80.0])
    j = strata.width_jnd(w)
    np.testing.assert_allclose(j[:3], w[:3] / WIDTH_JND_FLOOR_MM)
    assert abs(j[3] - j[2]) < 1e-6 and abs(j[4] - j[3]) < 1e-6
    # its slope is one over the JND at every width (the integral of dw / JND(w))
    for width in (2.0, knee + 3.0, 40.0):
        slope = (strata.width_jnd(width + 1e-6) - strata.width_jnd(width - 1e-6)) / 2e-6
        assert slope == pytest.approx(1.0 / max(WIDTH_JND_FRACTION * width, WIDTH_JND_FLOOR_MM),
                                      rel=1e-5)


def _pinches(widths, rng):
    """(n, 2, 3) pinches of the given widths (thumb to index), at random places and directions."""
    widths = np.asarray(widths, dtype=float)
    d = rng.normal(size=(len(widths), 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    start = rng.uniform(-50, 50, (len(widths), 3))
    return np.stack([start, start + widths[:, None] * d], axis=1)


def _width_at(jnd):
    """The width (mm) that is ``jnd`` just-noticeable differences from 0 (the inverse of
    width_jnd)."""
    knee = WIDTH_JND_FLOOR_MM / WIDTH_JND_FRACTION
    at_knee = knee / WIDTH_JND_FLOOR_MM
    return (jnd * WIDTH_JND_FLOOR_MM if jnd <= at_knee else knee
            * np.exp((jnd - at_knee) * WIDTH_JND_FRACTION))


def test_a_stratum_begins_at_its_boundary_width():
    rng = np.random.default_rng(0)
    for k in (1, 4, 11):
        edge = _width_at(k * strata.STRATUM_JND)
        below, above = strata.stratum_of(_pinches([edge * (1 - 1e-6), edge * (1 + 1e-6)], rng))
        assert (below, above) == (k - 1, k)
    # a tripod's width runs from the thumb to the middle of the other two
    tripod = np.array([[[0.0, 0, 0], [30.0, 5, 0], [30.0, -5, 0]]])
    assert strata.grip_width_mm(tripod)[0] == pytest.approx(30.0)


def test_the_quota_is_the_stratified_share_of_the_count():
    assert strata.quota_per_stratum(1000, 4) == int(strata.STRATUM_SHARE * 1000 // 4)
    assert strata.quota_per_stratum(1000, 200) == 0  # less than one each: left to the spread
    # grows with the count
    assert strata.quota_per_stratum(2000, 4) >= 2 * strata.quota_per_stratum(1000, 4) - 1


def test_each_stratum_stops_at_its_quota_its_tries_or_after_empty_batches():
    """Three strata: every candidate feasible (stops at the first batch, its quota met), none
    feasible (given up after EMPTY_BATCHES batches), one in twenty feasible (goes on doubling until
    its quota or its tries)."""
    rng = np.random.default_rng(3)
    widths = {"full": _width_at(2 * strata.STRATUM_JND + 1.0),
              "empty": _width_at(5 * strata.STRATUM_JND + 1.0),
              "sparse": _width_at(8 * strata.STRATUM_JND + 1.0)}
    n = 4000
    points = np.concatenate([_pinches(np.full(n, w), rng) for w in widths.values()])
    faces = np.zeros((len(points), 2), np.int64)
    kind = np.repeat(list(widths), n)
    sparse_ok = rng.random(len(points)) < 0.05
    feasible = (kind == "full") | ((kind == "sparse") & sparse_ok)
    checked = []

    def check(p, f):
        rows = np.array([np.flatnonzero((points == q).all(axis=(1, 2)))[0] for q in p])
        checked.append(rows)
        return SimpleNamespace(points=points[rows[feasible[rows]]])

    pool = Pool.of(points, faces, np.zeros((0, 2, 3)))
    count = 300
    parts, taken = strata.stratified_checks(pool, count, check)
    quota = strata.quota_per_stratum(count, 3)
    rows = np.concatenate(checked)
    spent = {k: int((kind[rows] == k).sum()) for k in widths}
    assert spent["full"] == strata.FIRST_BATCH * quota  # met its quota at once
    assert spent["empty"] == sum(strata.FIRST_BATCH * quota * 2**b
                                 for b in range(strata.EMPTY_BATCHES))
    found_sparse = int((feasible[rows] & (kind[rows] == "sparse")).sum())
    assert found_sparse >= quota or spent["sparse"] >= quota * strata.TRIES_PER_PINCH
    assert spent["sparse"] <= quota * strata.TRIES_PER_PINCH + strata.FIRST_BATCH * quota * 2**6
    # the checked ones are picked
    assert len(taken) == len(rows) and (pool.nearest[rows] == -1).all()
    assert sum(len(p.points) for p in parts) == int(feasible[rows].sum())


def test_a_stratum_stops_the_moment_its_quota_is_met_or_its_candidates_run_out():
    """One stratum finds exactly its quota in its first batch (it stops there); another has fewer
    candidates than its first batch, all feasible (it stops once they are spent: no empty batch is
    ever checked)."""
    rng = np.random.default_rng(5)
    count = 300
    quota = strata.quota_per_stratum(count, 2)
    exact_w, few_w = (_width_at(3 * strata.STRATUM_JND + 1.0),
                      _width_at(7 * strata.STRATUM_JND + 1.0))
    points = np.concatenate([_pinches(np.full(1000, exact_w), rng),
                             _pinches(np.full(quota // 3, few_w), rng)])
    kind = np.array(["exact"] * 1000 + ["few"] * (quota // 3))
    seen = {"exact": 0}
    calls = []

    def check(p, f):
        rows = np.array([np.flatnonzero((points == q).all(axis=(1, 2)))[0] for q in p],
                        dtype=np.int64)
        calls.append(len(rows))
        ok = np.zeros(len(rows), bool)
        for i, r in enumerate(rows):
            if kind[r] == "few" or seen["exact"] < quota:
                ok[i] = True
                seen["exact"] += kind[r] == "exact"
        return SimpleNamespace(points=points[rows[ok]])

    pool = Pool.of(points, np.zeros((len(points), 2), np.int64), np.zeros((0, 2, 3)))
    parts, taken = strata.stratified_checks(pool, count, check)
    assert all(n > 0 for n in calls)  # never an empty batch
    exact_spent = int((kind[np.concatenate([np.flatnonzero((points == q).all(axis=(1, 2)))
                                            for q in taken])]
                       == "exact").sum())
    assert exact_spent == strata.FIRST_BATCH * quota  # its quota met in the first batch: no second
    assert (kind == "few").sum() == quota // 3 and len(taken) == exact_spent + quota // 3


@pytest.mark.parametrize("extra", [0, 1])
def test_a_stratum_whose_candidates_are_spent_exactly_checks_no_more(extra):
    """A lone stratum of exactly its first batch of candidates (or one more), a third of them
    feasible: it is checked in one batch (and the one left over in a second), never in an empty
    one."""
    rng = np.random.default_rng(9)
    count = 300
    quota = strata.quota_per_stratum(count, 1)
    n = strata.FIRST_BATCH * quota + extra
    points = _pinches(np.full(n, _width_at(4 * strata.STRATUM_JND + 1.0)), rng)
    calls = []

    def check(p, f):
        calls.append(len(p))
        return SimpleNamespace(points=p[: len(p) // 3])

    pool = Pool.of(points, np.zeros((n, 2), np.int64), np.zeros((0, 2, 3)))
    parts, taken = strata.stratified_checks(pool, count, check)
    assert calls == [strata.FIRST_BATCH * quota] + ([1] if extra else [])
    assert len(taken) == n


def test_too_small_a_count_checks_nothing_and_says_so_in_the_grasps_shape():
    rng = np.random.default_rng(1)
    pool = Pool.of(_pinches([20.0, 30.0, 40.0], rng), np.zeros((3, 2), np.int64),
                   np.zeros((0, 2, 3)))
    parts, taken = strata.stratified_checks(pool, 5, lambda p, f: None)  # a quota of 0 per stratum
    assert parts == [] and taken.shape == (0, 2, 3)
