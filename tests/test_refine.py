"""Refinement after the search: cheaper answers, every refined pose feasible, less hanging on the
seed."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pinchmatch.grasp.analysis import analyze_object
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.match.candidates import candidate_poses
from pinchmatch.match.refine import MOVES, move_directions, moved_poses, refined_search
from pinchmatch.match.scene import match_scene
from pinchmatch.match.search import MatchSettings, Search, cost_model, cost_row
from pinchmatch.mesh.shapes import cylinder, ellipsoid
from test_pinches import assert_rules_hold

COUNT = 250


@pytest.fixture(scope="module")
def objects(tmp_path_factory):
    """An egg-like virtual object and two props (a larger ellipsoid and a cylinder), each sampled
    with three seeds."""
    folder = tmp_path_factory.mktemp("refine")
    meshes = {"egg": ellipsoid((30.0, 22.0, 16.0), faces=6000).mesh,
              "oval": ellipsoid((38.0, 26.0, 20.0), faces=6000).mesh,
              "rod": cylinder(14.0, 70.0, faces=6000).mesh}
    out = {}
    for name, mesh in meshes.items():
        mesh.export(folder / f"{name}.stl")
        obj = analyze_object(folder / f"{name}.stl")
        out[name] = [candidate_poses(obj, settings=PinchSettings(count=COUNT, seed=s))
                     for s in range(3)]
    return out


def settings_for(seed):
    return PinchSettings(count=COUNT, seed=seed)


def test_refinement_never_costs_more_and_its_poses_keep_every_rule(objects):
    tangibles, virtual = [objects["oval"][0], objects["rod"][0]], objects["egg"][0]
    model = cost_model(MatchSettings(), tangibles + [virtual])
    sampled = cost_row(Search(tangibles, [virtual], model, MatchSettings(refine=False)), 0)
    search = refined_search(tangibles, virtual, model, MatchSettings(),
                            pinch_settings=settings_for(0))
    refined = cost_row(search, 0)
    assert (refined <= sampled + 1e-12).all()
    assert refined.min() < 0.9 * sampled.min()  # the sample's best is not where the cost is lowest
    grown = [search.virtuals[0]] + list(search.tangibles)
    base = [virtual] + tangibles
    assert sum(len(g) - len(b) for g, b in zip(grown, base)) > 0
    for g, b in zip(grown, base):
        added = g.subset(np.arange(len(b), len(g)))
        assert (added.index == -1).all() and np.array_equal(g.index[:len(b)], b.index)
        if len(added):
            assert_rules_hold(g.obj.loaded.mesh, added.pinches, settings_for(0))


def test_the_answer_hangs_less_on_the_seed(objects):
    """Three seeds: refined, the best costs agree far better than the sampled ones do."""
    def best(seed, refine):
        tangibles, virtual = [objects["oval"][seed], objects["rod"][seed]], objects["egg"][seed]
        scene = match_scene(tangibles, [virtual],
                            settings=MatchSettings(refine=refine, landing_mm=0.0),
                            pinch_settings=settings_for(seed))
        return scene.matches[0].best

    def spread(costs):
        return (max(costs) - min(costs)) / np.median(costs)

    sampled = [best(s, False) for s in range(3)]
    refined = [best(s, True) for s in range(3)]
    assert max(c.cost for c in refined) < min(c.cost for c in sampled)
    assert spread([c.cost for c in refined]) < 0.5 * spread([c.cost for c in sampled])
    assert len({c.tangible for c in refined}) == 1


def test_moves_turn_with_the_object():
    """The moves come from the pinch and the object's axis: a rotated pinch moves as the rotation of
    the original's moves."""
    rng = np.random.default_rng(3)
    points = rng.normal(size=(5, 2, 3)) * 20.0
    axis = np.array([0.3, -0.2, 0.93])
    axis /= np.linalg.norm(axis)
    R = Rotation.from_rotvec([0.4, -1.1, 0.7]).as_matrix()
    a = move_directions(points, axis)
    b = move_directions(points @ R.T, R @ axis)
    np.testing.assert_allclose(b, a @ R.T, atol=1e-12)
    np.testing.assert_allclose(np.einsum("kid,kd->ki", a, points[:, 1] - points[:, 0]), 0.0,
                               atol=1e-9)
    assert len(np.unique(MOVES, axis=0)) == len(MOVES) == 16


