"""The match's targeted step (:mod:`pinchmatch.match.targeted`): its keys against an independent
computation at a turn and off the origin, the pool's checks made once each, the nearest candidates
taken rank by rank, and what the step finds on a mug whose sample lost its handle."""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial.distance import cdist
from scipy.spatial.transform import Rotation

import pinchmatch.match.targeted as targeted
from pinchmatch.grasp.analysis import analyze_object
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.grasp.strata import width_jnd
from pinchmatch.match.candidates import REFINED_INDEX, candidate_poses
from pinchmatch.match.cost import ANGLE_JND_FLOOR_DEG, COM_JND_MM, MASS_JND_FLOOR_MM
from pinchmatch.match.refine import refined_search
from pinchmatch.match.search import MatchSettings, Search, cost_model, cost_row
from pinchmatch.match.targeted import (CheckedPool, feature_keys, pinch_keys, targeted_poses,
                                       tripod_keys)
from pinchmatch.mesh.shapes import cylinder
from test_coverage import _handle, _turned, mug  # noqa: F401  (mug: the turned mug fixture)
from test_pinches import assert_rules_hold

TURN = Rotation.from_euler("zyx", [143.0, -38.0, 71.0], degrees=True).as_matrix()
SHIFT = np.array([312.0, -57.0, 940.0])


class _Props:
    def __init__(self, com_mm, principal_axis):
        self.com_mm, self.principal_axis = (np.asarray(com_mm, float),
                                            np.asarray(principal_axis, float))


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _pinch_key_by_hand(p, n, com, axis) -> list[float]:
    """One pinch's key, written out from its definition one quantity at a time."""
    a = axis / np.linalg.norm(axis)
    u = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0])
    mid = (p[0] + p[1]) / 2
    angles = sorted(np.degrees(np.arccos(min(1.0, abs(float(n[k] @ u))))) for k in range(2))
    arm = com - mid
    lever = np.linalg.norm(arm - (arm @ u) * u)
    return [float(width_jnd(np.linalg.norm(p[1] - p[0]))), abs(float((mid - com) @ a)) / COM_JND_MM,
            np.degrees(np.arcsin(min(1.0, abs(float(u @ a))))) / ANGLE_JND_FLOOR_DEG,
            angles[0] / ANGLE_JND_FLOOR_DEG, angles[1] / ANGLE_JND_FLOOR_DEG,
            lever / MASS_JND_FLOOR_MM]


def test_pinch_keys_match_their_definition_and_do_not_depend_on_the_frame():
    """Against the key written out pinch by pinch; then the same pinches turned and moved with their
    object (its centre of mass and axis too), the axis given reversed and unnormalised, and the
    fingers swapped: one key."""
    rng = np.random.default_rng(11)
    p = rng.normal(size=(40, 2, 3)) * 30.0 + [5.0, -8.0, 12.0]
    n = _unit(rng.normal(size=(40, 2, 3)))
    com, axis = np.array([3.0, -4.0, 9.0]), np.array([0.3, 0.9, -0.2])
    keys = pinch_keys(p, n, _Props(com, axis))
    expected = np.array([_pinch_key_by_hand(p[i], n[i], com, axis) for i in range(len(p))])
    np.testing.assert_allclose(keys, expected, rtol=1e-9, atol=1e-9)
    moved = _Props(com @ TURN.T + SHIFT, -2.5 * axis @ TURN.T)
    np.testing.assert_allclose(pinch_keys(p @ TURN.T + SHIFT, n @ TURN.T, moved), keys, atol=1e-7)
    np.testing.assert_allclose(pinch_keys(p[:, ::-1], n[:, ::-1], _Props(com, axis)), keys,
                               atol=1e-9)
    assert np.ptp(keys, axis=0).min() > 0.1


def test_tripod_keys_keep_the_thumb_first_and_either_finger_order():
    """A tripod's key: its thumb's normal angle in its own column, its two fingers' in either order
    one key; the same at a turn and off the origin; the spacing's column is the fingers' distance in
    JND of width."""
    rng = np.random.default_rng(12)
    p = rng.normal(size=(30, 3, 3)) * 25.0
    n = _unit(rng.normal(size=(30, 3, 3)))
    props = _Props([1.0, 2.0, -3.0], [0.0, 0.0, 1.0])
    keys = tripod_keys(p, n, props)
    assert keys.shape == (30, 8)
    np.testing.assert_allclose(keys[:, 7], width_jnd(np.linalg.norm(p[:, 2] - p[:, 1], axis=1)),
                               rtol=1e-12)
    np.testing.assert_allclose(tripod_keys(p[:, [0, 2, 1]], n[:, [0, 2, 1]], props), keys,
                               atol=1e-9)
    assert (keys[:, 4] <= keys[:, 5]).all()
    moved = _Props(props.com_mm @ TURN.T + SHIFT, props.principal_axis @ TURN.T)
    np.testing.assert_allclose(tripod_keys(p @ TURN.T + SHIFT, n @ TURN.T, moved), keys, atol=1e-7)
    # the thumb is not one of the fingers: moving it to a finger's place changes the key
    assert not np.allclose(tripod_keys(p[:, [1, 0, 2]], n[:, [1, 0, 2]], props), keys)


