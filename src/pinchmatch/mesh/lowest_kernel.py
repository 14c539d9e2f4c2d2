"""The compiled loop of :func:`pinchmatch.mesh.lowest.lowest_along` (numba, cached on disk next to
this file).

Imported when a point set is first asked for its lowest points, so that starting pinchmatch does
not load numba.
"""

from __future__ import annotations

import numpy as np

from ..compiled import njit


@njit(cache=True, nogil=True)
def lowest(points, starts, candidates, cells, directions, out):
    """For each direction ``directions[i]`` (its cell ``cells[i]``): the least ``p · d`` over the
    cell's candidates ``points[candidates[starts[c]:starts[c + 1]]]``, into ``out[i]``."""
    for i in range(directions.shape[0]):
        c = cells[i]
        dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
        best = np.inf
        for t in range(starts[c], starts[c + 1]):
            s = candidates[t]
            h = points[s, 0] * dx + points[s, 1] * dy + points[s, 2] * dz
            if h < best:
                best = h
        out[i] = best