def test_moved_contacts_stay_on_the_surface_within_the_step(objects):
    egg = objects["egg"][0]
    poses = np.arange(10)
    points, faces, which = moved_poses(egg, poses, np.full(10, 2.0))
    assert len(points) > 0.9 * 16 * 10
    tri = egg.obj.loaded.mesh.triangles[faces]  # each contact lies in its triangle's plane
    normal = np.cross(tri[:, :, 1] - tri[:, :, 0], tri[:, :, 2] - tri[:, :, 0])
    offset = np.einsum("kid,kid->ki", points - tri[:, :, 0],
                       normal / np.linalg.norm(normal, axis=2, keepdims=True))
    assert np.abs(offset).max() < 1e-6
    moved = np.linalg.norm(points - egg.pinches.points[poses][which], axis=2)
    assert moved.max() < 2.0 * 2.0 and (moved.max(axis=1) > 1.0).all()


def test_given_poses_are_not_moved(objects):
    egg = objects["egg"][0]
    p = egg.pinches.points[:20]
    given = candidate_poses(egg.obj, settings=settings_for(0), given=(p[:, 0], p[:, 1]))
    tangible = objects["oval"][0]
    search = refined_search([tangible], given, cost_model(MatchSettings(), [tangible, given]),
                            MatchSettings(), pinch_settings=settings_for(0))
    assert len(search.virtuals[0]) == len(given)


def test_reach_checked_later_gives_what_one_check_gives(objects):
    """Every rule but reach, then reach: the same pinches, arrays and all, as one check of every
    rule."""
    from pinchmatch.grasp.pinches import ARRAY_FIELDS, check_pinches, check_reach

    rod = objects["rod"][0]
    rng = np.random.default_rng(3)
    points = rod.pinches.points[:60] + rng.normal(scale=1.5, size=(60, 2, 3))  # some off the rules
    settings = settings_for(0)
    ctx = rod.obj.context
    at_once = check_pinches(ctx, points[:, 0], points[:, 1], settings=settings, thorough=False)
    first = check_pinches(ctx, points[:, 0], points[:, 1], settings=settings, with_reach=False)
    assert np.isnan(first.approach).all() and not first.broken[:, 5].any()
    later = check_reach(ctx, first, settings=settings, thorough=False)
    for name in ARRAY_FIELDS:
        assert np.array_equal(getattr(at_once, name), getattr(later, name), equal_nan=True), name
    assert 0 < at_once.feasible.sum() < len(points)


def test_a_pair_takes_its_cheapest_move_that_the_hand_reaches(objects):
    """Options are walked by cost; one with an unreachable pose on either side is passed over."""
    from pinchmatch.match.refine import _Moves, _Pair, _take_reachable

    def moves(base, reached):
        m = _Moves(None, np.zeros(len(reached), dtype=np.int64), np.zeros((len(reached), 3)), base)
        m.reached[:] = reached
        return m

    t = moves(100, [-1, 1, 1, -1])  # tangible moves 100..103: 100 and 103 unreachable
    v = moves(50, [1, -1, 1])  # virtual moves 50..52: 51 unreachable
    live = [_Pair(0, 0, 0, 1.0, 4.0), _Pair(0, 1, 1, 1.0, 4.0), _Pair(0, 2, 2, 1.0, 4.0)]
    options = {
        0: (np.array([100, 101, 101, 102]), np.array([50, 51, 52, 50]),
            np.array([0.1, 0.2, 0.3, 0.4])),
        1: (np.array([103, 7]), np.array([50, 51]), np.array([0.1, 0.2])),  # none reachable
        2: (np.array([3]), np.array([4]), np.array([0.5])),  # sampled poses: reachable
    }
    taken = _take_reachable(live, options, {0: t}, v, None, None, settings_for(0))
    assert taken == {0: (101, 52, 0.3), 2: (3, 4, 0.5)}


def test_an_option_is_taken_only_once_the_hand_is_known_to_reach_it(monkeypatch):
    """Options past the first wave are checked in a later wave before one is taken: none is taken
    unchecked."""
    from pinchmatch.match import refine as refine_module
    from pinchmatch.match.refine import _Moves, _Pair, _take_reachable

    truth = {100: -1, 101: -1, 102: -1, 103: 1}  # what the hand would find, move by move

    def confirm(context, moves, rows, settings):
        rows = np.unique(rows)
        moves.reached[rows] = [truth[moves.base + r] for r in rows]

    monkeypatch.setattr(refine_module, "_confirm", confirm)
    # confirm needs none
    grown = SimpleNamespace(current=SimpleNamespace(obj=SimpleNamespace(context=None)))
    for last, expected in ((102, {}), (103, {0: (103, 5, 0.4)})):
        t = _Moves(None, np.zeros(4, dtype=np.int64), np.zeros((4, 3)), 100)
        v = _Moves(None, np.zeros(0, dtype=np.int64), np.zeros((0, 3)), 50)
        its = np.array([100, 101, last])
        options = {0: (its, np.full(3, 5), np.array([0.1, 0.2, 0.4]))}
        taken = _take_reachable([_Pair(0, 0, 5, 1.0, 4.0)], options, {0: t}, v, [grown], grown,
                                settings_for(0))
        assert taken == expected
        assert (t.reached[its - 100] != 0).all()  # each option looked at was checked


