"""How a virtual object shown on a prop rests on what the prop stands on.

A registered placement (and the carousel, which is one) shows the virtual object where the fingers
on the prop say it is. The prop stands on a support (:mod:`pinchmatch.mesh.support`: a table, a
counter), so the object is seen standing on that support too, sunk into it, or hovering over it.
What the eye sees there is part of the match: a knife whose blade goes 47 mm through the table is
wrong whatever the fingers feel.

Per placement, the **rest gap** is the signed height of the placed object's lowest point over the
prop's support plane, in mm (negative: below it, sunk). It is exact: the lowest point of a rigidly
moved solid is one of its convex hull's vertices, so the gap is the least of the hull vertices'
heights (``support.normal · (R v + t) - height``), tried only among the vertices that can be lowest
for the placement's turn (:mod:`pinchmatch.mesh.lowest`).

The gap is not a felt difference, so it is not pooled with the haptic criteria (probability
summation would let a large haptic difference hide any gap: a 14 JND pinch hovering 35 mm would cost
0.02 JND more than one resting). It is a visible fault of the placement, and costs what it is worth
in JND, added to the pooled cost (:meth:`pinchmatch.match.cost.CostModel.pool`):

    x = max(-gap - tolerance, 0) / sink_mm_per_jnd + max(gap - tolerance, 0) / float_mm_per_jnd

Within ``REST_TOLERANCE_MM`` either way the object reads as resting (a contact a user takes for one;
a scan's own noise and a soft table top are of that size) and costs nothing. So a pinch that rests
beats one that does not unless it feels worse by more than x JND. The two rates are choices, stated
with their reasons in docs/matching.md:

- **sinking**, ``--rest-sink-mm-per-jnd`` (1 mm): a solid going through the table breaks solidity
  and is seen at once, not judged; 4 mm into the table (about a quarter of a degree at arm's length,
  several pixels of a current headset) already costs 2 JND, more than most haptic differences, so a
  pinch that rests wins wherever one exists;
- **hovering**, ``--rest-float-mm-per-jnd`` (10 mm): an object a little above the table reads as
  resting or as just lifted (depth from stereo and contact shadows is coarse at arm's length); 12 mm
  costs one JND, 32 mm three.

A prop held in the hand (``support = "none"``) has no support: nothing is charged, and the gap is
not reported. Under ``--placement fixed`` a redirected object stays where its level puts it, so only
the carousel's placements are charged.

Every term is at least 0, so the search's lower bounds stay lower bounds and the search stays exact.
"""

from __future__ import annotations

import numpy as np

from ..config import REST_FLOAT_MM_PER_JND as FLOAT_MM_PER_JND
from ..config import REST_SINK_MM_PER_JND as SINK_MM_PER_JND
from ..config import REST_TOLERANCE_MM
from ..mesh.lowest import LowestTable, lowest_along, lowest_table
from .candidates import memo_of
#: placements whose gaps are computed at a time (memory: 8 bytes x hull vertices each)
GAP_CHUNK = 4096

_HULLS: dict[int, tuple] = {}


def hull_points(obj) -> np.ndarray:
    """(h, 3) the vertices of the convex hull of ``obj``'s mesh (mm, its frame), made once while
    ``obj`` lives: where a rigidly moved copy has its lowest point. All vertices where the hull
    cannot be made (a flat object)."""
    memo = memo_of(_HULLS, obj)
    if "hull" not in memo:
        vertices = np.asarray(obj.loaded.mesh.vertices, dtype=np.float64)
        try:
            from scipy.spatial import ConvexHull

            points = vertices[np.sort(ConvexHull(vertices).vertices)]
        except Exception:  # a flat or degenerate set: every vertex is a candidate
            points = vertices
        memo["hull"] = np.ascontiguousarray(points)
    return memo["hull"]


