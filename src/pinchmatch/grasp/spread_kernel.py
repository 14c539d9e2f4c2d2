"""The compiled farthest-point loop of :mod:`spread` (numba, cached on disk next to this file).

Imported when pinches are first spread, so that starting pinchmatch does not load numba.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


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
    """The farthest-point loop over pinches in block order: ``len(chosen)`` picks from ``current``
    on, updating ``nearest``; blocks that the pick cannot come nearer to are skipped."""
    blocks = len(starts) - 1
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
            for c in range(6):
                da += (centre[k, c] - q[c]) ** 2
                db += (centre[k, c] - r[c]) ** 2
            gap = math.sqrt(min(da, db)) - radius[k]
            if gap > 0.0 and gap * gap > top[k] + slack:
                continue
            changed = False
            for j in range(starts[k], starts[k + 1]):
                # |x - q|² = |x|² + |q|² - 2 x·q, with the better of the two finger orders
                dot_a = a[j, 0] * q[0] + a[j, 1] * q[1] + a[j, 2] * q[2] + a[j, 3] * q[3] + a[j, 4] * q[4] + a[j, 5] * q[5]
                dot_b = b[j, 0] * q[0] + b[j, 1] * q[1] + b[j, 2] * q[2] + b[j, 3] * q[3] + b[j, 4] * q[4] + b[j, 5] * q[5]
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
