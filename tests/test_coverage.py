"""Coverage of what the fingers can feel: the sampler's width strata and the match's targeted step."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

import pinchmatch.grasp.strata as strata
from pinchmatch.grasp.analysis import analyze_object
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.grasp.sampling import sample_pinches
from pinchmatch.grasp.strata import stratum_of, width_jnd
from pinchmatch.match.candidates import REFINED_INDEX, candidate_poses
from pinchmatch.match.refine import refined_search
from pinchmatch.match.search import MatchSettings, Search, cost_model, cost_row
import pinchmatch.match.targeted as targeted
from pinchmatch.match.targeted import feature_keys, pinch_keys, targeted_poses
from pinchmatch.mesh import vessels
from pinchmatch.mesh.shapes import cylinder
from test_pinches import assert_rules_hold

ROTATION = Rotation.from_euler("xyz", [-71.0, 33.0, 128.0], degrees=True).as_matrix()
OFFSET = np.array([-260.0, 415.0, 38.0])
#: the mug's handle is a ring of 5 mm tube radius: pinched across its tube, 10 mm wide
HANDLE_WIDTH_MM = (8.0, 12.5)


def _turned(tmp_path, name, mesh, rotation=ROTATION, offset=OFFSET):
    mesh = mesh.copy()
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = rotation, offset
    mesh.apply_transform(M)
    path = tmp_path / f"{name}.stl"
    mesh.export(path)
    return path, trimesh.load(path, force="mesh")  # as stored: STL keeps float32


@pytest.fixture(scope="module")
def mug(tmp_path_factory):
    """The mug twin, turned and moved off the origin (its up axis is none of the file's)."""
    return _turned(tmp_path_factory.mktemp("mug"), "mug", vessels.mug())


def _handle(points):
    w = np.linalg.norm(points[:, 1] - points[:, 0], axis=1)
    return (w >= HANDLE_WIDTH_MM[0]) & (w <= HANDLE_WIDTH_MM[1])


def test_width_in_jnd_counts_just_noticeable_steps():
    """Below 0.4 / 0.0575 mm a JND is 0.4 mm, above it 5.75 % of the width; the count is continuous."""
    knee = 0.4 / 0.0575
    assert width_jnd(knee - 1e-9) == pytest.approx(width_jnd(knee + 1e-9), abs=1e-6)
    w = np.array([0.5, 2.0, 5.0])
    np.testing.assert_allclose(width_jnd(w + 0.4) - width_jnd(w), 1.0, rtol=1e-9)
    w = np.array([8.0, 30.0, 90.0])
    np.testing.assert_allclose(width_jnd(w * (1 + 0.0575 * 1e-4)) - width_jnd(w), 1e-4, rtol=1e-3)
    strata_of = stratum_of(np.array([[[0, 0, 0], [0, 0, 1.1]], [[0, 0, 0], [0, 0, 1.3]], [[5, 5, 5], [5, 5, 30]]]))
    assert strata_of.tolist() == [0, 1, int(width_jnd(25.0) // 3)]


def test_the_rare_width_is_sampled_and_a_larger_count_keeps_more_of_it(mug):
    """The turned mug's handle pinches are a few hundredths of its narrow candidates (most cross the wall,
    where no finger gets inside). The strata keep them at every count, more at the larger one; the spread
    over contacts alone keeps far fewer. Every pinch kept obeys every rule."""
    path, mesh = mug
    obj = analyze_object(path)
    found = {}
    for count in (600, 2400):
        pinches = sample_pinches(obj.context, settings=PinchSettings(count=count, seed=3))
        assert len(pinches) == count
        found[count] = int(_handle(pinches.points).sum())
        if count == 600:
            assert_rules_hold(mesh, pinches, PinchSettings(count=count, seed=3))
    assert found[600] >= 5 and found[2400] >= 2 * found[600]
    original = strata.STRATUM_SHARE
    try:
        strata.STRATUM_SHARE = 0.0  # the spread over contacts alone
        alone = _handle(sample_pinches(obj.context, settings=PinchSettings(count=2400, seed=3)).points).sum()
    finally:
        strata.STRATUM_SHARE = original
    assert found[2400] >= 1.5 * max(int(alone), 1)  # 57 against 28 when written


def test_keys_from_features_and_from_contacts_agree_in_either_finger_order(mug):
    """The targeted step keys its pool from contacts and triangle normals, the poses it looks for from their
    features: on the same pinches (patch normals given) both give one key, whichever finger is first."""
    path, _ = mug
    obj = analyze_object(path)
    c = candidate_poses(obj, settings=PinchSettings(count=150, seed=1))
    keys = feature_keys(c)
    np.testing.assert_allclose(pinch_keys(c.pinches.points, c.pinches.normals, obj.props), keys, atol=1e-9)
    swapped = pinch_keys(c.pinches.points[:, ::-1], c.pinches.normals[:, ::-1], obj.props)
    np.testing.assert_allclose(swapped, keys, atol=1e-9)
    assert np.ptp(keys, axis=0).min() > 0.1  # every key column varies over the mug's poses


def test_the_targeted_step_finds_on_the_prop_the_width_its_sample_lacks(tmp_path, mug):
    """A rod 10 mm thick and 160 mm long (longer than any pinch), turned another way, against the turned mug whose sampled poses have lost every
    handle pinch: the exact search can only offer the body's. The targeted step finds handle pinches on
    the mug by the rod's features; each obeys every rule, and the best cost falls below the body's."""
    path, mesh = mug
    settings = PinchSettings(count=300, seed=2)
    full = candidate_poses(analyze_object(path), settings=settings)
    no_handle = full.subset(np.flatnonzero(np.linalg.norm(full.pinches.points[:, 1] - full.pinches.points[:, 0],
                                                          axis=1) > 20.0))
    rod_path, _ = _turned(tmp_path, "rod", cylinder(5.0, 160.0, faces=8000).mesh,
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
    assert len(grown_rod) >= len(rod)
    after = float(cost_row(search.grown([grown], [grown_rod]), 0)[0])
    assert after < 0.5 * before
    # and the match runs it before refinement: the refined answer is at least as good
    assert float(cost_row(refined_search([no_handle], rod, model, match, pinch_settings=settings), 0)[0]) <= after + 1e-9


def test_the_targeted_step_is_deterministic_and_skipped_without_refinement(mug, tmp_path):
    path, _ = mug
    settings = PinchSettings(count=200, seed=4)
    box_path, _ = _turned(tmp_path, "box", trimesh.creation.box((30.0, 45.0, 60.0)).subdivide().subdivide())
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
    """The targeted step asked twice with overlapping keys checks each pool candidate once (a third ask checks
    nothing), and what it returns is what a process that never checked any gets, bit for bit."""
    path, _ = mug
    settings = PinchSettings(count=200, seed=5)
    box_path, _ = _turned(tmp_path, "box", trimesh.creation.box((30.0, 45.0, 60.0)).subdivide().subdivide())
    keys = feature_keys(candidate_poses(analyze_object(box_path), settings=settings))
    checked = []
    real = targeted.check_pinches
    monkeypatch.setattr(targeted, "check_pinches", lambda context, p1, p2, **kw: checked.append(len(p1))
                        or real(context, p1, p2, **kw))
    warm = candidate_poses(analyze_object(path), settings=settings)
    targeted.nearest_feasible(warm, keys[:6], settings)
    first = sum(checked)
    again = targeted.nearest_feasible(warm, keys[3:12], settings)
    second = sum(checked) - first
    assert 0 < second < targeted.NEAREST * len(np.unique(keys[3:12], axis=0))  # the shared candidates are not
    targeted.nearest_feasible(warm, keys[3:12], settings)                     # checked again
    assert sum(checked) == first + second
    fresh = targeted.nearest_feasible(candidate_poses(analyze_object(path), settings=settings), keys[3:12], settings)
    for field in ("points", "normals", "face_index", "feasible", "broken", "approach", "kappa_max_per_m"):
        np.testing.assert_array_equal(getattr(again, field), getattr(fresh, field))


def _nearest_spread_mm(points, to):
    """Each grasp's spread distance (either finger order) to the nearest of ``to``, mm."""
    from scipy.spatial import cKDTree

    tree = cKDTree(to.reshape(len(to), -1))
    return np.minimum(tree.query(points.reshape(len(points), -1))[0],
                      tree.query(points[:, ::-1].reshape(len(points), -1))[0])


def test_a_larger_count_holds_the_sample_of_half_of_it_and_spreads_the_rest_away_from_it(mug, monkeypatch):
    """Above the nested threshold, a count's sample begins with the sample of half the count, bit for bit,
    at every level of the chain; the rest comes from a random stream of its own and is spread away from
    the first half: its pinches lie farther from the first half's than as many sampled without it. Every
    pinch kept obeys every rule. Tripods nest the same way."""
    import pinchmatch.grasp.rounds as rounds
    from pinchmatch.grasp.tripods import sample_tripods

    monkeypatch.setattr(rounds, "NESTED_ABOVE", 150)
    path, mesh = mug
    obj = analyze_object(path)
    samples = {c: sample_pinches(obj.context, settings=PinchSettings(count=c, seed=5)) for c in (150, 300, 600)}
    for small, large in ((150, 300), (300, 600)):
        assert len(samples[large]) == large
        np.testing.assert_array_equal(samples[large].points[:small], samples[small].points)
        np.testing.assert_array_equal(samples[large].kappa_max_per_m[:small], samples[small].kappa_max_per_m)
    assert_rules_hold(mesh, samples[600], PinchSettings(count=600, seed=5))
    first, rest = samples[600].points[:300], samples[600].points[300:]
    unaware = sample_pinches(obj.context, settings=PinchSettings(count=300, seed=6)).points
    aware, alone = (np.median(_nearest_spread_mm(p, first)) for p in (rest, unaware))
    assert aware > 1.1 * alone, (aware, alone)
    tripods = {c: sample_tripods(obj.context, settings=PinchSettings(count=c, seed=5, grasp="tripod")) for c in (120, 240)}
    assert len(tripods[240]) == 240
    np.testing.assert_array_equal(tripods[240].points[:120], tripods[120].points)


def test_on_target_a_larger_nested_count_never_gives_a_worse_answer(tmp_path, mug, monkeypatch):
    """A rod, turned another way and moved, against the turned mug: with the sampling nested, the exact search
    at twice the count (refinement off, so no local search) sees every pair the smaller count offers, so its
    best cost on target is never above the smaller count's, for every seed."""
    import pinchmatch.grasp.rounds as rounds

    monkeypatch.setattr(rounds, "NESTED_ABOVE", 120)
    path, _ = mug
    rod_path, _ = _turned(tmp_path, "rod", cylinder(6.0, 90.0, faces=6000).mesh,
                          Rotation.from_euler("zxz", [-70.0, 41.0, 15.0], degrees=True).as_matrix(),
                          np.array([-140.0, 60.0, 95.0]))
    mug_obj, rod_obj = analyze_object(path), analyze_object(rod_path)
    match = MatchSettings(refine=False)
    for seed in (0, 1, 2):  # sampled afresh at each count, seed 0's best at 240 costs 0.23 more than at 120
        best, model = {}, None
        for count in (120, 240):
            settings = PinchSettings(count=count, seed=seed)
            props, virtual = [candidate_poses(mug_obj, settings=settings)], candidate_poses(rod_obj, settings=settings)
            model = model or cost_model(match, props + [virtual])  # one model for both counts
            best[count] = float(cost_row(Search(props, [virtual], model, match), 0)[0])
        assert best[240] <= best[120] + 1e-12, (seed, best)
