"""The search's pair lists: a pool served from a larger pass's list, a pool that grows evaluating a
pair again only when its bound has passed the pair's cost, and a search whose candidates grew, all
against brute force over every pair."""

import collections

import numpy as np
import pytest

from pinchmatch.grasp.analysis import analyze_object
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.match import search as search_module
from pinchmatch.match.candidates import candidate_poses, felt_table, mass_ratio
from pinchmatch.match.cost import pair_cost_blocks, pooled_bound_blocks
from pinchmatch.match.pairs import Ranked
from pinchmatch.match.search import MatchSettings, Search, cost_model, evaluate_pairs
from pinchmatch.mesh.shapes import ellipsoid, torus

from conftest import random_rigid, transformed


@pytest.fixture(scope="module")
def objects(tmp_path_factory):
    """An ellipsoid and a torus, each turned and moved off the origin."""
    tmp = tmp_path_factory.mktemp("pairs")
    out = []
    for k, mesh in enumerate([ellipsoid((30.0, 22.0, 14.0), faces=1300).mesh,
                              torus(faces=2000).mesh]):
        R, t = random_rigid(40 + k)
        path = tmp / f"o{k}.stl"
        transformed(mesh, R, t).export(path)
        out.append(candidate_poses(analyze_object(path), settings=PinchSettings(count=90, seed=k)))
    return out


def every_value(T, V, model, tight):
    """(nt, nv) the value each pair is pooled by: the bound from its separable sum, or its pooled
    bound (the objects stand on nothing: no rest gap is charged)."""
    felt = felt_table(V.table, mass_ratio(T, V))
    if tight:
        return np.concatenate([b for _, b in pooled_bound_blocks(
            T.table, felt, model, block_rows=16)])
    return model.bound_from_separable(np.concatenate([b.copy() for _, b, _ in pair_cost_blocks(
        T.table, felt, model, block_rows=16, with_swapped=False)]))


@pytest.mark.parametrize("tight", [False, True])
def test_a_pool_served_from_a_larger_pass_holds_the_pairs_of_least_value_and_bounds_the_rest(
        objects, tight):
    T, V = objects
    model = cost_model(MatchSettings(), [T, V])
    values = every_value(T, V, model, tight)
    ranked = Ranked.of(*search_module.pool_pairs(T, V, model, 800, 64, tight, raw=True), tight)
    assert np.all(np.diff(ranked.value) >= 0)
    for size in (40, 200, 799):
        assert ranked.serves(size, tight) and not ranked.serves(size, not tight)
        it, iv, rest = ranked.first(size)
        assert len(it) == size and len({(a, b) for a, b in zip(it, iv)}) == size
        left_out = np.ones(values.shape, dtype=bool)
        left_out[it, iv] = False
        # every pair left out is at least the rest
        assert values[left_out].min() >= rest * (1 - 1e-12)
        assert values[it, iv].max() <= rest * (1 + 1e-12)
        # what a pass of that size finds: the same pairs, up to those its quicker threshold leaves
        # out
        f_it, f_iv, _, f_rest = search_module.pool_pairs(T, V, model, size, 64, tight, raw=True)
        assert {(a, b) for a, b in zip(f_it, f_iv)} <= {(a, b) for a, b in zip(it, iv)}
        assert f_rest <= rest * (1 + 1e-12)
    assert not ranked.serves(800, tight)  # the value after the last is not known: a new pass


def counting(monkeypatch):
    """Count every pair the search evaluates."""
    asked = []
    real = search_module.evaluate_pairs

    def evaluate(T, V, it, iv, **kw):
        asked.extend(zip(np.asarray(it).tolist(), np.asarray(iv).tolist()))
        return real(T, V, it, iv, **kw)

    monkeypatch.setattr(search_module, "evaluate_pairs", evaluate)
    return asked


def picks(search, count):
    return [(c.tangible, c.t_pose, c.v_pose, round(c.cost, 12)) for c in search.choices(
        0, [0], count)]


