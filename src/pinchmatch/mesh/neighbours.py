"""The dense samples within a radius of many points: the neighbours a contact patch is fitted to.

A patch fit (:mod:`pinchmatch.grasp.curvature`) needs, per contact, the surface samples within the
patch radius, at most ``k`` of them (the nearest). The matching stage asks for them in clusters: the
25 landing points around a pinch's target lie within 5 mm of it, the moments' grid cells fill whole
regions. One KD-tree query per point walks the tree and keeps a heap of ``k`` for each; a cluster's
points share nearly all their neighbours. So the points are grouped in cubes of the radius's side,
and a cube holding at least ``CLUSTER_POINTS`` of them is asked once: every sample within the radius
plus the cube's half diagonal of its centre (one ball query), from which each point keeps those
within the radius (a compiled loop). The other points are queried one by one, as before.

Either way a point's neighbours are the same: the samples whose squared distance is below the radius
squared (the KD-tree's own test), the ``k`` nearest of them where there are more (ties to the lower
index), **listed by sample index**. The order is canonical, so a patch does not depend on which way
its neighbours were found, or on which other points were asked with it.
"""

from __future__ import annotations

import itertools

import numpy as np

from ..cores import query_tree

#: a cube holding at least this many query points is asked with one ball query
CLUSTER_POINTS = 4
#: the cubes' side, as a share of the radius
CUBE_SHARE = 1.0


def neighbours_within(tree, samples: np.ndarray, points: np.ndarray, radius: float, k: int):
    """``(idx, counts)``: per point (n, 3), the indices of the samples (rows of ``samples``, the
    points of the scipy KD-tree ``tree``) within ``radius``, at most the ``k`` nearest, by ascending
    index, in ``idx[i, :counts[i]]`` (n, c) int64 (0 beyond; c the largest count, at least 1)."""
    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    n = len(points)
    k = int(min(k, len(samples)))
    side = CUBE_SHARE * radius
    keys = np.floor(points / side).astype(np.int64)
    cubes, cube_of, per_cube = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    cube_of = cube_of.ravel()
    clustered = per_cube[cube_of] >= CLUSTER_POINTS
    idx = np.zeros((n, max(k, 1)), dtype=np.int64)
    counts = np.zeros(n, dtype=np.int64)
    alone = np.flatnonzero(~clustered)
    if len(alone):
        dist, near = query_tree(tree, points[alone], k=k, distance_upper_bound=radius,
                                work=len(alone) * k // 16)
        dist, near = dist.reshape(len(alone), k), near.reshape(len(alone), k)
        found = np.isfinite(dist)
        counts[alone] = found.sum(axis=1)
        # by index, the missing last
        idx[alone, :k] = np.sort(np.where(found, near, len(samples)), axis=1)
    grouped = np.flatnonzero(clustered)
    if len(grouped):
        asked = np.flatnonzero(per_cube >= CLUSTER_POINTS)
        slot = np.full(len(cubes), -1, dtype=np.int64)
        slot[asked] = np.arange(len(asked))
        centres = (cubes[asked] + 0.5) * side
        # each cube's list ascending (scipy sorts each list it returns), the lists in cube order
        lists = tree.query_ball_point(centres, (radius + 0.5 * np.sqrt(3.0) * side) * (1.0 + 1e-9),
                                      return_sorted=True)
        lengths = np.fromiter((len(found) for found in lists), dtype=np.int64, count=len(lists))
        candidates = np.fromiter(itertools.chain.from_iterable(lists), dtype=np.int64,
                                 count=int(lengths.sum()))
        starts = np.r_[0, np.cumsum(lengths)]
        from .neighbours_kernel import within  # numba: imported when a cluster is first asked

        within(np.ascontiguousarray(samples, dtype=np.float64), points, grouped,
               slot[cube_of[grouped]], starts, candidates, float(radius) ** 2, k, idx, counts)
    used = max(int(counts.max(initial=0)), 1)
    idx = idx[:, :used]
    idx[np.arange(used)[None, :] >= counts[:, None]] = 0
    return np.ascontiguousarray(idx), counts