def test_a_checked_pool_checks_each_candidate_once_and_returns_rows_in_the_order_asked(mug):
    """Asked for pool candidates in any order, with repeats, over several asks: each is checked
    once, the unchecked ones of an ask together in index order, and every answer is the fresh check
    of those asked, in that order."""
    path, _ = mug
    c = candidate_poses(analyze_object(path), settings=PinchSettings(count=60, seed=3))
    # stands for the checks of a pool of 60 candidates: row i is candidate i's check
    every = c.pinches
    calls = []

    def check(new):
        calls.append(new.copy())
        return every.subset(new)

    pool = CheckedPool(len(every))
    rng = np.random.default_rng(0)
    for ask in (rng.integers(0, 60, 25), np.array([5, 5, 5, 59, 0]), rng.permutation(60),
                rng.integers(0, 60, 9)):
        got = pool.checked(ask, check)
        np.testing.assert_array_equal(got.points, every.points[ask])
        np.testing.assert_array_equal(got.feasible, every.feasible[ask])
    flat = np.concatenate(calls)
    # each candidate checked once, all by the permutation
    assert len(flat) == len(np.unique(flat)) == 60
    assert all((np.diff(call) > 0).all() for call in calls)
    assert len(calls) == 3  # the last ask needed no check


def test_nearest_candidates_are_taken_rank_by_rank_over_the_keys(mug, monkeypatch):
    """The budget of ``NEAREST`` candidates per distinct key is spent the first nearest of every
    key, then the second, and so on, each candidate once: against a brute-force ranking of the pool
    by key distance."""
    path, _ = mug
    settings = PinchSettings(count=100, seed=6)
    c = candidate_poses(analyze_object(path), settings=settings)
    _, _, tree, _ = targeted.feature_pool(c, settings)
    keys = feature_keys(c)[[3, 3, 17, 40, 41]]  # a repeated key counts once
    asked = []
    real = CheckedPool.checked
    monkeypatch.setattr(CheckedPool, "checked", lambda self, idx,
                        check: asked.append(idx) or real(self, idx, check))
    targeted.nearest_feasible(c, keys, settings)
    distinct = np.unique(keys, axis=0)
    budget = targeted.NEAREST * len(distinct)
    ranked = np.argsort(cdist(distinct, tree.data), axis=1, kind="stable")[:, :budget].T.ravel()
    expected = ranked[np.sort(np.unique(ranked, return_index=True)[1])][:budget]
    np.testing.assert_array_equal(asked[0], expected)
    # where two keys' rankings overlap (40, 41), later ranks fill the budget
    assert len(asked[0]) == budget
def test_keys_from_features_and_from_contacts_agree_in_either_finger_order(mug):
    """The targeted step keys its pool from contacts and triangle normals, the poses it looks for
    from their features: on the same pinches (patch normals given) both give one key, whichever
    finger is first."""
    path, _ = mug
    obj = analyze_object(path)
    c = candidate_poses(obj, settings=PinchSettings(count=150, seed=1))
    keys = feature_keys(c)
    np.testing.assert_allclose(pinch_keys(c.pinches.points, c.pinches.normals, obj.props), keys,
                               atol=1e-9)
    swapped = pinch_keys(c.pinches.points[:, ::-1], c.pinches.normals[:, ::-1], obj.props)
    np.testing.assert_allclose(swapped, keys, atol=1e-9)
    assert np.ptp(keys, axis=0).min() > 0.1  # every key column varies over the mug's poses


