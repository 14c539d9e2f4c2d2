"""The compiled farthest-point loop of :mod:`spread` (numba, cached on disk next to this file).

Imported when pinches are first spread, so that starting pinchmatch does not load numba.
"""

from __future__ import annotations

import math

import numpy as np
from ..compiled import njit


@njit(cache=True, nogil=True)
def _block_max(nearest, perm, lo, hi):
    """Largest value in nearest[lo:hi] and where (the lowest original index among equals)."""
    best = lo
    for j in range(lo + 1, hi):
        if nearest[j] > nearest[best] or (nearest[j] == nearest[best] and perm[j] < perm[best]):
            best = j
    return nearest[best], best


@njit(cache=True, nogil=True)
def farthest(a, b, sq, nearest, current, chosen, perm, starts, centre, radius, slack):
    """The farthest-point loop over grasps (rows of ``a``, the same grasps in the other finger order
    in ``b``) in block order: ``len(chosen)`` picks from ``current``
    on, updating ``nearest``; blocks that the pick cannot come nearer to are skipped."""
    blocks = len(starts) - 1
    dims = a.shape[1]
    top = np.empty(blocks)
    top_at = np.empty(blocks, np.int64)
    for k in range(blocks):
        top[k], top_at[k] = _block_max(nearest, perm, starts[k], starts[k + 1])
    for i in range(len(chosen)):
        chosen[i] = current
        q = a[current]
        r = b[current]
        sq_q = sq[current]
        for k in range(blocks):
            if top[k] < 0.0:
                continue  # every pinch of the block is picked
            da = 0.0
            db = 0.0
            for c in range(dims):
                da += (centre[k, c] - q[c]) ** 2
                db += (centre[k, c] - r[c]) ** 2
            gap = math.sqrt(min(da, db)) - radius[k]
            if gap > 0.0 and gap * gap > top[k] + slack:
                continue
            changed = False
            for j in range(starts[k], starts[k + 1]):
                # |x - q|² = |x|² + |q|² - 2 x·q, with the better of the two finger orders
                dot_a = 0.0
                dot_b = 0.0
                for c in range(dims):
                    dot_a += a[j, c] * q[c]
                    dot_b += b[j, c] * q[c]
                d = sq[j] + sq_q - 2.0 * max(dot_a, dot_b)
                if d < nearest[j]:
                    nearest[j] = d
                    changed = True
            if changed:
                top[k], top_at[k] = _block_max(nearest, perm, starts[k], starts[k + 1])
        nearest[current] = -1.0
        k = np.searchsorted(starts, current, side="right") - 1
        top[k], top_at[k] = _block_max(nearest, perm, starts[k], starts[k + 1])
        best = 0
        for k in range(1, blocks):
            if top[k] > top[best] or (top[k] == top[best] and perm[top_at[k]] < perm[top_at[best]]):
                best = k
        current = top_at[best]
