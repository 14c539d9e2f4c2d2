"""A mesh's topology at scale: merged vertices, duplicate faces, edges, bodies, winding and volume.

The loader's repairs (:func:`pinchmatch.mesh.load.load_mesh`) ask the same questions trimesh
answers (``merge_vertices``, ``unique_faces``, ``face_adjacency``, ``is_watertight``,
``is_winding_consistent``, ``fix_inversion(multibody=True)``), and get the same answers, vertex
order and face order included. trimesh groups rows by sorting them as byte strings and computes full
mass properties for a volume; on a 5-million-face scan that takes a minute and several gigabytes.
Here rows (a vertex's rounded coordinates, a face's sorted corners, an edge) are grouped in one pass
over a hash table (:mod:`topology_kernel`, compiled), rows compared whole, groups numbered in the
order their first rows come; volumes are sums of signed tetrahedra, without the inertia trimesh
computes alongside. ``tests/test_load.py`` checks every answer against trimesh's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

def extents(vertices: np.ndarray) -> np.ndarray:
    """(3,) size of the vertices' axis-aligned bounding box (column by column: numpy reduces an
    (n, 3) array along its long axis several times slower)."""
    if len(vertices) == 0:
        return np.zeros(3)
    return np.array([np.ptp(vertices[:, axis]) for axis in range(3)], dtype=np.float64)


def thickness(vertices: np.ndarray) -> float:
    """The vertices' spread across their flattest direction: the smallest singular value of the
    centred vertices over the square root of their count (0 for vertices in one plane)."""
    from .topology_kernel import scatter

    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    mean = np.array([vertices[:, axis].mean() for axis in range(3)])
    return float(np.sqrt(max(np.linalg.eigvalsh(scatter(vertices, mean))[0], 0.0) / len(vertices)))


def nondegenerate_faces(vertices: np.ndarray, faces: np.ndarray, height: float) -> np.ndarray:
    """(f,) bool: trimesh's ``Trimesh.nondegenerate_faces(height)``, the same arithmetic face by
    face, without the (f, 3, 3) triangles and the cross products it builds."""
    from trimesh import tol

    from .topology_kernel import nondegenerate_faces as kernel

    return kernel(np.ascontiguousarray(vertices, dtype=np.float64),
                  np.ascontiguousarray(faces, dtype=np.int64), float(height), float(tol.merge))


#: rows are bucketed by a vertex in their first column while the buckets' comparisons, Σ size²,
#: stay under this many per row (a mesh's vertex valences); else they are hashed
BUCKET_WORK_PER_ROW = 64


def group_rows(rows: np.ndarray,
               keys: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Group equal integer rows: ``(first, last, inverse)``, the index of each group's first and
    last row, groups in the order their first rows come, and each row's group (exact: rows compared
    whole).

    ``keys``: the first column is a vertex below this number, so rows may be bucketed by it (the
    same groups, faster, where vertices have few rows each).
    """
    from . import topology_kernel as kernel  # numba: imported when a mesh is first repaired

    rows = np.ascontiguousarray(rows, dtype=np.int64)
    if keys is not None and len(rows) and rows.shape[1] > 1:
        sizes = np.bincount(rows[:, 0], minlength=keys)
        if float(sizes @ sizes) <= BUCKET_WORK_PER_ROW * len(rows):
            return kernel.group_rows_by_key(rows, int(keys))
    return kernel.group_rows(rows)


