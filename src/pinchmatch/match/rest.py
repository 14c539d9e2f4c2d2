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
The search also pools by the least charge a pair can have (:class:`RestFloor`, from one number per
pose on each side), so that it evaluates the pairs that can rest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.distance import cdist

from ..config import REST_FLOAT_MM_PER_JND as FLOAT_MM_PER_JND
from ..config import REST_SINK_MM_PER_JND as SINK_MM_PER_JND
from ..config import REST_TOLERANCE_MM
from ..mesh.lowest import LowestTable, lowest_along, lowest_table
from .candidates import memo_of
#: placements whose gaps are computed at a time (memory: 8 bytes x hull vertices each)
GAP_CHUNK = 4096

#: how far (mm) the reach of a grasp (:func:`grasp_reach`) is widened for round-off
ROUND_OFF_MM = 1e-6

_HULLS: dict[int, tuple] = {}
_REACH: dict[int, tuple] = {}


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


@dataclass(frozen=True)
class RestFloor:
    """A lower bound of what the rest gap adds to the cost of every pose pair of a prop and a
    virtual object, from one number per pose on each side.

    A registration puts the virtual grasp's contact centroid m on the prop's (both pinches and
    tripods: :mod:`pinchmatch.match.register`), so a pair's gap is the prop centroid's height H over
    the support less the virtual hull's support function about m in the turned-down direction:
    ``gap = H - h(d)``, d a unit vector. Whatever d, ``inner <= h(d) <= outer``: ``outer`` is the
    farthest hull vertex from m; ``inner`` the distance from m to the nearest hull facet's plane
    where m is inside the hull (the largest ball about m inside it), else minus the distance to the
    nearest hull vertex. So the gap lies in [H - outer, H - inner], and the charge is at least
    :func:`rest_jnd` of the nearer end (0 where the interval meets the tolerance)."""

    height_mm: np.ndarray
    inner_mm: np.ndarray
    outer_mm: np.ndarray
    sink_mm_per_jnd: float
    float_mm_per_jnd: float
    squared: bool

    def block(self, start: int, stop: int) -> np.ndarray:
        """(stop - start, v) the bound for the prop's poses ``start:stop`` against every virtual
        pose, in the cost's units (x, or x² under ``sum`` pooling: :meth:`CostModel.pool`)."""
        out = np.zeros((stop - start, len(self.inner_mm)))
        self.add_to(out, start)
        return out

    def add_to(self, values: np.ndarray, start: int) -> None:
        """Add :meth:`block` of the prop's poses from ``start`` to ``values`` (rows, v), in place,
        touching only the rows where some virtual pose can sink or hover past the tolerance (a
        pair can do one or the other: inner <= outer)."""
        h = self.height_mm[start:start + len(values)]
        sides = ((np.flatnonzero(h + REST_TOLERANCE_MM < self.inner_mm.max(initial=-np.inf)),
                  -1.0, self.inner_mm, self.sink_mm_per_jnd),
                 (np.flatnonzero(h - REST_TOLERANCE_MM > self.outer_mm.min(initial=np.inf)),
                  1.0, self.outer_mm, self.float_mm_per_jnd))
        for rows, sign, reach, mm_per_jnd in sides:
            if not len(rows):
                continue
            # sink: inner - h - tolerance; hover: h - outer - tolerance
            x = sign * (h[rows, None] - reach[None]) - REST_TOLERANCE_MM
            np.maximum(x, 0.0, out=x)
            x /= mm_per_jnd
            if self.squared:
                x *= x
            values[rows] += x


def grasp_reach(obj, centroids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(inner, outer) (k,) each of ``centroids`` (k, 3) mm: the least and the greatest that the
    support function of ``obj``'s hull about it can be, in any direction (:class:`RestFloor`)."""
    points = hull_points(obj)
    memo = memo_of(_HULLS, obj)
    if "planes" not in memo:
        try:
            from scipy.spatial import ConvexHull

            memo["planes"] = ConvexHull(points).equations  # n·x + b <= 0 inside, n unit
        except Exception:  # a flat set: no inside, the vertex bound alone
            memo["planes"] = np.zeros((0, 4))
    planes = memo["planes"]
    inner, outer = np.empty(len(centroids)), np.empty(len(centroids))
    for start in range(0, len(centroids), GAP_CHUNK // 16):
        c = centroids[start:start + GAP_CHUNK // 16]
        distance = cdist(c, points)
        outer[start:start + len(c)] = distance.max(axis=1)
        depth = (-(c @ planes[:, :3].T + planes[:, 3]).max(axis=1) if len(planes)
                 else np.full(len(c), -np.inf))
        inner[start:start + len(c)] = np.where(depth >= 0.0, depth, -distance.min(axis=1))
    # the planes' round-off, outward
    return inner - ROUND_OFF_MM, outer + ROUND_OFF_MM


def rest_floor(tangible, virtual, model, redirect=None) -> RestFloor | None:
    """The :class:`RestFloor` of every pose pair of the candidates ``tangible`` and ``virtual``, or
    None where the placement is charged nothing (no support, or a fixed placement)."""
    support = presented_support(tangible.obj, redirect)
    if support is None:
        return None
    memo = memo_of(_REACH, virtual)
    if "reach" not in memo:
        memo["reach"] = grasp_reach(virtual.obj, virtual.pinches.points.mean(axis=1))
    inner, outer = memo["reach"]
    height = (tangible.pinches.points.mean(axis=1) @ np.asarray(support.normal, dtype=np.float64)
              - support.height_mm)
    sink, hover = model.rest_mm_per_jnd
    return RestFloor(height, inner, outer, sink, hover, model.pooling == "sum")
