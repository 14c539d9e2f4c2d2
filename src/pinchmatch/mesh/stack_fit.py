"""A stack of the design family (:mod:`stacks`) fitted to a standing mesh: where ``design`` starts
from a shelf.

A shelf's props are meshes of any shape; the design searches coaxial stacks of cylinders, boxes,
frusta and barrels. To start the search from a shelf's best props, each is fitted by a stack: its
width profile along its up axis (+Z, as it stands), then the split of that profile into at most
``parts`` parts, each a cylinder (a constant width) or a frustum (a width changing linearly), that
follows the profile best in least squares (a dynamic programme over the split points). A part whose
sections are oblong (their narrower principal width under ``OBLONG_BELOW`` of the wider: a bottle's,
a box's) is a box of both widths, turned as they are.

The width at a height is twice the 98th percentile of the distances of the surface's points at that
height (drawn area-uniformly, seeded) from the centre of their bounding box: a round prop's
diameter, a square one's width between its sides and corners. A fitted stack is the shelf prop's
silhouette in the family's terms, not the prop: the design judges it as it judges every candidate.
"""

from __future__ import annotations

import math

import numpy as np
import trimesh

from .stacks import MIN_PART_HEIGHT_MM, MIN_PART_WIDTH_MM, Part, Stack

#: height bins of the width profile
SLICES = 48
#: points drawn on the surface (area-uniform, seeded) for the profile
SURFACE_POINTS = 40_000
#: the share of a slice's points nearer its median point than the width's radius
WIDTH_QUANTILE = 0.98
#: a frustum is taken over a cylinder only where it lowers the squared error by more than this share
FRUSTUM_GAIN = 0.2
#: a part whose section's narrower principal width is below this share of its wider is fitted by a
#: box
OBLONG_BELOW = 0.8


def _profile(mesh: trimesh.Trimesh, slices: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Per bin of height from the mesh's lowest point to its highest along +Z: (slices, 3) its width
    (mm) and its widths along the section's two principal directions across +Z, the wider first (NaN
    where a bin holds no point); (slices,) the wider's direction (degrees about +Z); and the bins'
    height (mm)."""
    points, _ = trimesh.sample.sample_surface(
        mesh, SURFACE_POINTS, seed=0
    )  # area-uniform: a bin gets its share
    z0, z1 = float(points[:, 2].min()), float(points[:, 2].max())
    step = max(z1 - z0, 1e-9) / slices
    which = np.minimum(((points[:, 2] - z0) / step).astype(np.int64), slices - 1)
    profile, turns = np.full((slices, 3), np.nan), np.zeros(slices)
    for k in np.unique(which):  # one slice at a time: at most SLICES small reductions
        xy = points[which == k, :2]
        centred = (
            xy - (xy.min(axis=0) + xy.max(axis=0)) / 2.0
        )  # the section's box centre: its axis, if round
        radius = np.linalg.norm(centred, axis=1)
        _, vectors = np.linalg.eigh(np.cov(centred.T) if len(centred) > 2 else np.eye(2))
        major, minor = vectors[:, 1], vectors[:, 0]
        along = [
            2.0 * float(np.quantile(np.abs(centred @ d), WIDTH_QUANTILE)) for d in (major, minor)
        ]
        profile[k] = [2.0 * float(np.quantile(radius, WIDTH_QUANTILE)), max(along), min(along)]
        turns[k] = math.degrees(math.atan2(major[1], major[0])) % 180.0
    return profile, turns, step


def _segment_fit(z: np.ndarray, w: np.ndarray) -> tuple[float, tuple]:
    """The squared error and the part (kind, bottom width, top width) that best follows widths ``w``
    at heights ``z`` (bin centres, from the segment's bottom)."""
    mean = float(w.mean())
    flat = float(((w - mean) ** 2).sum())
    if len(w) < 3:
        return flat, ("cylinder", mean, None)
    slope, intercept = np.polyfit(z, w, 1)
    line = slope * z + intercept
    sloped = float(((w - line) ** 2).sum())
    if sloped < (1.0 - FRUSTUM_GAIN) * flat:
        half = (z[1] - z[0]) / 2.0
        return sloped, (
            "frustum",
            float(intercept + slope * (z[0] - half)),
            float(intercept + slope * (z[-1] + half)),
        )
    return flat, ("cylinder", mean, None)


def fitted_stack(mesh: trimesh.Trimesh, *, parts: int = 4, slices: int = SLICES) -> Stack:
    """The stack of at most ``parts`` cylinders and frusta whose widths follow ``mesh``'s width
    profile along +Z best in least squares (module notes), each part at least ``MIN_PART_HEIGHT_MM``
    tall and ``MIN_PART_WIDTH_MM`` wide."""
    profile, turns, step = _profile(mesh, slices)
    filled = np.flatnonzero(np.isfinite(profile[:, 0]))
    # a bin with no point takes its neighbours' widths
    profile = np.column_stack(
        [np.interp(np.arange(slices), filled, profile[filled, c]) for c in range(3)]
    )
    widths = profile[:, 0]
    z = (np.arange(slices) + 0.5) * step
    shortest = min(max(1, math.ceil(MIN_PART_HEIGHT_MM / step)), slices)
    parts = max(1, min(parts, slices // shortest))
    # best[j][b]: least error of j + 1 parts over bins [0, b); how[j][b]: (start, part) of the last
    # part
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
        major, minor = float(np.median(profile[a:b, 1])), float(np.median(profile[a:b, 2]))
        if (
            minor < OBLONG_BELOW * major
        ):  # an oblong section (a bottle, a box): a box of both widths
            chosen.append(
                Part(
                    "box",
                    height,
                    round(max(major, MIN_PART_WIDTH_MM), 1),
                    turn_deg=round(float(np.median(turns[a:b])), 1),
                    depth_mm=round(max(minor, MIN_PART_WIDTH_MM), 1),
                )
            )
        else:
            bottom = round(max(bottom, MIN_PART_WIDTH_MM), 1)
            chosen.append(
                Part(
                    kind,
                    height,
                    bottom,
                    None if top is None else round(max(top, MIN_PART_WIDTH_MM), 1),
                )
            )
        b, j = a, j - 1
    return Stack(tuple(reversed(chosen)))
