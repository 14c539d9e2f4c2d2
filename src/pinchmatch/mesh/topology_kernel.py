"""The compiled row grouping of :mod:`topology` (numba, cached on disk next to this file).

Imported when a mesh is first repaired, so that starting pinchmatch does not load numba.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def group_rows(rows):
    """Group equal rows of an (n, k) int64 array in one pass over an open-addressing hash table.

    Returns ``(first, inverse)``: the index of each group's first row, groups numbered in the order
    their first rows come, and each row's group. Rows are compared whole, so no collision of the
    hash can merge rows that differ. The table holds group numbers only (8 bytes a slot, twice as
    many slots as rows), which keeps a large mesh's repair within memory.
    """
    n, k = rows.shape
    size = 16
    while size < 2 * n:
        size *= 2
    mask = size - 1
    table = np.full(size, -1, np.int64)
    first = np.empty(n, np.int64)
    inverse = np.empty(n, np.int64)
    groups = 0
    for i in range(n):
        h = np.uint64(14695981039346656037)
        for c in range(k):
            h = (h ^ np.uint64(rows[i, c])) * np.uint64(1099511628211)
            h ^= h >> np.uint64(29)
        slot = np.int64(h & np.uint64(mask))
        while True:
            g = table[slot]
            if g < 0:
                table[slot] = groups
                first[groups] = i
                inverse[i] = groups
                groups += 1
                break
            r = first[g]
            same = True
            for c in range(k):
                if rows[r, c] != rows[i, c]:
                    same = False
                    break
            if same:
                inverse[i] = g
                break
            slot = (slot + 1) & mask
    return first[:groups].copy(), inverse


@njit(cache=True, nogil=True)
def signed_volumes(vertices, faces):
    """(f,) signed volume of the tetrahedron from the origin to each face."""
    out = np.empty(len(faces))
    for f in range(len(faces)):
        a, b, c = vertices[faces[f, 0]], vertices[faces[f, 1]], vertices[faces[f, 2]]
        out[f] = (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                  + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6.0
    return out
