"""The compiled loop of :mod:`neighbours` (numba, cached on disk next to this file).

Imported when a cluster of points is first asked for its neighbours, so that starting pinchmatch
does not load numba.
"""

from __future__ import annotations

import numpy as np
from ..compiled import njit


@njit(cache=True, nogil=True)
def within(samples, points, rows, cube, starts, candidates, radius2, k, idx, counts):
    """For each point ``rows[i]``: of its cube's candidates (``candidates[starts[c]:starts[c +
    1]]``, ascending, ``c = cube[i]``), those whose squared distance is below ``radius2``, the ``k``
    nearest where there are more (ties to the lower index), ascending, into ``idx[row]`` and
    ``counts[row]``."""
    widest = 1
    for c in range(len(starts) - 1):
        widest = max(widest, starts[c + 1] - starts[c])
    kept = np.empty(widest, np.int64)
    dist = np.empty(widest)
    for i in range(len(rows)):
        row = rows[i]
        c = cube[i]
        x, y, z = points[row, 0], points[row, 1], points[row, 2]
        n = 0
        for t in range(starts[c], starts[c + 1]):
            s = candidates[t]
            dx = x - samples[s, 0]
            dy = y - samples[s, 1]
            dz = z - samples[s, 2]
            d = dx * dx + dy * dy + dz * dz
            if d < radius2:
                kept[n] = s
                dist[n] = d
                n += 1
        if n > k:
            # the k nearest (a stable sort: equal distances keep the lower index first), by index
            nearest = np.sort(kept[:n][np.argsort(dist[:n], kind="mergesort")[:k]])
            for j in range(k):
                idx[row, j] = nearest[j]
            counts[row] = k
        else:
            for j in range(n):
                idx[row, j] = kept[j]
            counts[row] = n
