"""Step #3: the exact search for a virtual object's best tangibles and pinch pairs, registered.

The search is exact over the poses it is given (sampled, and refined:
:mod:`pinchmatch.match.refine`; :mod:`pinchmatch.match.scene` runs it for a whole scene). For each
(virtual object, tangible) pair of objects:

1. A lower bound of every pose pair's cost is computed blockwise with BLAS: from
   the separable part of the cost (the paper's seven criteria and the lower
   bound of ``mass``: :func:`pinchmatch.match.cost.pair_cost_blocks`), plus the
   least that the placement's rest gap can add on a prop standing on a table
   (:class:`pinchmatch.match.rest.RestFloor`), keeping only the ``pool``
   smallest values; ``tau`` is the smallest value left out.
2. The pooled pairs are registered and get their exact cost (the exact
   ``mass`` term, and ``--keep-upright``). Every pair left out costs at
   least ``tau``, so the pooled pairs costing less than ``tau`` are exactly
   the cheapest pairs of all. If they do not hold the best pair and
   ``top_k`` distinct alternatives, the pool grows and step 1 repeats, from
   the larger list step 1 kept where it can (:mod:`pinchmatch.match.pairs`),
   evaluating only pairs not evaluated before.

Alternatives are picked greedily by cost among pairs that are not near
duplicates of those already picked: a pair is a near duplicate of another
when it uses the same tangible and both its pinches, the tangible's and the
virtual's, lie within ``distinct_mm`` of the other's (each contact, in the
better finger order).

The result does not depend on the pool sizes, so a search of one virtual
object alone (what parallel runs do) gives the same
bits as a search of the whole scene: every pair cheaper than tau is pooled,
the greedy pick walks pairs by cost, and ties go to the lower (tangible,
tangible pose, virtual pose).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..config import MatchSettings  # noqa: F401 (re-exported)
from .candidates import Candidates, felt_table, mass_ratio, pair_terms
from .cost import CostModel, feature_ranges, pair_cost_blocks, pooled_bound_blocks, total
from .redirect import Redirect, pair_budget, placed_transform, redirection, seen_turn
from .choice import Choice, Pose, pinch_distance  # noqa: F401 (re-exported)
from .pairs import PairResult, Ranked, Seen, concat_pairs, take_pairs
from .register import FLIP_COSINE, register_poses
from .comfort import approach_angles, comfortable_poses
from .rest import rest_floor, rested
from ..grasp.spread import other_order

#: pose pairs kept per (virtual, tangible) object pair before the exact evaluation: one per
#: POOL_PAIRS_PER_KEPT pose pairs, within [MIN_POOL, MAX_POOL]; grows x4 when short
MIN_POOL, MAX_POOL, POOL_PAIRS_PER_KEPT = 256, 4096, 4096
#: a pool grown this many times (x4 each) is selected by the pooled bound, not the separable sum
TIGHT_AFTER = 2
#: the pooled bound's margin for the round-off of its matrix products (relative)
TIGHT_ROUND_OFF = 1e-9
#: pooled pairs are evaluated this many at a time (memory: about 2 kB per pair while evaluated)
EVALUATE_CHUNK = 65_536
#: a blockwise pass keeps this many times its pool's size, in order, where the pool's next growth
#: selects by the same sum (separable, or the pooled bound): growths within them need no new pass
RESERVE = 4
#: pairs a pool remembers having evaluated, kept or not (16 bytes each, and about 250 for each
#: kept), so that a growth evaluates only pairs it has not seen
SEEN_PAIRS = 2_097_152


def initial_pool(n_tangible: int, n_virtual: int) -> int:
    """The first pool size for n_tangible x n_virtual pose pairs.

    The blockwise pass costs in proportion to all pairs, the exact evaluation to the pool: a pool
    that grows with the pairs keeps the evaluation a small share of the search at every size. The
    result does not depend on it (see the module's notes)."""
    return int(np.clip(n_tangible * n_virtual // POOL_PAIRS_PER_KEPT, MIN_POOL, MAX_POOL))

def cost_model(settings: MatchSettings, candidates: list[Candidates], *,
               ranges: np.ndarray | None = None) -> CostModel:
    """The run's cost model; ``range`` takes each feature's range over every candidate of the run
    (or ``ranges``, when they were gathered elsewhere, see
    :func:`pinchmatch.match.cost.ranges_from_bounds`).

    Parameters
    ----------
    settings : MatchSettings
        The match's weights, criteria, normalisation and pooling.
    candidates : list of Candidates
        Every object of the run (their features' ranges, under ``normalize="range"``).
    ranges : ndarray, optional
        The features' ranges when they were gathered elsewhere.

    Returns
    -------
    CostModel
        The cost every pair of the run is judged by.

    Examples
    --------
    >>> model = cost_model(MatchSettings(weights={"width": 2.0}), [])
    >>> model.pooling, model.normalize, model.weights["width"], model.weights["com"]
    ('quick', 'jnd', 2.0, 0.0)
    """
    if settings.normalize == "range" and ranges is None:
        ranges = feature_ranges(*[c.table for c in candidates])
    return CostModel(dict(settings.weights), settings.normalize,
                     ranges if settings.normalize == "range" else None, tuple(settings.criteria),
                     settings.pooling,
                     (settings.rest_sink_mm_per_jnd, settings.rest_float_mm_per_jnd),
                     settings.scan_trust)


def evaluate_pairs(
    tangible: Candidates,
    virtual: Candidates,
    it: np.ndarray,
    iv: np.ndarray,
    *,
    model: CostModel | None = None,
    keep_upright: bool | None = None,
    swapped: bool | None = None,
    redirect: Redirect | None = None,
    user_mm=None,
) -> PairResult:
    """Register k pose pairs (tangible pose ``it[i]``, virtual pose ``iv[i]``) and give their exact
    cost, in the better finger order, or in the order ``swapped`` when it is given.

    ``model`` defaults to :func:`cost_model` of the default settings over the two objects;
    ``keep_upright`` (default off) charges a placement that turns the virtual object upside down
    an infinite cost. With ``redirect`` the virtual object stays where it is and the hand is
    redirected (:mod:`pinchmatch.match.redirect`): the redirection joins the cost, a pair beyond the
    budget is not allowed, and none is flipped. A tangible that stands on a table allows only the
    poses reached comfortably from where the user stands (``user_mm``, the level's frame; default:
    where the hand starts), unless it has none (:mod:`pinchmatch.match.comfort`).

    Parameters
    ----------
    tangible, virtual : Candidates
        The prop's and the virtual object's poses.
    it, iv : (k,) int
        The pairs' tangible and virtual pose indices.
    model : CostModel, optional
        The cost model.
    keep_upright : bool, optional
        Charge a placement that turns the virtual object upside down an infinite cost.
    swapped : bool, optional
        The finger order of every pair (default: each pair's better one).
    redirect : Redirect, optional
        Keep the virtual object where it is and redirect the hand (``--placement fixed``).
    user_mm : (3,) float64, optional
        Where the user stands, in the level's frame.

    Returns
    -------
    PairResult
        Per pair the exact cost, its terms, the finger order, the registration (mm), whether it
        flips the object, the mass offset, whether it is allowed, the redirection and the rest gap.

    Examples
    --------
    >>> from pinchmatch import PinchSettings, analyze_object, candidate_poses
    >>> settings = PinchSettings(count=50, seed=0)
    >>> can = candidate_poses(analyze_object(can_obj, units="m"), settings=settings)
    >>> result = evaluate_pairs(can, can, np.array([0, 1]), np.array([0, 0]))
    >>> float(result.cost[0]), bool(result.cost[1] > 0)  # a pose on itself costs nothing
    (0.0, True)
    """
    model = model or cost_model(MatchSettings(), [tangible, virtual])
    keep_upright = bool(keep_upright)
    it, iv = np.asarray(it, dtype=np.int64), np.asarray(iv, dtype=np.int64)
    tp, tn = tangible.pinches.points[it], tangible.pinches.normals[it]
    t_rows = tangible.table[it]
    t_props, v_props = tangible.obj.props, virtual.obj.props
    up_t, up_v = tangible.obj.loaded.up, virtual.obj.loaded.up
    reachable = comfortable_poses(tangible, user_mm)
    results = []
    for order in (False, True) if swapped is None else (swapped,):
        vp, vn, v_rows = virtual.pinches.points[iv], virtual.pinches.normals[iv], virtual.table[iv]
        if order:
            other = other_order(vp.shape[1])
            vp, vn, v_rows = vp[:, other], vn[:, other], v_rows[:, other]
        X = register_poses(tp, tn, vp, vn, tangible_com=t_props.com_mm, virtual_com=v_props.com_mm,
                           tangible_axis=t_props.principal_axis,
                           virtual_axis=v_props.principal_axis)
        # registered, the virtual object turns with the registration; fixed, it stays as the level
        # has it, seen from the prop's frame (the registration is then the hand's warp onto the
        # prop, not a placement)
        R = seen_turn(tangible.obj, X[:, :3, :3], redirect is not None)
        terms, delta = pair_terms(tangible, virtual, t_rows, v_rows, model, R=R, t_points=tp,
                                  v_points=vp)
        if redirect is None:
            flipped = (R @ up_v) @ up_t < FLIP_COSINE
            allowed = ~flipped if keep_upright else np.ones(len(it), dtype=bool)
            moved_terms = np.zeros((len(it), 2))
        else:
            # the virtual object stays where it is; flipped when the prop stands otherwise than the
            # level's up
            moved = redirection(tangible.obj, tp, vp, redirect)
            flipped = np.full(len(it), bool((R @ up_v) @ up_t < FLIP_COSINE))
            allowed, moved_terms = moved.allowed, moved.terms
        if reachable is not None:
            allowed = allowed & reachable[it]
        gap, rest = rested(tangible.obj, virtual.obj, X, model, redirect)
        cost = np.where(allowed,
                        total(terms, model, moved_terms if redirect is not None else None, rest),
                        np.inf)
        results.append(PairResult(cost, terms, np.full(len(it), order), X, flipped, delta, allowed,
                                  moved_terms, gap, rest))
    if len(results) == 1:
        return results[0]
    a, b = results
    pick_b = b.cost < a.cost
    return PairResult(**{
        f.name: np.where(pick_b.reshape((-1,) + (1,) * (getattr(a, f.name).ndim - 1)),
                         getattr(b, f.name), getattr(a, f.name))
        for f in dataclasses.fields(a)
    })


def _only_rows(rows: np.ndarray, n_virtual: int, budget=None):
    """A blockwise pass's ``extra`` that leaves out the tangible poses not in ``rows`` (bool)
    against each of ``n_virtual`` virtual poses, besides what ``budget`` (another such function, or
    None) adds and leaves out."""
    def block(start: int, stop: int):
        term, ok = budget(start, stop) if budget is not None else (0.0, True)
        return term, np.broadcast_to(ok & rows[start:stop, None], (stop - start, n_virtual))

    return block


def pool_pairs(tangible: Candidates, virtual: Candidates, model: CostModel, size: int,
               block_rows: int, tight: bool = False, moments: tuple | None = None,
               redirect: Redirect | None = None, *, raw: bool = False, user_mm=None):
    """The ``size`` pose pairs of least bound on their cost, and tau, a cost no pair left out is
    below. The bound: the model's bound from the separable sum
    (:meth:`~pinchmatch.match.cost.CostModel.bound_from_separable`; ``tight``: the pooled bound,
    :func:`pinchmatch.match.cost.pooled_bound_blocks`), plus the least that the placement's rest gap
    can add (:class:`~pinchmatch.match.rest.RestFloor`). With ``moments`` ((mean, variance) of the
    tangible's rows, the same of the virtual's), the sum is the expected one of
    :mod:`pinchmatch.match.steady` over the first ``len(mean)`` poses of each, and no floor is
    added. With ``redirect`` (the virtual object stays in the level) the sum gains a lower bound
    of the redirection angle's contribution and the pairs beyond the budget are left out
    (:func:`pinchmatch.match.redirect.pair_budget`).

    The tangible's poses that the user cannot reach comfortably (``user_mm``:
    :func:`evaluate_pairs`) are left out too.

    Returns (it, iv, bound, tau); tau is inf when no pair was left out. ``raw``: tau is the least
    bound of a pair left out, without the margin for round-off.
    """
    ratio = mass_ratio(tangible, virtual)
    t_table, v_table, spreads = tangible.table, virtual.table, None
    if moments is not None:
        (t_table, t_var), (v_table, v_var) = moments
        # a variance scales by the ratio squared
        spreads = (t_var, felt_table(felt_table(v_var, ratio), ratio))
    nv = len(v_table)
    kept_val = np.zeros(0)
    kept_idx = np.zeros(0, dtype=np.int64)
    tau = np.inf
    felt = felt_table(v_table, ratio)
    budget = None
    if redirect is not None:
        budget = pair_budget(tangible.obj, tangible.pinches.points[:len(t_table)].mean(axis=1),
                             virtual.pinches.points[:nv].mean(axis=1), redirect)
    reachable = comfortable_poses(tangible, user_mm)
    if reachable is not None:
        budget = _only_rows(reachable[:len(t_table)], nv, budget)
    if tight:
        blocks = ((start, bound, None)
                  for start, bound in pooled_bound_blocks(t_table, felt, model, extra=budget))
    else:
        blocks = pair_cost_blocks(t_table, felt, model, block_rows=block_rows, with_swapped=False,
                                  spreads=spreads, extra=budget)
    floor = rest_floor(tangible, virtual, model, redirect) if moments is None else None
    extra_weight = 0.0 if redirect is None else 1.0
    for start, block, _ in blocks:
        if not tight:  # the separable sum's bound on the cost, in the pass's own buffer
            block = model.bound_from_separable(block, extra_weight=extra_weight, out=block)
        if floor is not None:
            floor.add_to(block, start)
        flat = block.ravel()
        if not np.isfinite(tau) and flat.size > 4 * size:
            # a first threshold from a subsample, so that the full block is only compared, never
            # partitioned; every pair left out costs at least tau, whatever the estimate
            step = max(1, flat.size // (64 * size))
            sub = flat[::step]
            kth = min(len(sub) - 1, max(1, size // step))
            tau = float(np.partition(sub, kth)[kth])
        sel = np.flatnonzero(flat < tau) if np.isfinite(tau) else np.arange(flat.size)
        vals = np.concatenate([kept_val, flat[sel]])
        idx = np.concatenate([kept_idx, sel + start * nv])
        if len(vals) > size:
            part = np.argpartition(vals, size)
            tau = min(tau, float(vals[part[size]]))
            keep = part[:size]
            vals, idx = vals[keep], idx[keep]
        kept_val, kept_idx = vals, idx
    return kept_idx // nv, kept_idx % nv, kept_val, tau if raw else _bound(tau)


def _bound(value: float) -> float:
    """The least cost of a pair whose bound (:func:`pool_pairs`) is at least ``value``: the value,
    less a margin for the round-off of its matrix products."""
    return value * (1.0 - TIGHT_ROUND_OFF)


@dataclass
class _PairPool:
    """Exactly evaluated pose pairs of one (virtual, tangible) object pair, all costing less than
    tau: the first ``size`` of the list ``ranked`` (a pass's, with the passes of pairs added since
    merged in), grown from ``first``; and the pairs evaluated for it (None past ``SEEN_PAIRS``)."""

    tangible: int
    it: np.ndarray
    iv: np.ndarray
    result: PairResult
    tau: float
    size: int
    first: int
    ranked: Ranked
    seen: Seen | None


class Search:
    """The exact search of a scene: per (virtual, tangible) a pool of the cheapest pose pairs,
    exactly evaluated, grown on demand until it provably holds the best pairs (see the module's
    notes)."""

    def __init__(self, tangibles, virtuals, model, settings):
        self.tangibles, self.virtuals, self.model, self.settings = (tangibles, virtuals, model,
                                                                    settings)
        self.pools: dict[tuple[int, int], _PairPool] = {}

    def pool(self, j: int, t: int, size: int | None = None) -> _PairPool:
        old = self.pools.get((j, t))
        if old is not None and (size is None or old.size >= size or not np.isfinite(old.tau)):
            return old
        T, V = self.tangibles[t], self.virtuals[j]
        size = size or initial_pool(len(T), len(V))
        first = old.first if old is not None else size
        tight = self._tight(size, first)
        ranked = old.ranked if old is not None else None
        if ranked is None or not ranked.serves(size, tight):
            ranked = Ranked.of(*self._pass(T, V, size, first), tight)
        it, iv, rest = ranked.first(size)
        tau = _bound(rest)
        it, iv, result, seen = self._below(T, V, it, iv, tau, old.seen if old is not None else None)
        pool = _PairPool(t, it, iv, result, tau, size, first, ranked, seen)
        self.pools[(j, t)] = pool
        return pool

    def _pass(self, T: Candidates, V: Candidates, size: int, first: int,
              rows: tuple | None = None) -> tuple:
        """:func:`pool_pairs` for a pool of ``size`` grown from ``first`` (the least value left out,
        raw), keeping ``RESERVE`` times as many where the pool's next growth selects as this one
        does; over the pairs of the poses ``rows`` (t_rows, v_rows) only, where given (indices of
        T's and V's)."""
        tight = self._tight(size, first)
        limit = size * RESERVE if self._tight(size * 4, first) == tight else size
        if rows is None:
            return pool_pairs(T, V, self.model, limit, self.settings.block_rows, tight,
                              redirect=self.settings.redirect, raw=True,
                              user_mm=self.settings.user_mm)
        t_rows, v_rows = rows
        it, iv, value, rest = pool_pairs(T.subset(t_rows), V.subset(v_rows), self.model, limit,
                                         self.settings.block_rows, tight,
                                         redirect=self.settings.redirect, raw=True,
                                         user_mm=self.settings.user_mm)
        return t_rows[it], v_rows[iv], value, rest

    def _tight(self, size: int, first: int) -> bool:
        """Pool by the pooled bound once a pool has grown ``TIGHT_AFTER`` times past its ``first``
        size under ``quick`` pooling: the separable sum's bound was too loose to close it."""
        return self.model.pooling == "quick" and size >= first * 4**TIGHT_AFTER

    def _below(self, T: Candidates, V: Candidates, it: np.ndarray, iv: np.ndarray, tau: float,
               seen: Seen | None = None):
        """The pairs (it, iv) whose exact cost is below ``tau``, in the order given, their
        evaluation, and the pairs evaluated so far: ``seen``'s, whose evaluation is taken from it,
        and those evaluated here (None once more than ``SEEN_PAIRS``). Evaluated ``EVALUATE_CHUNK``
        pairs at a time, so that a pool of millions (a prop whose poses all look alike) never holds
        them all at once."""
        if seen is not None:
            at, cost = seen.find(it, iv)
        else:
            at, cost = np.full(len(it), -1), np.full(len(it), np.nan)
        # evaluated: the pairs never seen, and those seen, not kept, and below tau now; a pair seen
        # costing at least tau is left out by its cost
        new = np.flatnonzero((at < 0) & ~(cost >= tau))
        remember = (0 if seen is None else len(seen)) + len(new) <= SEEN_PAIRS
        keep, parts, costs = [], [], []
        for start in range(0, max(len(new), 1), EVALUATE_CHUNK):
            # once at least: an empty result has its fields
            rows = new[start:start + EVALUATE_CHUNK]
            result = evaluate_pairs(T, V, it[rows], iv[rows], model=self.model,
                                    keep_upright=self.settings.keep_upright,
                                    redirect=self.settings.redirect, user_mm=self.settings.user_mm)
            costs.append(result.cost)
            below = np.flatnonzero(result.cost < tau)
            keep.append(rows[below])
            parts.append(take_pairs(result, below))
        fresh = len(keep)  # the parts evaluated here
        known = np.flatnonzero(at >= 0)
        if len(known):
            result = take_pairs(seen.kept, at[known])
            below = np.flatnonzero(result.cost < tau)
            keep.append(known[below])
            parts.append(take_pairs(result, below))
        if remember:
            kept = np.concatenate(keep[:fresh])
            args = (it[new], iv[new], np.concatenate(costs), it[kept], iv[kept],
                    concat_pairs(parts[:fresh]))
            seen = seen.plus(*args) if seen is not None else Seen.of(*args)
        keep = np.concatenate(keep)
        order = np.argsort(keep, kind="stable")
        keep, result = keep[order], take_pairs(concat_pairs(parts), order)
        return it[keep], iv[keep], result, seen if remember else None

    def grown(self, tangibles: list, virtuals: list) -> "Search":
        """The search over the same objects with poses appended to their candidates (each list
        starts with this search's): pools known here carry over. Each pool's list takes the new
        pairs' own blockwise passes (:meth:`pool`'s), and the grown pool of the same size is that
        list's first pairs: only those not evaluated before are evaluated."""
        out = Search(tangibles, virtuals, self.model, self.settings)
        for (j, t), old in self.pools.items():
            T, V = tangibles[t], virtuals[j]
            n_t, n_v = len(self.tangibles[t]), len(self.virtuals[j])
            tight = self._tight(old.size, old.first)
            if old.ranked is not None and old.ranked.tight == tight:
                new = ((np.arange(n_t, len(T)), np.arange(len(V))),
                       (np.arange(n_t), np.arange(n_v, len(V))))
                ranked = old.ranked.merged([out._pass(T, V, old.size, old.first, rows)
                                            for rows in new
                                            if len(rows[0]) and len(rows[1])])
            else:
                ranked = Ranked.of(*out._pass(T, V, old.size, old.first), tight)
            it, iv, rest = ranked.first(old.size)
            tau = _bound(rest)
            seen = old.seen or Seen.of(old.it, old.iv, old.result.cost, old.it, old.iv, old.result)
            it, iv, result, seen = out._below(T, V, it, iv, tau, seen)
            out.pools[(j, t)] = _PairPool(t, it, iv, result, tau, old.size, old.first, ranked, seen)
        return out

    def best_cost(self, j: int, t: int) -> float:
        """Exact minimum cost of virtual j on tangible t (inf if no pair is allowed)."""
        while True:
            pool = self.pool(j, t)
            if len(pool.it) or not np.isfinite(pool.tau):
                return float(pool.result.cost.min()) if len(pool.it) else np.inf
            self.pool(j, t, pool.size * 4)

    def choices(self, j: int, allowed_tangibles: list[int], count: int) -> list[Choice]:
        """Up to ``count`` distinct best choices for virtual j among the allowed tangibles."""
        while True:
            pools = [self.pool(j, t) for t in allowed_tangibles]
            tau = min(p.tau for p in pools)
            picks = self._greedy(j, pools, tau, count)
            if len(picks) >= count or not np.isfinite(tau):
                return picks
            smallest = min((p for p in pools if np.isfinite(p.tau)), key=lambda p: p.tau)
            self.pool(j, smallest.tangible, smallest.size * 4)

    def _greedy(self, j, pools, tau, count) -> list[Choice]:
        entries = [(p, np.flatnonzero(np.isfinite(p.result.cost) & (p.result.cost < tau)))
                   for p in pools]
        return self.distinct_choices(j,
                                     [(p.tangible, p.it[ok], p.iv[ok], take_pairs(p.result, ok))
                                      for p, ok in entries],
                                      [p.result.cost[ok] for p, ok in entries], count)

    def distinct_choices(self, j: int, parts: list, keys: list, count: int) -> list[Choice]:
        """Up to ``count`` choices of virtual j picked greedily by ``keys`` (one array per part,
        lower first; ties by tangible and poses) among ``parts`` [(tangible, it, iv, PairResult)],
        none a near duplicate of an earlier pick (module notes)."""
        V = self.virtuals[j]
        key = np.concatenate(keys) if keys else np.zeros(0)
        owner = np.concatenate([np.full(len(it), t)
                                for t, it, _, _ in parts]) if parts else np.zeros(0, np.int64)
        local = np.concatenate([np.arange(len(it))
                                for _, it, _, _ in parts]) if parts else np.zeros(0, np.int64)
        it = np.concatenate([it for _, it, _, _ in parts]) if parts else np.zeros(0, np.int64)
        iv = np.concatenate([iv for _, _, iv, _ in parts]) if parts else np.zeros(0, np.int64)
        if not len(key):
            return []
        t_pinch = np.concatenate([self.tangibles[t].pinches.points[p_it]
                                  for t, p_it, _, _ in parts])
        v_pinch = V.pinches.points[iv]
        by_owner = {t: k for k, (t, _, _, _) in enumerate(parts)}
        # by key; ties by tangible and poses, whatever the pools
        order = np.lexsort((iv, it, owner, key))
        alive = np.ones(len(key), dtype=bool)
        picks: list[Choice] = []
        for i in order:
            if len(picks) >= count:
                break
            if not alive[i]:
                continue
            _, _, _, r = parts[by_owner[owner[i]]]
            picks.append(self.choice(j, int(owner[i]), int(it[i]), int(iv[i]), r, int(local[i])))
            # the rest are out already, or on other tangibles
            near = np.flatnonzero(alive & (owner == owner[i]))
            near = near[pinch_distance(t_pinch[near], t_pinch[i]) < self.settings.distinct_mm]
            alive[near[pinch_distance(v_pinch[near],
                                      v_pinch[i]) < self.settings.distinct_mm]] = False
        return picks

    def choice(self, j: int, t: int, it: int, iv: int, r: PairResult, k: int) -> Choice:
        """The :class:`Choice` of virtual j's pose ``iv`` on tangible t's pose ``it``, evaluated as
        ``r[k]``."""
        T, V, fixed = self.tangibles[t], self.virtuals[j], self.settings.redirect is not None
        return Choice(j, t, it, iv, float(r.cost[k]), r.terms[k], bool(r.swapped[k]),
                      r.transform[k], bool(r.flipped[k]), r.mass_delta_mm[k], T.name, V.name,
                      r.redirect_terms[k] if fixed else None, placed_transform(T.obj.spec) if fixed
                      else r.transform[k],
                      Pose.of(T, it), Pose.of(V, iv, bool(r.swapped[k])),
                      rest_gap_mm=None if np.isnan(r.rest_gap_mm[k]) else float(r.rest_gap_mm[k]),
                      rest_jnd=float(r.rest_jnd[k]),
                      **_approach_fields(T, it, self.settings.user_mm))


def _approach_fields(tangible: Candidates, pose: int, user_mm) -> dict:
    """A choice's ``approach_elevation_deg`` and ``approach_azimuth_deg`` on tangible pose
    ``pose``."""
    if (tangible.obj.context.support is None
        or not np.isfinite(tangible.pinches.approach[pose]).all()):
        return {}
    elevation, azimuth = approach_angles(tangible.obj, tangible.pinches.points[pose:pose + 1],
                                         tangible.pinches.approach[pose:pose + 1], user_mm)
    return {"approach_elevation_deg": float(elevation[0]),
            "approach_azimuth_deg": None if np.isnan(azimuth[0]) else float(azimuth[0])}


def cost_row(search: "Search", j: int) -> np.ndarray:
    """(n,) exact least cost of virtual j on each tangible (inf where none is allowed)."""
    return np.array([search.best_cost(j, t) for t in range(len(search.tangibles))],
                    dtype=np.float64)
