"""Pose pairs as the exact search keeps them (:mod:`pinchmatch.match.search`).

- :class:`PairResult`: the exact evaluation of pose pairs (registered, every term).
- :class:`Ranked`: the pairs one blockwise pass kept, smallest sum first, and the least sum of any
  pair it left out. A pool of any size up to the pass's is its first pairs, so a pool that grows
  needs no new pass while its selection (separable sum or pooled bound) stays the same. A search's
  candidates that grow (refinement) add the new pairs' own passes to it (:meth:`Ranked.merged`), and
  the grown pool is its first pairs.
- :class:`Seen`: every pair evaluated for a pool, kept or not, so that a pool that grows evaluates
  only pairs it has not seen, or saw costing less than its bound then (kept) or at least its bound
  now (left out by their cost).

None of them changes what a search finds: a pool of a given size holds the pairs of least value and
a bound below every pair it leaves out, whether it came from a pass of its own size or from a larger
one's list (which of equal values at its edge it takes may differ; the search is exact either way),
and a pair's evaluation does not depend on which others it was evaluated with.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PairResult:
    """Exact evaluation of k (tangible pose, virtual pose) pairs, in the better finger order.

    cost (k,), terms (k, 8) contributions per criterion, swapped (k,) bool (virtual p1 on
    tangible p2), transform (k, 4, 4) virtual -> tangible, flipped (k,) bool, mass_delta_mm
    (k, 3) seen minus felt centre-of-mass offset in the tangible's frame, allowed (k,) bool
    (False: flipped under ``keep_upright``, or redirected beyond the budget; cost is then inf),
    redirect_terms (k, 2) the redirection's contributions (zero unless the placement is fixed),
    rest_gap_mm (k,) the placed object's lowest point over the prop's support (NaN where it is not
    shown on a support: :mod:`pinchmatch.match.rest`), rest_jnd (k,) what the gap adds to the cost,
    in JND-equivalents (0 where nothing is charged).
    """

    cost: np.ndarray
    terms: np.ndarray
    swapped: np.ndarray
    transform: np.ndarray
    flipped: np.ndarray
    mass_delta_mm: np.ndarray
    allowed: np.ndarray
    redirect_terms: np.ndarray
    rest_gap_mm: np.ndarray
    rest_jnd: np.ndarray


def take_pairs(result: PairResult, keep) -> PairResult:
    """The evaluations ``keep`` selects (an index array, a mask or a slice)."""
    return PairResult(**{f.name: getattr(result, f.name)[keep] for f in dataclasses.fields(result)})


def concat_pairs(parts: list[PairResult]) -> PairResult:
    """The evaluations of ``parts`` one after the other."""
    return PairResult(**{f.name: np.concatenate([getattr(p, f.name) for p in parts])
                         for f in dataclasses.fields(PairResult)})


def _ordered(it: np.ndarray, iv: np.ndarray, value: np.ndarray) -> tuple:
    order = np.argsort(value, kind="stable")  # equal values keep the order given
    return it[order], iv[order], value[order]


@dataclass(frozen=True)
class Ranked:
    """Pairs (``it``, ``iv``) with their ``value`` (separable sum, or pooled bound where ``tight``),
    smallest first (equal values in the order the pass gave them); every pair not listed has a value
    of at least ``rest`` (inf: every pair is listed), and every listed one less."""

    it: np.ndarray
    iv: np.ndarray
    value: np.ndarray
    rest: float
    tight: bool

    @classmethod
    def of(cls, it: np.ndarray, iv: np.ndarray, value: np.ndarray, rest: float,
           tight: bool) -> "Ranked":
        """A pass's pairs (any order) and the least value it left out."""
        return cls(*_ordered(np.asarray(it), np.asarray(iv), np.asarray(value)), float(rest),
                   bool(tight))

    def serves(self, size: int, tight: bool) -> bool:
        """Does this list hold the pool of ``size`` under this selection, and the value after it?"""
        return self.tight == tight and (size < len(self.value) or not np.isfinite(self.rest))

    def first(self, size: int) -> tuple:
        """(it, iv, least value of a pair left out) of the pool of ``size`` (:meth:`serves` it)."""
        if size < len(self.value):
            return self.it[:size], self.iv[:size], float(self.value[size])
        return self.it, self.iv, self.rest

    def merged(self, parts: list) -> "Ranked":
        """This list and the lists ``parts`` [(it, iv, value, rest)] of pairs it does not hold,
        under the same selection (indices in one numbering): complete below the least of their
        ``rest``."""
        rest = min([self.rest] + [float(p[3]) for p in parts])
        it = np.concatenate([self.it] + [p[0] for p in parts])
        iv = np.concatenate([self.iv] + [p[1] for p in parts])
        value = np.concatenate([self.value] + [p[2] for p in parts])
        below = value < rest
        return Ranked(*_ordered(it[below], iv[below], value[below]), rest, self.tight)


