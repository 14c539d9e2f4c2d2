"""Which K props of a shelf serve a scene best: the subset search behind ``pinchmatch select``.

Input: the scene's served matrix over the whole shelf, ``cost`` (m virtual objects x n props, the
exact least cost of each object on each prop, inf where no registration is allowed) and
``noticeable`` (the same shape, bool: that best placement leaves some criterion at 1 JND or more),
both from the one match of ``match`` (:func:`pinchmatch.match.scene.match_one`: its ranked row and
whether each prop's best choice is noticed). With a subset S chosen, each object
uses its best prop in S: the cheapest (ties to the earlier prop), and under ``noticeable`` the
cheapest of those on which nothing is noticeable, when there is one. The **objective** of S is then

- ``mean``: the mean of those costs (inf when an object has no allowed prop in S);
- ``noticeable``: the number of objects whose placement is noticeable, ties broken by the mean;
- ``max``: the worst object's cost, ties broken by the mean.

With these rules a prop added to S never makes an object's placement worse by the objective, so the
best objective never rises with K. (Under ``noticeable``, an object on its cheapest prop alone could
go from a quiet prop to a cheaper, noticeable one: the count would then rise.)

Objects with no allowed registration on any shelf prop cannot be served by any subset: they are
reported and left out of the objective.

**Exact where it can be.** When C(n, K) is at most ``EXACT_SUBSETS`` (200,000: every 5 of 30
props, every 3 of 100), every subset is evaluated (vectorised, in blocks) and the best one, first
in lexicographic order among equals, is returned. Beyond it, two steps, each documented with what
it guarantees:

1. **Greedy**: start empty, add the prop that lowers the objective most. For ``mean`` this is the
   greedy of the facility-location problem: the saving Σ_j (c_j⁰ - min_{t∈S} C_jt), c_j⁰ an
   object's worst finite cost, is monotone and submodular, so the greedy subset saves at least (1 -
   1/e) of the best K-subset's saving (Nemhauser, Wolsey and Fisher, 1978). For ``noticeable`` the
   count of quietly served objects is a coverage function: the same (1 - 1/e) bound on it. For
   ``max`` (a K-centre problem on costs that are not a metric) no constant factor is known: the
   greedy is a heuristic.
2. **Local search**: swap one chosen prop for one left out while that improves the objective,
   best swap first, until none does (a local optimum under single swaps; it can only improve on the
   greedy, so the greedy's bound still holds).

The **coverage curve** is the best objective for K = 1, 2, …: exact per K where C(n, K) allows,
else the same two steps. Exact values never increase with K (a superset is never worse: each
object keeps its best prop); approximate points are made monotone by keeping, for each K, the best
subset found for K or for any smaller K padded with props (tested).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

#: the best subset is found by evaluating every one while there are at most this many
EXACT_SUBSETS = 200_000
#: subsets evaluated at once (each block holds objects x block x K costs)
BLOCK_SUBSETS = 4096
OBJECTIVES = ("mean", "noticeable", "max")


@dataclass(frozen=True)
class Selection:
    """A chosen subset and how it serves the scene.

    props : (K,) int, the chosen props (shelf indices, ascending)
    value : float, the objective (``noticeable``: the count of noticeable objects)
    mean_cost : float, the mean best cost of the served objects
    assigned : (m,) int, each object's prop (-1 for an object no shelf prop serves)
    cost : (m,) float, each object's cost on it (inf where unserved)
    noticeable : (m,) bool
    exact : bool, the subset is the best one (every subset was evaluated)
    method : str, "exhaustive" or "greedy + swaps"
    """

    props: np.ndarray
    value: float
    mean_cost: float
    assigned: np.ndarray
    cost: np.ndarray
    noticeable: np.ndarray
    exact: bool
    method: str


def _pick(c: np.ndarray, q: np.ndarray, objective: str) -> np.ndarray:
    """Each object's prop among the chosen columns (last axis): the cheapest, ties to the earlier
    column; for ``noticeable``, the cheapest of those where nothing is noticeable, if any."""
    if objective != "noticeable":
        return np.argmin(c, axis=-1)
    finite = np.isfinite(c)
    span = float(np.abs(c[finite]).max()) + 1.0 if finite.any() else 1.0
    # a quiet prop before any loud one
    return np.argmin(np.where(finite, c + span * q, np.inf), axis=-1)


def _scores(cost: np.ndarray, noticeable: np.ndarray, subsets: np.ndarray,
            objective: str) -> np.ndarray:
    """(s, 2) (objective, mean) of each subset (rows of prop indices): lower is better, compared
    lexicographically. cost and noticeable hold only servable objects."""
    c = cost[:, subsets]  # (m, s, K)
    q = noticeable[:, subsets]
    pick = _pick(c, q, objective)
    best = np.take_along_axis(c, pick[..., None], axis=2)[..., 0]  # (m, s)
    with np.errstate(invalid="ignore"):
        mean = best.mean(axis=0)
    if objective == "mean":
        value = mean
    elif objective == "max":
        value = best.max(axis=0)
    else:
        loud = np.take_along_axis(q, pick[..., None], axis=2)[..., 0]
        value = np.where(np.isfinite(best).all(axis=0), loud.sum(axis=0).astype(np.float64), np.inf)
    return np.column_stack([value, mean])


def _better(a, b) -> bool:
    """Score ``a`` is strictly better than ``b`` (objective, then mean)."""
    return (a[0], a[1]) < (b[0], b[1])


def _exhaustive(cost, noticeable, k: int, objective: str) -> np.ndarray:
    n = cost.shape[1]
    best, best_score = None, (np.inf, np.inf)
    combos = itertools.combinations(range(n), k)  # lexicographic: the first of equals is kept
    while True:
        block = np.array(list(itertools.islice(combos, BLOCK_SUBSETS)), dtype=np.int64).reshape(-1,
                                                                                                k)
        if not len(block):
            break
        scores = _scores(cost, noticeable, block, objective)
        # stable: the first of equals in the block
        i = int(np.lexsort((scores[:, 1], scores[:, 0]))[0])
        if best is None or _better(scores[i], best_score):
            best, best_score = block[i], tuple(scores[i])
    return best


def _greedy_and_swaps(cost, noticeable, k: int, objective: str, start=()) -> np.ndarray:
    n = cost.shape[1]
    chosen = list(start)
    while len(chosen) < k:
        rest = np.array([t for t in range(n) if t not in chosen], dtype=np.int64)
        trial = np.column_stack([np.tile(chosen, (len(rest), 1)),
                                 rest]) if chosen else rest[:, None]
        scores = _scores(cost, noticeable, trial, objective)
        chosen.append(int(rest[np.lexsort((rest, scores[:, 1], scores[:, 0]))[0]]))
    score = _scores(cost, noticeable, np.array([chosen]), objective)[0]
    while True:  # best single swap while one improves
        rest = [t for t in range(n) if t not in chosen]
        if not rest:
            break
        swaps = [(i, t) for i in range(k) for t in rest]
        trial = np.array([chosen[:i] + [t] + chosen[i + 1:] for i, t in swaps], dtype=np.int64)
        scores = _scores(cost, noticeable, trial, objective)
        j = int(np.lexsort((np.arange(len(swaps)), scores[:, 1], scores[:, 0]))[0])
        if not _better(scores[j], score):
            break
        chosen, score = list(trial[j]), scores[j]
    return np.array(sorted(chosen), dtype=np.int64)


def _selection(cost, noticeable, servable, props, objective, exact) -> Selection:
    props = np.sort(np.asarray(props, dtype=np.int64))
    c = cost[:, props]
    pick = _pick(c, noticeable[:, props], objective)
    assigned = np.where(servable & np.isfinite(c[np.arange(len(c)), pick]), props[pick], -1)
    own = np.where(assigned >= 0, c[np.arange(len(c)), pick], np.inf)
    loud = np.where(assigned >= 0,
                    noticeable[np.arange(len(c)), np.where(assigned >= 0, assigned, 0)], False)
    score = _scores(cost[servable], noticeable[servable], props[None], objective)[0]
    return Selection(props, float(score[0]), float(score[1]), assigned, own, loud, exact,
                     "exhaustive" if exact else "greedy + swaps")


def select_props(cost: np.ndarray, noticeable: np.ndarray, k: int, *,
                 objective: str = "mean") -> Selection:
    """The ``k`` props that serve the scene best under ``objective`` (see the module notes).

    Parameters
    ----------
    cost : (m, n) float64
        The ranked cost of each virtual object (rows) on each prop (columns); inf where none fits.
    noticeable : (m, n) bool
        Whether each object's difference on each prop is noticed at least half of the time.
    k : int
        How many props to keep.
    objective : {"mean", "max", "noticeable"}
        What the selection minimises.

    Returns
    -------
    Selection
        The props kept, the objective's value and the prop each object is assigned.

    Examples
    --------
    >>> cost = np.array([[0.2, 1.5, 0.9], [2.0, 0.3, 0.8], [1.1, 1.2, 0.4]])  # 3 objects x 3 props
    >>> pick = select_props(cost, cost >= 1.0, 2)
    >>> pick.props.tolist(), round(pick.mean_cost, 3), pick.assigned.tolist()
    ([0, 2], 0.467, [0, 2, 2])
    """
    cost = np.asarray(cost, dtype=np.float64)
    noticeable = np.asarray(noticeable, dtype=bool)
    m, n = cost.shape
    if objective not in OBJECTIVES:
        raise ConfigError(f"objective {objective!r}: use one of {', '.join(OBJECTIVES)}")
    if not 1 <= k <= n:
        raise ConfigError(f"k = {k} for a shelf of {n} props")
    servable = np.isfinite(cost).any(axis=1)
    c, q = cost[servable], noticeable[servable]
    exact = math.comb(n, k) <= EXACT_SUBSETS
    props = _exhaustive(c, q, k, objective) if exact else _greedy_and_swaps(c, q, k, objective)
    return _selection(cost, noticeable, servable, props, objective, exact)


def coverage_curve(cost: np.ndarray, noticeable: np.ndarray, *, objective: str = "mean",
                   max_k: int | None = None) -> list[Selection]:
    """The best selection for K = 1 … min(n, max_k); values never increase with K.

    Parameters
    ----------
    cost : (m, n) float64
        The ranked cost of each virtual object (rows) on each prop (columns); inf where none fits.
    noticeable : (m, n) bool
        Whether each object's difference on each prop is noticed at least half of the time.
    objective : {"mean", "max", "noticeable"}
        What a selection minimises.
    max_k : int, optional
        The largest shelf (default: every prop).

    Returns
    -------
    list of Selection
        The best selection of each size K = 1, 2, ...

    Examples
    --------
    >>> cost = np.array([[0.2, 1.5, 0.9], [2.0, 0.3, 0.8], [1.1, 1.2, 0.4]])
    >>> [(s.props.tolist(), round(s.mean_cost, 3)) for s in coverage_curve(cost, cost >= 1.0)]
    [([2], 0.7), ([0, 2], 0.467), ([0, 1, 2], 0.3)]
    """
    n = cost.shape[1]
    out: list[Selection] = []
    for k in range(1, min(n, max_k or n) + 1):
        s = select_props(cost, noticeable, k, objective=objective)
        if out and not s.exact:
            # a larger set is never worse: the previous subset, padded greedily, competes
            servable = np.isfinite(cost).any(axis=1)
            padded = _greedy_and_swaps(cost[servable], noticeable[servable], k, objective,
                                       start=out[-1].props)
            alt = _selection(cost, noticeable, servable, padded, objective, False)
            if _better((alt.value, alt.mean_cost), (s.value, s.mean_cost)):
                s = alt
        out.append(s)
    return out


def best_addition(cost: np.ndarray, noticeable: np.ndarray, selection: Selection,
                  objective: str = "mean"):
    """The shelf prop not chosen whose addition improves the objective most, and the selection with
    it; None when every prop is chosen or none improves it."""
    n = cost.shape[1]
    rest = [t for t in range(n) if t not in set(selection.props.tolist())]
    if not rest:
        return None
    servable = np.isfinite(cost).any(axis=1)
    trial = np.array([np.r_[selection.props, t] for t in rest], dtype=np.int64)
    scores = _scores(cost[servable], noticeable[servable], trial, objective)
    j = int(np.lexsort((np.arange(len(rest)), scores[:, 1], scores[:, 0]))[0])
    if not _better(scores[j], (selection.value, selection.mean_cost)):
        return None
    return rest[j], _selection(cost, noticeable, servable, trial[j], objective, False)


def helpful_props(cost: np.ndarray, selection: Selection) -> np.ndarray:
    """(m,) for each object, the prop not chosen on which it costs least (-1 when no such prop is
    cheaper than its chosen one)."""
    others = np.setdiff1d(np.arange(cost.shape[1]), selection.props)
    if not len(others):
        return np.full(len(cost), -1)
    c = cost[:, others]
    j = np.argmin(c, axis=1)
    better = c[np.arange(len(c)), j] < selection.cost
    return np.where(better, others[j], -1)