def test_a_pinch_along_the_axis_still_moves_across_its_line():
    points = np.array([[[0.0, 0.0, -20.0], [0.0, 0.0, 20.0]], [[-5.0, 0.0, 0.0], [5.0, 0.0, 0.0]]])
    dirs = move_directions(points, np.array([0.0, 0.0, 1.0]))
    u = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    np.testing.assert_allclose(np.einsum("kid,kd->ki", dirs, u), 0.0, atol=1e-12)  # across the line
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=2), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.einsum("kd,kd->k", dirs[:, 0], dirs[:, 1]), 0.0, atol=1e-12)


def test_a_moved_pose_keeps_the_triangle_of_each_contact_that_did_not_move(objects):
    """Each move names the triangle under each of its contacts: the one the finger closed onto for a
    contact that moved, the pose's own for one that did not, whichever poses are moved together and
    in what order: a pose's moves do not depend on what else is moved with it."""
    T = objects["rod"][0]
    ctx = T.obj.context
    poses = np.array([len(T) - 1, 7, len(T) // 2, 7])
    points, faces, which = moved_poses(T, poses, np.full(len(poses), 3.0))
    for contact in (0, 1):
        still = np.flatnonzero(np.abs(points[:, contact]
                                      - T.pinches.points[poses[which], contact]).max(axis=1) == 0)
        assert (len(still)
                and (faces[still, contact]
                     == T.pinches.face_index[poses[which[still]], contact]).all())
    # every contact lies on its triangle's plane
    tri = ctx.mesh.triangles[faces]
    normal = np.cross(tri[:, :, 1] - tri[:, :, 0], tri[:, :, 2] - tri[:, :, 0])
    offset = np.einsum("kid,kid->ki", points - tri[:, :, 0],
                       normal / np.linalg.norm(normal, axis=2, keepdims=True))
    assert np.abs(offset).max() < 1e-6
    # the same pose moved alone or with others gives the same moves
    alone = moved_poses(T, poses[1:2], np.full(1, 3.0))
    np.testing.assert_array_equal(alone[1], faces[which == 1])
    np.testing.assert_array_equal(alone[0], points[which == 1])


def test_refinement_starts_from_more_pairs_at_a_larger_count(objects, monkeypatch):
    """Up to the default count, 2 distinct best pairs on the best prop and 1 on each other
    contender; in proportion above it (a denser sample holds more pairs near each good one), at most
    16 and 8. The starts handed to refinement are the search's best distinct pairs per prop, as many
    as that says."""
    import pinchmatch.match.refine as refine_module

    assert [refine_module.seed_counts(n) for n in (50, 1000, 1001, 4000, 100_000)] == \
        [(2, 1), (2, 1), (3, 2), (8, 4), (16, 8)]
    tangibles, virtual = [objects["oval"][0], objects["rod"][0]], objects["egg"][0]
    model = cost_model(MatchSettings(), tangibles + [virtual])
    starts = []
    real = refine_module.refine
    monkeypatch.setattr(refine_module, "CONTENDER_RATIO", 100.0)  # both props contend
    monkeypatch.setattr(refine_module, "refine", lambda t, v, seeds, *a,
                        **k: starts.append(seeds) or real(t, v, seeds, *a, **k))
    for count in (1000, 3000):
        refined_search(tangibles, virtual, model, MatchSettings(),
                       pinch_settings=PinchSettings(count=count, seed=0))
    for seeds, (on_best, on_other) in zip(starts, [(2, 1), (6, 3)]):
        per_prop = {t: [s for s in seeds if s[0] == t] for t in {s[0] for s in seeds}}
        best = min(per_prop, key=lambda t: min(s[3] for s in per_prop[t]))
        assert len(per_prop[best]) == on_best
        assert all(len(v) == on_other for t, v in per_prop.items() if t != best)
        # best first
        assert all(np.diff([s[3] for s in v]).min(initial=0.0) >= 0.0 for v in per_prop.values())
        assert len(per_prop) == 2
