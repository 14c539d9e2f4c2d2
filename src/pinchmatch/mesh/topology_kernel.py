"""The compiled row grouping of :mod:`topology` (numba, cached on disk next to this file).

Imported when a mesh is first repaired, so that starting pinchmatch does not load numba.
"""

from __future__ import annotations

import math

import numpy as np
from ..compiled import njit


@njit(cache=True, nogil=True, inline="always")
def _mix(h, value):
    """One column mixed into a row's hash (then splitmix64's finaliser in :func:`_finish`)."""
    h = (h ^ np.uint64(value)) * np.uint64(0xBF58476D1CE4E5B9)
    return h ^ (h >> np.uint64(31))


@njit(cache=True, nogil=True, inline="always")
def _finish(h):
    h *= np.uint64(0x94D049BB133111EB)
    return h ^ (h >> np.uint64(29))


@njit(cache=True, nogil=True)
def _grow(table, hashes, groups):
    size = 2 * len(table)
    mask = np.uint64(size - 1)
    out = np.full(size, -1, np.int64)
    for g in range(groups):
        slot = np.int64(hashes[g] & mask)
        while out[slot] >= 0:
            slot = (slot + 1) & (size - 1)
        out[slot] = g
    return out


@njit(cache=True, nogil=True)
def group_rows(rows):
    """Group equal rows of an (n, k) int64 array in one pass over an open-addressing hash table.

    Returns ``(first, last, inverse)``: the index of each group's first and last row, groups
    numbered in the order their first rows come, and each row's group. Rows are compared whole, so
    no collision of the hash can merge rows that differ. Slots hold group numbers; each group keeps
    its first row's full hash, compared before the row itself, so a probe past another group's slot
    reads no row. The table starts small and doubles when half full, so its size follows the number
    of groups, not of rows: a triangle soup's 15 million corners that are 2.6 million vertices probe
    a table a fraction of the size.
    """
    n, k = rows.shape
    table = np.full(1024, -1, np.int64)
    hashes = np.empty(n, np.uint64)
    first = np.empty(n, np.int64)
    last = np.empty(n, np.int64)
    inverse = np.empty(n, np.int64)
    groups = 0
    for i in range(n):
        h = np.uint64(0x9E3779B97F4A7C15)
        for c in range(k):
            h = _mix(h, rows[i, c])
        h = _finish(h)
        mask = len(table) - 1
        slot = np.int64(h & np.uint64(mask))
        while True:
            g = table[slot]
            if g < 0:
                table[slot] = groups
                hashes[groups] = h
                first[groups] = i
                last[groups] = i
                inverse[i] = groups
                groups += 1
                if 2 * groups > len(table):
                    table = _grow(table, hashes, groups)
                break
            if hashes[g] == h:
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
def merge_rounded(vertices, referenced, factor):
    """Group the referenced vertices whose coordinates are equal once multiplied by ``factor`` and
    rounded to integers (numpy's ``(v * factor).round()``, half to even), in one pass.

    Returns ``(first, inverse)``: the index of each group's first vertex, groups in the order their
    first vertices come, and each vertex's group (0 for one not referenced).
    """
    n = len(vertices)
    table = np.full(1024, -1, np.int64)
    hashes = np.empty(n, np.uint64)
    first = np.empty(n, np.int64)
    keys = np.empty((n, 3), np.int64)
    inverse = np.zeros(n, np.int64)
    groups = 0
    for i in range(n):
        if not referenced[i]:
            continue
        x = np.int64(np.rint(vertices[i, 0] * factor))
        y = np.int64(np.rint(vertices[i, 1] * factor))
        z = np.int64(np.rint(vertices[i, 2] * factor))
        h = _finish(_mix(_mix(_mix(np.uint64(0x9E3779B97F4A7C15), x), y), z))
        mask = len(table) - 1
        slot = np.int64(h & np.uint64(mask))
        while True:
            g = table[slot]
            if g < 0:
                table[slot] = groups
                hashes[groups] = h
                first[groups] = i
                keys[groups, 0], keys[groups, 1], keys[groups, 2] = x, y, z
                inverse[i] = groups
                groups += 1
                if 2 * groups > len(table):
                    table = _grow(table, hashes, groups)
                break
            if hashes[g] == h and keys[g, 0] == x and keys[g, 1] == y and keys[g, 2] == z:
                inverse[i] = g
                break
            slot = (slot + 1) & mask
    return first[:groups].copy(), inverse


