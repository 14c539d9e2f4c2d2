"""The compiled row grouping of :mod:`topology` (numba, cached on disk next to this file).

Imported when a mesh is first repaired, so that starting pinchmatch does not load numba.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def group_rows(rows):
    """Group equal rows of an (n, k) int64 array in one pass over an open-addressing hash table.

    Returns ``(first, last, inverse)``: the index of each group's first and last row, groups numbered
    in the order their first rows come, and each row's group. Rows are compared whole, so no collision of the
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
    last = np.empty(n, np.int64)
    inverse = np.empty(n, np.int64)
    groups = 0
    for i in range(n):
        h = np.uint64(0x9E3779B97F4A7C15)
        for c in range(k):  # each column mixed in, then splitmix64's finaliser: neighbouring rows scatter
            h = (h ^ np.uint64(rows[i, c])) * np.uint64(0xBF58476D1CE4E5B9)
            h ^= h >> np.uint64(31)
        h *= np.uint64(0x94D049BB133111EB)
        h ^= h >> np.uint64(29)
        slot = np.int64(h & np.uint64(mask))
        while True:
            g = table[slot]
            if g < 0:
                table[slot] = groups
                first[groups] = i
                last[groups] = i
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
                last[g] = i
                break
            slot = (slot + 1) & mask
    return first[:groups].copy(), last[:groups].copy(), inverse


@njit(cache=True, nogil=True)
def signed_volumes(vertices, faces):
    """(f,) signed volume of the tetrahedron from the origin to each face."""
    out = np.empty(len(faces))
    for f in range(len(faces)):
        a, b, c = vertices[faces[f, 0]], vertices[faces[f, 1]], vertices[faces[f, 2]]
        out[f] = (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                  + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6.0
    return out


@njit(cache=True, nogil=True)
def _root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]  # path halving
        i = parent[i]
    return i


@njit(cache=True, nogil=True)
def component_labels(pairs, n):
    """(n,) connected component of each node over the (k, 2) pairs (union-find), components
    numbered in the order of their smallest node, as scipy's ``connected_components`` numbers them."""
    parent = np.arange(n)
    for p in range(len(pairs)):
        a = _root(parent, pairs[p, 0])
        b = _root(parent, pairs[p, 1])
        if a < b:
            parent[b] = a
        elif b < a:
            parent[a] = b
    labels = np.empty(n, np.int64)
    number = np.full(n, -1, np.int64)
    count = 0
    for i in range(n):
        r = _root(parent, i)
        if number[r] < 0:
            number[r] = count
            count += 1
        labels[i] = number[r]
    return labels