def pair_keys(it: np.ndarray, iv: np.ndarray) -> np.ndarray:
    """(k,) int64 one key per (tangible pose, virtual pose) pair, the same whatever either list's
    length (poses appended to a list keep their keys)."""
    return (np.asarray(it, dtype=np.int64) << 32) | np.asarray(iv, dtype=np.int64)


def _sorted_by(key: np.ndarray, *values) -> tuple:
    order = np.argsort(key, kind="stable")
    return (key[order],) + tuple(v[order] if isinstance(v, np.ndarray) else take_pairs(v, order)
                                 for v in values)


def _find(keys: np.ndarray, asked: np.ndarray) -> np.ndarray:
    """(k,) where each of ``asked`` lies in the sorted ``keys``, -1 where it is not there."""
    if not len(keys):
        return np.full(len(asked), -1)
    pos = np.minimum(np.searchsorted(keys, asked), len(keys) - 1)
    return np.where(keys[pos] == asked, pos, -1)


@dataclass(frozen=True)
class Seen:
    """Pairs evaluated for a pool, kept or not: every one's key (:func:`pair_keys`, sorted) and
    exact cost, and the whole evaluation of those that cost less than the pool's bound when they
    were evaluated (the others are not kept then, and stay out while the bound is at most their
    cost: their cost alone says so, about 16 bytes a pair against 250)."""

    key: np.ndarray
    cost: np.ndarray
    kept_key: np.ndarray
    kept: PairResult

    @classmethod
    def of(cls, it: np.ndarray, iv: np.ndarray, cost: np.ndarray, kept_it: np.ndarray,
           kept_iv: np.ndarray, kept: PairResult) -> "Seen":
        """The pairs (it, iv), any order, evaluated at ``cost``, those of them kept (kept_it,
        kept_iv) evaluated as ``kept``."""
        return cls(*_sorted_by(pair_keys(it, iv), cost),
                   *_sorted_by(pair_keys(kept_it, kept_iv), kept))

    def __len__(self) -> int:
        return len(self.key)

    def find(self, it: np.ndarray, iv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For each pair (it, iv): where its whole evaluation lies in ``kept`` (-1 where it is not
        kept), and its exact cost (NaN where it was never evaluated)."""
        asked = pair_keys(it, iv)
        at = _find(self.key, asked)
        cost = np.where(at >= 0, self.cost[np.maximum(at, 0)] if len(self.key) else np.nan,
                        np.nan)
        return _find(self.kept_key, asked), cost

    def plus(self, it: np.ndarray, iv: np.ndarray, cost: np.ndarray, kept_it: np.ndarray,
             kept_iv: np.ndarray, kept: PairResult) -> "Seen":
        """This list with the pairs (it, iv) evaluated at ``cost`` added, and those of them kept
        (a pair listed already, not kept then and evaluated again, is kept now)."""
        key = pair_keys(it, iv)
        fresh = _find(self.key, key) < 0
        return Seen(*_sorted_by(np.concatenate([self.key, key[fresh]]),
                                np.concatenate([self.cost, cost[fresh]])),
                    *_sorted_by(np.concatenate([self.kept_key, pair_keys(kept_it, kept_iv)]),
                                concat_pairs([self.kept, kept])))