def test_the_targeted_step_finds_on_the_prop_the_width_its_sample_lacks(tmp_path, mug):
    """A rod 10 mm thick and 160 mm long (longer than any pinch), turned another way, against the
    turned mug whose sampled poses have lost every handle pinch: the exact search can only offer the
    body's. The targeted step finds handle pinches on the mug by the rod's features; each obeys
    every rule, and the best cost falls below the body's."""
    path, mesh = mug
    settings = PinchSettings(count=300, seed=2)
    full = candidate_poses(analyze_object(path), settings=settings)
    no_handle = full.subset(np.flatnonzero(np.linalg.norm(
        full.pinches.points[:, 1] - full.pinches.points[:, 0],
                                                          axis=1) > 20.0))
    rod_path, rod_mesh = _turned(tmp_path, "rod", cylinder(5.0, 160.0, faces=8000).mesh,
                          Rotation.from_euler("zxz", [12.0, 97.0, -40.0], degrees=True).as_matrix(),
                          np.array([33.0, -18.0, -120.0]))
    rod = candidate_poses(analyze_object(rod_path), settings=settings)
    match = MatchSettings(refine=True)
    model = cost_model(match, [no_handle, rod])
    search = Search([no_handle], [rod], model, match)
    before = float(cost_row(search, 0)[0])
    (grown,), grown_rod = targeted_poses(search, settings)
    added = grown.pinches.subset(np.arange(len(no_handle), len(grown)))
    assert len(added) > 0 and (grown.index[len(no_handle):] == REFINED_INDEX).all()
    assert _handle(added.points).sum() >= 3
    assert_rules_hold(mesh, added, settings)
    # the other way round, the mug's best poses are looked for on the rod: what is found there joins
    # the rod's
    grown_added = grown_rod.pinches.subset(np.arange(len(rod), len(grown_rod)))
    assert len(grown_added) > 0 and (grown_rod.index[len(rod):] == REFINED_INDEX).all()
    assert_rules_hold(rod_mesh, grown_added, settings)
    after = float(cost_row(search.grown([grown], [grown_rod]), 0)[0])
    assert after < 0.5 * before
    # and the match runs it before refinement: the refined answer is at least as good
    assert float(cost_row(refined_search([no_handle], rod, model, match, pinch_settings=settings),
                          0)[0]) <= after + 1e-9


def test_the_targeted_step_is_deterministic_and_skipped_without_refinement(mug, tmp_path):
    path, _ = mug
    settings = PinchSettings(count=200, seed=4)
    box_path, _ = (_turned(tmp_path, "box",
                           trimesh.creation.box((30.0, 45.0, 60.0)).subdivide().subdivide()))
    a = candidate_poses(analyze_object(path), settings=settings)
    b = candidate_poses(analyze_object(box_path), settings=settings)
    model = cost_model(MatchSettings(), [a, b])
    one = targeted_poses(Search([a], [b], model, MatchSettings()), settings)
    two = targeted_poses(Search([a], [b], model, MatchSettings()), settings)
    np.testing.assert_array_equal(one[0][0].pinches.points, two[0][0].pinches.points)
    np.testing.assert_array_equal(one[1].pinches.points, two[1].pinches.points)
    off = refined_search([a], b, model, MatchSettings(refine=False), pinch_settings=settings)
    assert len(off.tangibles[0]) == len(a) and len(off.virtuals[0]) == len(b)


def test_a_pool_candidate_is_checked_once_and_as_a_fresh_check_would(mug, tmp_path, monkeypatch):
    """The targeted step asked twice with overlapping keys checks each pool candidate once (a third
    ask checks nothing), and what it returns is what a process that never checked any gets, bit for
    bit."""
    path, _ = mug
    settings = PinchSettings(count=200, seed=5)
    box_path, _ = (_turned(tmp_path, "box",
                           trimesh.creation.box((30.0, 45.0, 60.0)).subdivide().subdivide()))
    keys = feature_keys(candidate_poses(analyze_object(box_path), settings=settings))
    checked = []
    real = targeted.check_pinches
    monkeypatch.setattr(targeted, "check_pinches", lambda context, p1, p2,
                        **kw: checked.append(len(p1))
                        or real(context, p1, p2, **kw))
    warm = candidate_poses(analyze_object(path), settings=settings)
    targeted.nearest_feasible(warm, keys[:6], settings)
    first = sum(checked)
    again = targeted.nearest_feasible(warm, keys[3:12], settings)
    second = sum(checked) - first
    # the shared candidates are not
    assert 0 < second < targeted.NEAREST * len(np.unique(keys[3:12], axis=0))
    targeted.nearest_feasible(warm, keys[3:12], settings)                     # checked again
    assert sum(checked) == first + second
    fresh = targeted.nearest_feasible(candidate_poses(analyze_object(path), settings=settings),
                                      keys[3:12], settings)
    for field in ("points", "normals", "face_index", "feasible", "broken", "approach",
                  "kappa_max_per_m"):
        np.testing.assert_array_equal(getattr(again, field), getattr(fresh, field))


