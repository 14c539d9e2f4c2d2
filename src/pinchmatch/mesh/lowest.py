"""The lowest point of a point set along many directions, exactly, at a fraction of the price of
trying every point.

A rigidly moved solid rests on its lowest point, one of its convex hull's vertices
(:mod:`pinchmatch.match.rest`): per placement, the least of ``v · d`` over the vertices ``v``, with
``d`` the support's normal turned into the solid's frame. A scanned fruit's hull has 4,000 to
6,000 vertices and a match asks for a million placements or more, so trying every vertex for every
placement is most of what resting costs.

A :class:`LowestTable` splits the sphere of directions into the cells of a cube map
(``LOWEST_CELLS`` a face edge) and keeps, per cell, only the vertices that can be lowest for some
direction in it. With ``c`` a cell's centre direction, ``θ`` its angular radius (the angle to its
farthest corner: the cell is a convex polygon on the cube's face, whose farthest point from ``c`` in
angle is a corner) and ``R`` the largest distance of a vertex from the set's centre ``o``, any unit
``d`` of the cell has ``|d - c| <= δ = 2 sin(θ/2)``, so each vertex's height moves by at most
``Rδ`` between ``c`` and ``d`` (heights about ``o``; ``o · d`` is common to every vertex). The
vertex lowest along ``d`` is then within ``2Rδ`` of the least height along ``c``: the cell keeps
every vertex within that (and a rounding margin), and the least over them is the least over all. The
answer is the same number as the full search's: the same products of the same vertex, only fewer
tried.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: cells along each edge of the cube map's faces (6 x 12 x 12 cells of about 6.7 degrees' radius)
LOWEST_CELLS = 12
#: the rounding margin of a cell's slab, relative to the set's radius
MARGIN = 1e-9


@dataclass(frozen=True)
class LowestTable:
    """``points`` (h, 3) and, per cell ``c`` of the cube map, the candidates
    ``candidates[starts[c]:starts[c + 1]]`` (indices into ``points``, ascending)."""

    points: np.ndarray
    starts: np.ndarray
    candidates: np.ndarray
    cells: int


#: per major axis, the two others, in order: a face's (u, v) coordinates
OTHER_AXES = np.array([[1, 2], [0, 2], [0, 1]])


def _face_axes(face: int) -> tuple[int, float, int, int]:
    """The major axis, its sign and the two others of a cube face (0: +x, 1: -x, 2: +y, ...)."""
    axis = face // 2
    b, c = OTHER_AXES[axis]
    return axis, 1.0 if face % 2 == 0 else -1.0, int(b), int(c)


def _cell_directions(cells: int) -> tuple[np.ndarray, np.ndarray]:
    """(6·n², 3) each cell's unit centre direction and (6·n²,) its angular radius (rad)."""
    centre_uv = (np.arange(cells) + 0.5) / cells * 2.0 - 1.0
    half = 1.0 / cells
    centres, radii = [], []
    for face in range(6):
        axis, sign, b, c = _face_axes(face)
        u, v = np.meshgrid(centre_uv, centre_uv, indexing="ij")
        u, v = u.reshape(-1), v.reshape(-1)

        def direction(uu, vv):
            d = np.zeros((len(uu), 3))
            d[:, axis], d[:, b], d[:, c] = sign, uu, vv
            return d / np.linalg.norm(d, axis=1, keepdims=True)

        centre = direction(u, v)
        corners = [direction(u + su * half, v + sv * half) for su in (-1, 1) for sv in (-1, 1)]
        cos = np.min([np.einsum("kd,kd->k", centre, k) for k in corners], axis=0)
        centres.append(centre)
        radii.append(np.arccos(np.clip(cos, -1.0, 1.0)))
    return np.concatenate(centres), np.concatenate(radii)


def lowest_table(points: np.ndarray, cells: int = LOWEST_CELLS) -> LowestTable:
    """The table of ``points`` (h, 3) (module notes)."""
    points = np.ascontiguousarray(points, dtype=np.float64)
    centres, radii = _cell_directions(cells)
    q = points - points.mean(axis=0)
    radius = float(np.linalg.norm(q, axis=1).max()) if len(q) else 0.0
    heights = q @ centres.T  # (h, cells)
    slab = 2.0 * radius * 2.0 * np.sin(radii / 2.0) * (1.0 + MARGIN) + MARGIN * max(radius, 1.0)
    keep = heights <= heights.min(axis=0) + slab
    cell, point = np.nonzero(keep.T)  # cell-major, points ascending within a cell
    starts = np.searchsorted(cell, np.arange(len(centres) + 1))
    return LowestTable(points, starts.astype(np.int64), point.astype(np.int64), cells)


def direction_cells(directions: np.ndarray, cells: int) -> np.ndarray:
    """(k,) the cube-map cell of each direction (k, 3), finite and non-zero."""
    d = np.asarray(directions, dtype=np.float64)
    axis = np.abs(d).argmax(axis=1)
    rows = np.arange(len(d))
    major = d[rows, axis]
    face = 2 * axis + (major < 0)
    b, c = OTHER_AXES[axis].T
    scale = np.abs(major)
    u, v = d[rows, b] / scale, d[rows, c] / scale
    i = np.clip(np.floor((u + 1.0) / 2.0 * cells), 0, cells - 1).astype(np.int64)
    j = np.clip(np.floor((v + 1.0) / 2.0 * cells), 0, cells - 1).astype(np.int64)
    return (face * cells + i) * cells + j


def lowest_along(table: LowestTable, directions: np.ndarray) -> np.ndarray:
    """(k,) the least ``p · d`` over the table's points for each direction ``d`` (k, 3); rows that
    are not finite or are zero are tried against every point."""
    from .lowest_kernel import lowest

    d = np.ascontiguousarray(directions, dtype=np.float64)
    out = np.empty(len(d))
    ok = np.isfinite(d).all(axis=1) & (np.abs(d).max(axis=1) > 0)
    if ok.any():
        rows = d[ok]
        found = np.empty(len(rows))
        lowest(table.points, table.starts, table.candidates, direction_cells(rows, table.cells),
               rows, found)
        out[ok] = found
    if not ok.all():
        out[~ok] = (table.points @ d[~ok].T).min(axis=0)
    return out
