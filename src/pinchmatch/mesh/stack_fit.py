"""A stack of the design family (:mod:`stacks`) fitted to a standing mesh: where ``design`` starts from a shelf.

A shelf's props are meshes of any shape; the design searches coaxial stacks of cylinders, boxes, frusta
and barrels. To start the search from a shelf's best props, each is fitted by a stack: its width profile
along its up axis (+Z, as it stands), then the split of that profile into at most ``parts`` parts, each a
cylinder (a constant width) or a frustum (a width changing linearly), that follows the profile best in
least squares (a dynamic programme over the split points).

The width at a height is twice the 90th percentile of the distances of the surface's points at that
height from their median point: a round prop's diameter, a square one's width between its sides and
corners. A fitted stack is the shelf prop's silhouette in the family's terms, not the prop: the design
judges it as it judges every candidate.
"""

from __future__ import annotations

import math

import numpy as np
import trimesh

from .stacks import MIN_PART_HEIGHT_MM, MIN_PART_WIDTH_MM, Part, Stack

#: height bins of the width profile
SLICES = 48
#: the share of a slice's points nearer its median point than the width's radius
WIDTH_QUANTILE = 0.9
#: a frustum is taken over a cylinder only where it lowers the squared error by more than this share
FRUSTUM_GAIN = 0.2


def width_profile(mesh: trimesh.Trimesh, slices: int = SLICES) -> tuple[np.ndarray, float]:
    """(slices,) the mesh's width (mm) in each of ``slices`` equal bins of height from its lowest point to its
    highest along +Z (NaN where a bin holds no surface point), and the bins' height (mm)."""
    points = np.concatenate([np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.triangles_center)])
    z0, z1 = float(points[:, 2].min()), float(points[:, 2].max())
    step = max(z1 - z0, 1e-9) / slices
    which = np.minimum(((points[:, 2] - z0) / step).astype(np.int64), slices - 1)
    widths = np.full(slices, np.nan)
    for k in np.unique(which):  # one slice at a time: at most SLICES small reductions
        xy = points[which == k, :2]
        radius = np.linalg.norm(xy - np.median(xy, axis=0), axis=1)
        widths[k] = 2.0 * float(np.quantile(radius, WIDTH_QUANTILE))
    return widths, step


def _segment_fit(z: np.ndarray, w: np.ndarray) -> tuple[float, tuple]:
    """The squared error and the part (kind, bottom width, top width) that best follows widths ``w`` at
    heights ``z`` (bin centres, from the segment's bottom)."""
    mean = float(w.mean())
    flat = float(((w - mean) ** 2).sum())
    if len(w) < 3:
        return flat, ("cylinder", mean, None)
    slope, intercept = np.polyfit(z, w, 1)
    line = slope * z + intercept
    sloped = float(((w - line) ** 2).sum())
    if sloped < (1.0 - FRUSTUM_GAIN) * flat:
        half = (z[1] - z[0]) / 2.0
        return sloped, ("frustum", float(intercept + slope * (z[0] - half)), float(intercept + slope * (z[-1] + half)))
    return flat, ("cylinder", mean, None)


def fitted_stack(mesh: trimesh.Trimesh, *, parts: int = 4, slices: int = SLICES) -> Stack:
    """The stack of at most ``parts`` cylinders and frusta whose widths follow ``mesh``'s width profile along
    +Z best in least squares (module notes), each part at least ``MIN_PART_HEIGHT_MM`` tall and
    ``MIN_PART_WIDTH_MM`` wide."""
    widths, step = width_profile(mesh, slices)
    filled = np.flatnonzero(np.isfinite(widths))
    widths = np.interp(np.arange(slices), filled, widths[filled])  # a bin with no point: its neighbours'
    z = (np.arange(slices) + 0.5) * step
    shortest = min(max(1, math.ceil(MIN_PART_HEIGHT_MM / step)), slices)
    parts = max(1, min(parts, slices // shortest))
    # best[j][b]: least error of j + 1 parts over bins [0, b); how[j][b]: (start, part) of the last part
    best = np.full((parts, slices + 1), np.inf)
    how: list[dict] = [dict() for _ in range(parts)]
    fits = {}
    for a in range(slices):
        for b in range(a + shortest, slices + 1):
            fits[(a, b)] = _segment_fit(z[a:b] - z[a] + step / 2.0, widths[a:b])
    for b in range(shortest, slices + 1):
        best[0, b], how[0][b] = fits[(0, b)][0], (0, fits[(0, b)][1])
    for j in range(1, parts):
        for b in range(shortest * (j + 1), slices + 1):
            for a in range(shortest * j, b - shortest + 1):
                total = best[j - 1, a] + fits[(a, b)][0]
                if total < best[j, b]:
                    best[j, b], how[j][b] = total, (a, fits[(a, b)][1])
    j = int(np.argmin(best[:, slices]))
    chosen, b = [], slices
    while b > 0:
        a, (kind, bottom, top) = how[j][b]
        height = round((b - a) * step, 1)
        bottom = round(max(bottom, MIN_PART_WIDTH_MM), 1)
        chosen.append(Part(kind, height, bottom, None if top is None else round(max(top, MIN_PART_WIDTH_MM), 1)))
        b, j = a, j - 1
    return Stack(tuple(reversed(chosen)))
