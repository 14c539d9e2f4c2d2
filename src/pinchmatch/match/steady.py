"""The steady search: among every sampled pose pair, the ones whose landings agree, found before
their felt cost is known.

The felt cost (:mod:`pinchmatch.match.felt`) needs each pair's landings, too dear for every pair of
a sample (a million for two objects of 1,000 poses). The pairs best on target are often knife edges,
features that agree at one point and nowhere around it, so ranking only them by their felt cost
misses the pairs that feel alike wherever the fingers land. This search finds those:

- **per pose, once per object**: the mean μ and the variance σ² of its feature-table rows over
  its own landings (:func:`pinchmatch.match.felt.landing_moments`), on ``MOMENT_RINGS``: the target
  and eight points at the acceptance radius, weighed by the felt cost's landing distribution (with
  ``--scan-trust``, a scanned prop's variance at its scan's error added: :mod:`pinchmatch.match.
  trust`). A process keeps each object's moments while the object lives (:func:`moments_of`).
- **per pair, every pair**: the expected separable cost of two independent landings,
  Σ a ((μ_v − μ_t)² + σ_t² + σ_v²), computed for all pairs by the search's blockwise
  matrix products at the price of one more pass (the ``spreads`` of
  :func:`pinchmatch.match.cost.pair_cost_blocks`). The ``STEADY_POOL`` lowest are registered; their
  expected terms are pooled as the model pools them (``mass`` exact on target plus its spread, the
  hand's redirection as the match's).
- the ``STEADY_CHOICES`` best distinct pairs by that expected cost join the best distinct pairs on
  target (:mod:`pinchmatch.match.scene`), and all of them are ranked by their exact felt cost.

Independent landings ignore that the fingers land at corresponding points of both objects (the felt
cost pairs them), so for two alike surfaces the surrogate overstates the spread. It only chooses
which pairs are felt exactly: the ranking is the felt cost's. Where the search is exact and where it
ranks a bounded set is said in docs/matching.md.

Only the sampled (and given) poses are searched: a refined pose is found on target, and joins the
ranking through the best pairs on target.
"""

from __future__ import annotations

import numpy as np

from ..options import digest
from .candidates import Candidates, felt_table, mass_ratio, memo_of
from .cost import separable_terms
from .felt import landing_moments
from ..grasp.spread import other_order
from .search import Choice, Search, evaluate_pairs, pool_pairs, take_pairs
from .trust import scan_terms, scan_variance, spread_terms

#: the landings the moments are made of: the target and this many points on a ring at the radius
MOMENT_RINGS = (8,)
#: their patches are fitted once per cell of a grid this share of the radius wide
#: (:func:`landing_moments`)
MOMENT_SPACING_SHARE = 0.5
#: pose pairs per (virtual, tangible) pooled by the expected separable cost and registered
STEADY_POOL = 512
#: distinct best pairs by the expected cost that are felt exactly
STEADY_CHOICES = 32

_MOMENTS: dict[int, tuple] = {}


def moments_of(candidates: Candidates, radius_mm: float, settings) -> tuple[np.ndarray, np.ndarray]:
    """:func:`pinchmatch.match.felt.landing_moments` of every pose of ``candidates`` on
    ``MOMENT_RINGS``, made once per object and radius while the object lives (a tangible serves
    every virtual object), or as :func:`keep_moments` was given them."""
    key = moments_key(radius_mm, settings)
    memo = memo_of(_MOMENTS, candidates)
    if key not in memo:
        memo[key] = landing_moments(candidates, radius_mm, settings, rings=MOMENT_RINGS,
                                        patch_spacing_mm=MOMENT_SPACING_SHARE * radius_mm)
    return memo[key]


def ranks_by_landings(settings) -> bool:
    """Does a match under ``settings`` (:class:`~pinchmatch.config.MatchSettings`) rank by the felt
    cost, and so search steadily (not ``--rank nominal``, and a landing radius above 0)?"""
    return settings.rank != "nominal" and settings.landing_mm > 0


def moments_key(radius_mm: float, settings) -> tuple[float, str]:
    """What an object's moments depend on besides its poses: the landing radius and every pinch
    setting (their digest: the patch radius, the hand's sizes; a setting added later is in it
    without a decision here)."""
    return float(radius_mm), digest(settings)


