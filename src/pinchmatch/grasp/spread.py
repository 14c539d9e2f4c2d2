"""Spreading pinches: a farthest-point order over the pinch space.

A pinch is a point (p1, p2) in 6-D, the same pinch as (p2, p1). Taking next
always the pinch farthest from all taken so far makes every prefix of the
order cover the graspable regions evenly, without clumps; a :class:`Pool`
keeps each candidate's distance to its nearest pick, so that later rounds of
:mod:`sampling`, and candidates added between rounds, continue one order.

The farthest-point loop is compiled with numba (:mod:`spread_kernel`, cached on
disk): per pick, one pass over the blocks and over the members of those it may
change, with no temporary arrays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

#: pinches per block of the farthest-point loop (a block is skipped when no pick comes near it)
BLOCK = 64


def other_order(fingers: int) -> list[int]:
    """The contacts of a grasp of ``fingers`` contacts in its other finger order, the same grasp: a
    pinch held the other way round (p2, p1); a tripod with index and middle swapped (the thumb
    stays)."""
    return [1, 0] if fingers == 2 else [0] + list(range(fingers - 1, 0, -1))


def _pair_vectors(points: np.ndarray):
    """Centred 3F-vectors of grasps (n, F, 3) in both finger orders, for the spread distance."""
    n, fingers = len(points), points.shape[1]
    return points.reshape(n, 3 * fingers), points[:, other_order(fingers)].reshape(n, 3 * fingers)


def spread_order(points: np.ndarray, count: int, nearest: np.ndarray | None = None):
    """Farthest-point order of pinches, treating (p1, p2) and (p2, p1) as the same (or of tripods,
    their two fingers in either order: :func:`other_order`).

    points : (n, F, 3). Each next pick is the pinch farthest from all picked
    so far, so any prefix covers the graspable regions evenly, without clumps.

    Returns ``(chosen, nearest)``: the indices of up to ``count`` new picks
    and each pinch's squared distance to its nearest pick (-1 for picks).
    Pass ``nearest`` back in to continue the same order. Ties go to the
    lowest index.
    """
    n = len(points)
    a, b = _pair_vectors(points - points.reshape(-1, 3).mean(axis=0))
    sq = (a * a).sum(axis=1)  # same for both finger orders
    if nearest is None:
        nearest = np.full(n, np.inf)
        current = 0
    else:
        nearest = nearest.copy()
        current = int(np.argmax(nearest))
    count = min(count, int((nearest >= 0).sum()))
    chosen = np.empty(count, dtype=np.int64)
    if count == 0:
        return chosen, nearest
    # blocks of nearby pinches, in the order of a KD-tree's leaves over one finger order
    perm = cKDTree(a, leafsize=BLOCK // 2).indices.astype(np.int64) if n > BLOCK else np.arange(n)
    ap, bp = np.ascontiguousarray(a[perm]), np.ascontiguousarray(b[perm])
    starts = np.arange(0, n + BLOCK, BLOCK).clip(max=n)
    starts = starts[np.r_[True, np.diff(starts) > 0]]
    centre = np.add.reduceat(ap, starts[:-1]) / np.diff(starts)[:, None]
    member = np.repeat(np.arange(len(starts) - 1), np.diff(starts))
    # the spread distance is a metric (both finger orders are the same pinch), so a block
    # whose centre is farther from a new pick than its radius plus the square root of its
    # largest nearest distance holds no pinch that the pick comes nearer to
    to_centre = np.minimum(np.linalg.norm(ap - centre[member], axis=1),
                           np.linalg.norm(bp - centre[member], axis=1))
    radius = np.maximum.reduceat(to_centre, starts[:-1])
    slack = 1e-9 * float(sq.max()) + 1e-12  # the rounding of |x|² + |q|² - 2 x·q
    from .spread_kernel import farthest  # numba: imported when pinches are first spread

    nearest_p = nearest[perm]
    farthest(ap, bp, sq[perm], nearest_p, int(np.flatnonzero(perm == current)[0]), chosen,
              perm, starts, centre, radius, slack)
    nearest[perm] = nearest_p
    return perm[chosen], nearest


def _nearest_to(points: np.ndarray, picked: np.ndarray) -> np.ndarray:
    """Squared spread distance from each pinch to the nearest of ``picked`` (inf when none): a
    KD-tree over the picks in one finger order, queried with each pinch in both (the nearer order
    counts)."""
    out = np.full(len(points), np.inf)
    if len(picked) == 0 or len(points) == 0:
        return out
    origin = points.reshape(-1, 3).mean(axis=0)
    a, b = _pair_vectors(points - origin)
    q, _ = _pair_vectors(picked - origin)
    tree = cKDTree(q)
    return np.minimum(tree.query(a, k=1)[0], tree.query(b, k=1)[0]) ** 2


@dataclass
class Pool:
    """Candidates that passed the cheap rules, with their spread distance to every pick so far."""

    points: np.ndarray
    faces: np.ndarray
    nearest: np.ndarray  # squared spread distance to the nearest pick, -1 once picked

    @classmethod
    def of(cls, points, faces, picked_points) -> "Pool":
        """Candidates whose spread counts ``picked_points`` (grasps picked before, (m, F, 3)) as
        picks."""
        return cls(points, faces, _nearest_to(points, picked_points))

    @classmethod
    def empty(cls, fingers: int = 2) -> "Pool":
        return cls(np.zeros((0, fingers, 3)), np.zeros((0, fingers), np.int64), np.zeros(0))

    def add(self, points, faces, picked_points):
        self.nearest = np.concatenate([self.nearest, _nearest_to(points, picked_points)])
        self.points = np.concatenate([self.points, points])
        self.faces = np.concatenate([self.faces, faces])

    def pick(self, count: int) -> np.ndarray:
        if len(self.points) == 0 or count <= 0:
            return np.zeros(0, np.int64)
        order, self.nearest = spread_order(self.points, count, self.nearest)
        return order

    def take(self, indices):
        """Count the candidates at ``indices`` as picked (checked elsewhere), and their points for
        the spread of the rest."""
        indices = np.asarray(indices, dtype=np.int64)
        self.nearest[indices] = -1.0
        self.saw(self.points[indices])

    def saw(self, picked_points):
        """Picks made from another pool count for this one's spread too."""
        live = self.nearest >= 0
        self.nearest[live] = np.minimum(self.nearest[live],
                                        _nearest_to(self.points[live], picked_points))