def hull_table(obj) -> LowestTable:
    """The :class:`~pinchmatch.mesh.lowest.LowestTable` of :func:`hull_points`, made once while
    ``obj`` lives."""
    memo = memo_of(_HULLS, obj)
    if "table" not in memo:
        memo["table"] = lowest_table(hull_points(obj))
    return memo["table"]


def rest_gaps(support, points: np.ndarray, transforms: np.ndarray, *,
              table: LowestTable | None = None) -> np.ndarray:
    """(k,) the signed height (mm) of the lowest of ``points`` (h, 3), moved by each of
    ``transforms`` (k, 4, 4), over ``support`` (a :class:`~pinchmatch.mesh.support.SupportPlane` in
    the transforms' target frame); negative below it. ``table``: the points' table where one is
    kept (:func:`pinchmatch.mesh.lowest.lowest_table`; else it is made here).

    >>> from pinchmatch.mesh.support import SupportPlane
    >>> table = SupportPlane(np.array([0.0, 0.0, 1.0]), 10.0, "lowest point")
    >>> cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float)
    >>> T = np.tile(np.eye(4), (2, 1, 1)); T[1, :3, 3] = [0.0, 0.0, 12.5]
    >>> rest_gaps(table, cube, T).tolist()
    [-10.0, 2.5]
    """
    transforms = np.asarray(transforms, dtype=np.float64)
    normal = np.asarray(support.normal, dtype=np.float64)
    table = lowest_table(points) if table is None else table
    out = np.empty(len(transforms))
    for start in range(0, len(transforms), GAP_CHUNK):
        X = transforms[start:start + GAP_CHUNK]
        # Rᵀ n: the support's normal in the object's frame
        down = np.einsum("kji,j->ki", X[:, :3, :3], normal)
        lowest = lowest_along(table, down)
        out[start:start + GAP_CHUNK] = lowest + X[:, :3, 3] @ normal - support.height_mm
    return out


def rest_jnd(gaps: np.ndarray, *, sink_mm_per_jnd: float = SINK_MM_PER_JND,
             float_mm_per_jnd: float = FLOAT_MM_PER_JND) -> np.ndarray:
    """(k,) what each gap adds to the cost, in JND-equivalents (module notes); 0 within the
    tolerance and where the gap is NaN (nothing to rest on).

    >>> rest_jnd(np.array([0.0, -2.0, -5.0, 22.0, np.nan])).tolist()
    [0.0, 0.0, 3.0, 2.0, 0.0]
    """
    gaps = np.nan_to_num(np.asarray(gaps, dtype=np.float64), nan=0.0)
    return (np.maximum(-gaps - REST_TOLERANCE_MM, 0.0) / sink_mm_per_jnd
            + np.maximum(gaps - REST_TOLERANCE_MM, 0.0) / float_mm_per_jnd)


def presented_support(tangible_obj, redirect) -> object | None:
    """The support plane a virtual object placed on ``tangible_obj`` is seen on, or None: the prop's
    own support, unless the placement is fixed (``redirect`` given: the object stays in its
    level)."""
    return None if redirect is not None else tangible_obj.context.support


def rested(tangible_obj, virtual_obj, transforms: np.ndarray, model,
           redirect=None) -> tuple[np.ndarray, np.ndarray]:
    """The rest gaps (k,) of ``virtual_obj`` placed on ``tangible_obj`` by ``transforms`` (k, 4, 4),
    NaN where it is not shown on a support (a held prop, a redirected object), and what they add to
    the cost under ``model``'s rates (k,), JND-equivalents."""
    k = len(transforms)
    support = presented_support(tangible_obj, redirect)
    if support is None:
        return np.full(k, np.nan), np.zeros(k)
    gaps = rest_gaps(support, hull_points(virtual_obj), transforms, table=hull_table(virtual_obj))
    sink, hover = model.rest_mm_per_jnd
    return gaps, rest_jnd(gaps, sink_mm_per_jnd=sink, float_mm_per_jnd=hover)