def keep_moments(candidates: Candidates, key: tuple,
                 moments: tuple[np.ndarray, np.ndarray]) -> None:
    """Keep ``moments`` ((mean, variance), as :func:`moments_of` makes them under ``key``) for
    ``candidates``: a run's workers take a tangible's moments made once, with its poses, instead of
    each making them."""
    memo_of(_MOMENTS, candidates)[(float(key[0]), str(key[1]))] = moments


def expected_terms(tangible_moments: tuple, virtual_moments: tuple, ratio: float,
                   model) -> np.ndarray:
    """(k, 8) each criterion's expected contribution over two independent landings, for k aligned
    pairs of moments ((mean, variance) rows (k, 2, 9) each, the virtual ones in the tangible's
    finger order, ``ratio`` the :func:`~pinchmatch.match.candidates.mass_ratio`): the contribution
    of the means' difference plus that of both variances, in the tangible's scales; ``mass`` at its
    separable bound."""
    (t_mean, t_var), (v_mean, v_var) = tangible_moments, virtual_moments
    return (separable_terms(t_mean, felt_table(v_mean, ratio), model)
            + spread_terms(t_mean, t_var, v_var, ratio, model))


class SteadySearch:
    """The steady search of one virtual object (``search.virtuals[0]``) on each tangible, over the
    poses sampled for them (``sampled_tangibles``, ``sampled_virtual``: the first poses of the
    search's lists)."""

    def __init__(self, search: Search, sampled_tangibles: list[Candidates],
                 sampled_virtual: Candidates, radius_mm: float, pinch_settings):
        self.search, self.radius_mm, self.pinch_settings = search, float(radius_mm), pinch_settings
        self.sampled_tangibles, self.sampled_virtual = sampled_tangibles, sampled_virtual
        self._parts: dict[int, tuple] = {}

    def part(self, t: int) -> tuple:
        """((t, it, iv, PairResult), expected cost) of the allowed pairs of tangible t's pool."""
        if t not in self._parts:
            self._parts[t] = self._part(t)
        return self._parts[t]

    def _part(self, t: int) -> tuple:
        search = self.search
        T, V, model, settings = (search.tangibles[t], search.virtuals[0], search.model,
                                 search.settings)
        mt = moments_of(self.sampled_tangibles[t], self.radius_mm, self.pinch_settings)
        pooled = mt
        if model.scan_trust:  # independent of the landings: the variances add
            pooled = mt[0], mt[1] + scan_variance(self.sampled_tangibles[t])
        mv = moments_of(self.sampled_virtual, self.radius_mm, self.pinch_settings)
        it, iv, _, _ = pool_pairs(T, V, model, STEADY_POOL, settings.block_rows,
                                  moments=(pooled, mv),
                                  redirect=settings.redirect, user_mm=settings.user_mm)
        order = np.lexsort((iv, it))  # the pool's own order depends on its blocks
        it, iv = it[order], iv[order]
        r = evaluate_pairs(T, V, it, iv, model=model, keep_upright=settings.keep_upright,
                           redirect=settings.redirect, user_mm=settings.user_mm)
        swapped, other = r.swapped[:, None, None], other_order(mv[0].shape[1])
        v_mean = np.where(swapped, mv[0][iv][:, other], mv[0][iv])
        v_var = np.where(swapped, mv[1][iv][:, other], mv[1][iv])
        terms = expected_terms((mt[0][it], mt[1][it]), (v_mean, v_var), mass_ratio(T, V), model)
        if model.scan_trust:  # in the JND of the least values (pinchmatch.match.trust)
            terms += scan_terms(self.sampled_tangibles[t], it, model)
        # the mass offset exact on target (it needs the registration), and its spread
        terms[:, 7] += r.terms[:, 7] - separable_terms(mt[0][it],
                                                       felt_table(v_mean, mass_ratio(T, V)),
                                                       model)[:, 7]
        extra = r.redirect_terms if settings.redirect is not None else None
        key = np.where(np.isfinite(r.cost), model.pool(terms, extra=extra, rest=r.rest_jnd), np.inf)
        ok = np.flatnonzero(np.isfinite(key))
        return (t, it[ok], iv[ok], take_pairs(r, ok)), key[ok]

    def choices(self, tangibles: list[int], count: int) -> list[Choice]:
        """Up to ``count`` distinct best choices by the expected cost among ``tangibles``, evaluated
        on target (their ``cost`` the nominal one, as the search finds it)."""
        parts = [self.part(t) for t in tangibles]
        return self.search.distinct_choices(0, [p for p, _ in parts], [k for _, k in parts], count)