@njit(cache=True, nogil=True)
def group_rows_by_key(rows, keys):
    """:func:`group_rows` for rows whose first column is a small key in ``0 … keys - 1`` (a
    vertex): rows are bucketed by it and compared only within their bucket, a pass over memory in
    the order the rows come. Worth it where buckets are small (a vertex's edges); quadratic in a
    bucket's size."""
    n, k = rows.shape
    start = np.zeros(keys + 1, np.int64)
    for i in range(n):
        start[rows[i, 0] + 1] += 1
    for b in range(keys):
        start[b + 1] += start[b]
    filled = np.zeros(keys, np.int64)
    slot_group = np.empty(n, np.int64)
    slot_rest = np.empty((n, k - 1), np.int64)  # each bucket's groups' other columns, side by side
    first = np.empty(n, np.int64)
    last = np.empty(n, np.int64)
    inverse = np.empty(n, np.int64)
    groups = 0
    for i in range(n):
        b = rows[i, 0]
        s0 = start[b]
        s1 = s0 + filled[b]
        found = -1
        for t in range(s0, s1):
            same = True
            for c in range(1, k):
                if slot_rest[t, c - 1] != rows[i, c]:
                    same = False
                    break
            if same:
                found = slot_group[t]
                break
        if found < 0:
            slot_group[s1] = groups
            for c in range(1, k):
                slot_rest[s1, c - 1] = rows[i, c]
            filled[b] += 1
            first[groups] = i
            last[groups] = i
            inverse[i] = groups
            groups += 1
        else:
            inverse[i] = found
            last[found] = i
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
    numbered in the order of their smallest node, as scipy's ``connected_components`` numbers
    them."""
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


@njit(cache=True, nogil=True)
def nondegenerate_faces(vertices, faces, height, min_edge):
    """(f,) bool: trimesh's ``nondegenerate_faces(height)``, face by face with its arithmetic.

    A face is kept when both heights of its 2D bounding box, twice its area over the edge from
    corner 0 to 1 and over the edge from 0 to 2, exceed ``height``; an edge no longer than
    ``min_edge`` gives a height of 0.
    """
    keep = np.empty(len(faces), np.bool_)
    for f in range(len(faces)):
        v0, v1, v2 = vertices[faces[f, 0]], vertices[faces[f, 1]], vertices[faces[f, 2]]
        ax, ay, az = v1[0] - v0[0], v1[1] - v0[1], v1[2] - v0[2]
        bx, by, bz = v2[0] - v0[0], v2[1] - v0[1], v2[2] - v0[2]
        qx, qy, qz = v2[0] - v1[0], v2[1] - v1[1], v2[2] - v1[2]
        cx = ay * qz - az * qy
        cy = az * qx - ax * qz
        cz = ax * qy - ay * qx
        area = math.sqrt(cx * cx + cy * cy + cz * cz) / 2.0
        la = (ax * ax + ay * ay + az * az) ** 0.5
        lb = (bx * bx + by * by + bz * bz) ** 0.5
        ha = area * 2.0 / la if la > min_edge else 0.0
        hb = area * 2.0 / lb if lb > min_edge else 0.0
        keep[f] = ha > height and hb > height
    return keep


@njit(cache=True, nogil=True)
def scatter(points, mean):
    """(3, 3) Σ (p - mean)(p - mean)ᵀ over the rows of an (n, 3) array."""
    s = np.zeros((3, 3))
    for i in range(len(points)):
        x, y, z = points[i, 0] - mean[0], points[i, 1] - mean[1], points[i, 2] - mean[2]
        s[0, 0] += x * x
        s[0, 1] += x * y
        s[0, 2] += x * z
        s[1, 1] += y * y
        s[1, 2] += y * z
        s[2, 2] += z * z
    s[1, 0], s[2, 0], s[2, 1] = s[0, 1], s[0, 2], s[1, 2]
    return s


@njit(cache=True, nogil=True)
def face_edges(faces, keys, work_per_row):
    """The directed edges of the faces, three per face in corner order ((0, 1), (1, 2), (2, 0)),
    grouped into undirected edges as :func:`group_rows_by_key` groups their (smaller, larger) corner
    rows, without building those rows.

    Returns ``(ok, group, first, last, count, directed_dup)``; ``ok`` is False, and nothing else
    computed, where the smaller corners' buckets would cost more than ``work_per_row`` comparisons
    a row (a vertex of huge valence): the caller then hashes.
    """
    f = len(faces)
    n = 3 * f
    start = np.zeros(keys + 1, np.int64)
    for i in range(f):
        for c in range(3):
            a, b = faces[i, c], faces[i, (c + 1) % 3]
            start[min(a, b) + 1] += 1
    work = 0.0
    for b in range(keys):
        work += float(start[b + 1]) ** 2
        start[b + 1] += start[b]
    empty = np.zeros(0, np.int64)
    if work > work_per_row * n:
        return False, empty, empty, empty, empty, np.zeros(0, np.bool_)
    filled = np.zeros(keys, np.int64)
    slot_group = np.empty(n, np.int64)
    slot_other = np.empty(n, np.int64)
    first = np.empty(n, np.int64)
    last = np.empty(n, np.int64)
    group = np.empty(n, np.int64)
    count = np.zeros(n, np.int64)
    # per undirected edge, held from its larger corner / its smaller: 0, 1, 2+
    ways = np.zeros((n, 2), np.uint8)
    groups = 0
    for i in range(n):
        a, b = faces[i // 3, i % 3], faces[i // 3, (i % 3 + 1) % 3]
        lo, hi = min(a, b), max(a, b)
        s0 = start[lo]
        s1 = s0 + filled[lo]
        found = -1
        for t in range(s0, s1):
            if slot_other[t] == hi:
                found = slot_group[t]
                break
        if found < 0:
            found = groups
            slot_group[s1] = groups
            slot_other[s1] = hi
            filled[lo] += 1
            first[groups] = i
            groups += 1
        last[found] = i
        group[i] = found
        count[found] += 1
        way = 1 if a < b else 0
        ways[found, way] = min(ways[found, way] + 1, 2)
    directed_dup = np.empty(n, np.bool_)
    for i in range(n):
        a, b = faces[i // 3, i % 3], faces[i // 3, (i % 3 + 1) % 3]
        directed_dup[i] = ways[group[i], 1 if a < b else 0] > 1
    return (True, group, first[:groups].copy(), last[:groups].copy(), count[:groups].copy(),
            directed_dup)