@pytest.mark.parametrize("tight_after", [0, 1, search_module.TIGHT_AFTER])
def test_a_growing_pool_evaluates_each_pair_once_and_finds_what_brute_force_does(
    objects, monkeypatch, tight_after):
    T, V = objects
    settings = MatchSettings(distinct_mm=6.0)
    model = cost_model(settings, [T, V])
    monkeypatch.setattr(search_module, "TIGHT_AFTER", tight_after)
    monkeypatch.setattr(search_module, "MIN_POOL", 5)  # the pools grow many times
    monkeypatch.setattr(search_module, "MAX_POOL", 5)
    asked = counting(monkeypatch)
    search = Search([T], [V], model, settings)
    grown = picks(search, 25)
    # a pair is evaluated again only when it cost at least the pool's bound then (its cost alone
    # was kept) and less than the bound now: it is kept from then on, so never a third time
    times = collections.Counter(asked)
    again = [pair for pair, n in times.items() if n > 1]
    assert max(times.values()) <= 2
    pool = search.pools[(0, 0)]
    costs = evaluate_pairs(T, V, [a for a, _ in again], [b for _, b in again], model=model).cost
    assert (costs < pool.tau).all()
    assert set(again) <= set(zip(pool.it.tolist(), pool.iv.tolist()))
    # the pool remembers each pair evaluated once, at its cost
    seen = pool.seen
    assert len(seen) == len(times) and len(np.unique(seen.key)) == len(seen)
    first = list(times)
    remembered = seen.find(np.array([a for a, _ in first]), np.array([b for _, b in first]))[1]
    exact = evaluate_pairs(T, V, [a for a, _ in first], [b for _, b in first], model=model).cost
    np.testing.assert_array_equal(remembered, exact)
    once = len(asked)
    # a pass per growth, and every pool evaluated afresh
    monkeypatch.setattr(search_module, "RESERVE", 1)
    monkeypatch.setattr(search_module, "SEEN_PAIRS", 0)
    asked.clear()
    assert picks(Search([T], [V], model, settings), 25) == grown
    assert len(asked) > once
    brute = evaluate_pairs(T, V, np.repeat(np.arange(len(T)), len(V)),
                           np.tile(np.arange(len(V)), len(T)), model=model).cost
    assert grown[0][3] == pytest.approx(brute.min(), rel=1e-12)
    assert sorted(c for *_, c in grown) == [c for *_, c in grown]


def test_a_search_whose_candidates_grew_finds_what_a_search_of_them_all_does(objects, monkeypatch):
    T, V = objects
    settings = MatchSettings(distinct_mm=6.0)
    model = cost_model(settings, [T, V])
    monkeypatch.setattr(search_module, "MIN_POOL", 5)
    monkeypatch.setattr(search_module, "MAX_POOL", 5)
    first = Search([T.subset(np.arange(60))], [V.subset(np.arange(70))], model, settings)
    first.best_cost(0, 0)
    first.pool(0, 0, 80)  # a pool with a list to carry over
    grown = first.grown([T], [V])
    ranked = grown.pools[(0, 0)].ranked  # the old list and the new pairs' lists, merged
    values = every_value(T, V, model, ranked.tight)
    listed = np.zeros(values.shape, dtype=bool)
    listed[ranked.it, ranked.iv] = True
    assert np.isfinite(ranked.rest) and listed.sum() == len(ranked.it) > 80
    assert values[~listed].min() >= ranked.rest * (1 - 1e-9)  # complete below its rest
    assert np.allclose(ranked.value, values[ranked.it, ranked.iv], rtol=1e-9, atol=1e-12)
    assert (ranked.value < ranked.rest).all() and np.all(np.diff(ranked.value) >= 0)
    asked = counting(monkeypatch)
    found = picks(grown, 20)
    assert len(asked) == len(set(asked))
    assert found == picks(Search([T], [V], model, settings), 20)
