"""Width strata: every width of pinch an object offers is checked, the rare ones included.

The sampler's spread order (:mod:`spread`) covers the contacts evenly, so a kind of pinch
that takes little of the surface, or that the hand reaches at few of its places, is found by
luck: a mug's handle pinched across its 8 mm thickness is a few hundredths of the mug's
narrow candidates (most of them cross its wall, where no finger gets inside), and at a larger
count the spread may well check none of them. A plate, pinched across its 3-4 mm rim, then
finds no prop pose of its width at all, and a larger sample gives a worse answer.

Before the spread's rounds, the candidates that passed the cheap rules are sorted into strata
by width, ``STRATUM_JND`` just-noticeable differences of width each (5.75 % of the width
above 7 mm, 0.4 mm below: :func:`width_jnd`). Every stratum is checked, in its own spread
order over the contacts, in doubling batches, until ``quota`` of its pinches are feasible or
it has spent ``TRIES_PER_PINCH`` checks per pinch of its quota; a stratum whose first
``EMPTY_BATCHES`` batches found nothing feasible is given up. The quota is the stratified
share (``STRATUM_SHARE``) of the count, divided among the strata that have candidates, so it
grows with the count: a larger sample checks every width at least as hard as a smaller one.

What strata do not cover: a kind of pinch whose width is common but whose place is rare (one
small flat face among curved ones of the same width) is left to the spread over contacts and
to the match's targeted step (:mod:`pinchmatch.match.targeted`), which looks for the pinches
a match needs by all their features.
"""

from __future__ import annotations

import numpy as np

from ..config import WIDTH_JND_FLOOR_MM, WIDTH_JND_FRACTION
from .spread import Pool, spread_order

#: width of a stratum, in just-noticeable differences of width
STRATUM_JND = 3.0
#: the share of the count that the strata are to give, divided among the strata with candidates
STRATUM_SHARE = 0.1
#: a stratum stops after this many checks per pinch of its quota, found or not
TRIES_PER_PINCH = 24
#: the first batch of a stratum is its quota times this; each later batch doubles
FIRST_BATCH = 2
#: a stratum in which this many batches found no feasible pinch is given up (the hand reaches none
#: of its places: the inside of a wall, the middle of a plate)
EMPTY_BATCHES = 2


def width_jnd(width_mm) -> np.ndarray:
    """Widths counted in just-noticeable differences from 0: the integral of dw / JND(w), with
    JND(w) = max(WIDTH_JND_FRACTION·w, WIDTH_JND_FLOOR_MM) (linear up to the floor's width,
    logarithmic above)."""
    w = np.asarray(width_mm, dtype=np.float64)
    knee = WIDTH_JND_FLOOR_MM / WIDTH_JND_FRACTION
    return np.where(w <= knee, w / WIDTH_JND_FLOOR_MM,
                    knee / WIDTH_JND_FLOOR_MM + np.log(np.maximum(w, knee) / knee)
                    / WIDTH_JND_FRACTION)


def grip_width_mm(points: np.ndarray) -> np.ndarray:
    """(n,) the width of each grasp (n, F, 3): from the thumb (contact 0) to the middle of the
    others (a pinch's width, a tripod's aperture)."""
    return np.linalg.norm(points[:, 1:].mean(axis=1) - points[:, 0], axis=1)


def stratum_of(points: np.ndarray) -> np.ndarray:
    """(n,) the width stratum of each grasp (n, F, 3)."""
    return np.floor(width_jnd(grip_width_mm(points)) / STRATUM_JND).astype(np.int64)


def quota_per_stratum(count: int, strata: int) -> int:
    """Feasible pinches wanted per stratum: the stratified share of ``count`` over ``strata`` (0
    when the share leaves less than one per stratum: a count that small is spread over contacts
    alone)."""
    return int(STRATUM_SHARE * count // max(strata, 1))


def stratified_checks(pool: Pool, count: int, check) -> list:
    """Check candidates of ``pool`` stratum by stratum (see the module); ``check(points, faces)``
    returns the feasible pinches among them. The checked candidates are taken from the pool (its
    spread counts them as picked). Returns the feasible parts, in the order checked, and the checked
    pinches' points."""
    strata = stratum_of(pool.points)
    labels, inverse = np.unique(strata, return_inverse=True)
    quota = quota_per_stratum(count, len(labels))
    if quota == 0 or len(pool.points) == 0:
        return [], np.zeros((0,) + pool.points.shape[1:])
    # each stratum's spread order over its contacts, up to what it may spend
    limit = quota * TRIES_PER_PINCH
    orders = []
    for k in range(len(labels)):
        members = np.flatnonzero(inverse == k)
        chosen, _ = spread_order(pool.points[members], min(limit, len(members)))
        orders.append(members[chosen])
    found = np.zeros(len(labels), np.int64)
    spent = np.zeros(len(labels), np.int64)
    batch = np.full(len(labels), FIRST_BATCH * quota)
    sizes = np.array([len(o) for o in orders])
    parts, taken = [], []
    for round_ in range(64):
        live = np.flatnonzero((found < quota) & (spent < sizes)
                              & ((found > 0) | (round_ < EMPTY_BATCHES)))
        if not len(live):
            break
        picks = np.concatenate([orders[k][spent[k]:spent[k] + batch[k]] for k in live])
        spent[live] += batch[live]
        batch[live] *= 2
        part = check(pool.points[picks], pool.faces[picks])
        taken.append(picks)
        parts.append(part)
        hit_labels, hits = np.unique(stratum_of(part.points), return_counts=True)
        found[np.searchsorted(labels, hit_labels)] += hits
    taken = np.concatenate(taken)
    pool.take(taken)
    return parts, pool.points[taken]