def group_rows_first(rows: np.ndarray, keys: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`group_rows` without the last rows: ``(first, inverse)``."""
    first, _, inverse = group_rows(rows, keys)
    return first, inverse


def merge_vertices(vertices: np.ndarray, faces: np.ndarray,
                   digits: int) -> tuple[np.ndarray, np.ndarray]:
    """trimesh's ``merge_vertices`` on positions alone: vertices equal after rounding to ``digits``
    decimals become one, kept in the order of their first referenced occurrence.

    Returns ``(mask, inverse)`` for ``Trimesh.update_vertices``.
    """
    from .topology_kernel import merge_rounded

    referenced = np.zeros(len(vertices), dtype=bool)
    referenced[faces] = True
    return merge_rounded(np.ascontiguousarray(vertices, dtype=np.float64), referenced,
                         float(10**digits))


def unique_faces(faces: np.ndarray) -> np.ndarray:
    """(f,) bool: the first of each set of faces on the same three vertices (any order), as
    trimesh's ``unique_faces``."""
    keep = np.zeros(len(faces), dtype=bool)
    if len(faces):
        keep[group_rows_first(np.sort(faces, axis=1), keys=int(faces.max()) + 1)[0]] = True
    return keep


@dataclass(frozen=True)
class Edges:
    """The directed edges of a mesh's faces, three per face in corner order, grouped.

    face : (3f,) int64       the face of each edge
    group : (3f,) int64      the undirected edge each belongs to
    count : (g,) int64       how many faces hold each undirected edge
    ends : (g, 2) int64      the first and the last of each undirected edge's entries
    directed_dup : (3f,) bool  another face holds the same edge in the same direction
    """

    face: np.ndarray
    group: np.ndarray
    count: np.ndarray
    ends: np.ndarray
    directed_dup: np.ndarray

    @property
    def shared(self) -> np.ndarray:
        """(3f,) bool: the edge is held by exactly two faces (trimesh's adjacency and watertight
        rule)."""
        return self.count[self.group] == 2


def edges(faces: np.ndarray) -> Edges:
    """The faces' edges, grouped."""
    from .topology_kernel import face_edges

    faces = np.ascontiguousarray(faces, dtype=np.int64)
    keys = int(faces.max()) + 1 if len(faces) else 0
    ok, group, first, last, count, directed_dup = face_edges(faces, keys,
                                                             float(BUCKET_WORK_PER_ROW))
    if not ok:  # a vertex of huge valence: the edges hashed
        directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        a, b = directed[:, 0], directed[:, 1]
        first, last, group = group_rows(np.column_stack([np.minimum(a, b), np.maximum(a, b)]))
        count = np.bincount(group, minlength=len(first))
        # the same edge the same way: the same undirected edge, running from its smaller corner or
        # not
        way = 2 * group + (a < b)
        directed_dup = np.bincount(way, minlength=2 * len(first))[way] > 1
    return Edges(np.repeat(np.arange(len(faces)), 3), group, count, np.column_stack([first, last]),
                 directed_dup)


def face_adjacency(e: Edges) -> np.ndarray:
    """(k, 2) pairs of distinct faces sharing an edge that exactly two faces hold (trimesh's
    ``face_adjacency``, as a set of rows; each row sorted)."""
    ends = e.ends[e.count == 2]  # an edge two faces hold: its first entry's face and its last's
    a, b = e.face[ends[:, 0]], e.face[ends[:, 1]]
    keep = a != b
    return np.column_stack([np.minimum(a[keep], b[keep]), np.maximum(a[keep], b[keep])])


def component_labels(adjacency: np.ndarray, n_faces: int) -> np.ndarray:
    """(f,) body of each face over the adjacency, bodies numbered in the order of their first face:
    scipy's labels, as trimesh's ``connected_component_labels`` gives them."""
    from .topology_kernel import component_labels as kernel

    return kernel(np.ascontiguousarray(adjacency, dtype=np.int64).reshape(-1, 2), int(n_faces))


def watertight_and_wound(e: Edges) -> tuple[bool, bool]:
    """(watertight, winding consistent) as trimesh defines them: every edge held by exactly two
    faces; every edge two faces hold runs opposite ways in them."""
    shared = e.shared
    return bool(shared.all()), not bool((e.directed_dup & shared).any())


def signed_volumes(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(f,) signed volume of the tetrahedron from the origin to each face (their sum is the
    enclosed volume of a closed, outward-wound surface)."""
    from .topology_kernel import signed_volumes as kernel

    return kernel(np.ascontiguousarray(vertices, dtype=np.float64),
                  np.ascontiguousarray(faces, dtype=np.int64))


def inverted_bodies(vertices: np.ndarray, faces: np.ndarray, e: Edges, labels: np.ndarray,
                    volumes: np.ndarray | None = None) -> np.ndarray:
    """(f,) bool: faces of the bodies to turn right side out, as trimesh's
    ``fix_inversion(multibody=True)``: bodies of at least 4 faces, watertight and consistently
    wound on their own, whose volume is negative. ``volumes``: :func:`signed_volumes`, if known."""
    bodies = int(labels.max()) + 1 if len(labels) else 0
    body_of_edge = labels[e.face]
    # each body's own count of every edge, undirected and directed
    if watertight_and_wound(e) == (True, True):
        bad = np.zeros(len(e.face), dtype=bool)  # every body is closed and wound on its own too
    else:
        undirected = group_rows_first(np.column_stack([body_of_edge, e.group]))
        directed = group_rows_first(np.column_stack([body_of_edge,
                                                     faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)]))
        bad = ((np.bincount(undirected[1])[undirected[1]] != 2)
               | (np.bincount(directed[1])[directed[1]] > 1))
    broken = np.bincount(body_of_edge, weights=bad, minlength=bodies) > 0
    size = np.bincount(labels, minlength=bodies)
    volumes = signed_volumes(vertices, faces) if volumes is None else volumes
    volume = np.bincount(labels, weights=volumes, minlength=bodies)
    flip = (size >= 4) & ~broken & (volume < 0.0)
    return flip[labels]


#: parts tested for lying inside another, at most (a scan of thousands of pieces is left as it is)
MAX_ENCLOSED_TESTS = 256
#: each part's vertices tested, at most (evenly spread over its vertex list)
ENCLOSED_SAMPLES = 16


def winding_numbers(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(k,) the generalised winding number of a triangle surface around each point: the sum of the
    triangles' signed solid angles (Van Oosterom and Strackee) over 4π; ±1 inside a closed
    surface, 0 outside. Vectorised over points and faces, as many points at a time as keep about 2
    million pairs."""
    tri = vertices[faces]  # (f, 3, 3)
    out = np.zeros(len(points))
    step = max(1, 2_000_000 // max(len(faces), 1))
    for start in range(0, len(points), step):
        rel = tri[None] - points[start:start + step, None, None, :]  # (k, f, 3, 3)
        a, b, c = rel[:, :, 0], rel[:, :, 1], rel[:, :, 2]
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        numerator = np.einsum("kfi,kfi->kf", a, np.cross(b, c))
        denominator = la * lb * lc + np.einsum("kfi,kfi->kf", a, b) * lc + np.einsum("kfi,kfi->kf",
                                                                                     a, c) * lb \
            + np.einsum("kfi,kfi->kf", b, c) * la
        out[start:start + step] = np.arctan2(numerator, denominator).sum(axis=1) / (2.0 * np.pi)
    return out


def enclosed_parts(vertices: np.ndarray, faces: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """(parts,) bool: the parts (bodies of ``labels``) that lie wholly inside another part (pages
    inside a book's cover, a liner inside a shell): inside a part closed on its own, every sampled
    vertex of theirs has a winding number of at least one half about it; inside an open one (a cover
    of three sheets, open at the page edges), every sampled face centre has a generalized winding
    number of at least one half (Jacobson et al. 2013's inside test for surfaces with holes: the
    page corners by the open edges see less of the cover, their faces' centres are inside). Only
    parts inside another's bounding box are tested."""
    parts = int(labels.max()) + 1 if len(labels) else 0
    out = np.zeros(parts, dtype=bool)
    if parts < 2 or parts > MAX_ENCLOSED_TESTS:
        return out
    corners = faces.reshape(-1)
    owner = np.repeat(labels, 3)
    low = np.full((parts, 3), np.inf)
    high = np.full((parts, 3), -np.inf)
    np.minimum.at(low, owner, vertices[corners])
    np.maximum.at(high, owner, vertices[corners])
    closed: dict[int, bool] = {}
    for p in range(parts):
        mine = faces[labels == p]
        own = np.unique(mine)
        corners = vertices[own[np.linspace(0, len(own) - 1,
                                           min(ENCLOSED_SAMPLES, len(own))).astype(int)]]
        centres = vertices[mine[np.linspace(0, len(mine) - 1,
                                            min(ENCLOSED_SAMPLES,
                                                len(mine))).astype(int)]].mean(axis=1)
        for q in np.flatnonzero(np.all(low <= low[p], axis=1) & np.all(high >= high[p], axis=1)):
            if q == p or out[q]:
                continue
            if q not in closed:
                closed[q] = watertight_and_wound(edges(faces[labels == q]))[0]
            sample = corners if closed[q] else centres
            if (np.abs(winding_numbers(sample, vertices, faces[labels == q])) >= 0.5).all():
                out[p] = True
                break
    return out


def cyclic(faces: np.ndarray) -> np.ndarray:
    """Faces rotated to start at their smallest index: equal rows mean equal orientation."""
    shift = np.argmin(faces, axis=1)
    idx = (shift[:, None] + np.arange(3)) % 3
    return np.take_along_axis(faces, idx, axis=1)
