"""A coarse distance field of a point sample: sure bounds on the distance to the nearest sample.

The hand's reach search asks, for about a million test spheres per thousand pinches, how far each
sphere's centre is from the nearest dense surface sample. Most answers decide nothing close: the
sphere is far out in the air (the distance only has to be known to exceed a cap) or deep in the
object (it only has to be known to fall below a threshold). A KD-tree query costs the same either
way, and more on a large scan, whose tree is larger. The field answers those cases from a grid.

**Construction.** The sample's bounding box, grown by a margin, is cut into cubic voxels of side
``v``; a voxel is *occupied* when a sample lies in it. The exact Euclidean distance transform
(``scipy.ndimage.distance_transform_edt``) gives, for every voxel centre g, the distance e(g) to
the nearest occupied voxel's centre.

**Bounds.** Every sample lies within r = v·√3/2 of its voxel's centre. For a point x in the voxel
of centre g, with s the sample nearest to x and o the centre of s's voxel,

    |x - s| ≥ |g - o| - |x - g| - |s - o| ≥ e(g) - |x - g| - r,

and the occupied voxel nearest to g holds some sample within e(g) + r of g, so

    |x - s| ≤ e(g) + |x - g| + r.

A point outside the grid is farther than the margin from every sample. Both bounds are certain (up
to floating point, which a relative guard covers), so a caller that only needs to know "at least
the cap" or "below a threshold" gets the same decisions as from the exact query.

The bounds of a batch of points are one compiled pass
(:mod:`pinchmatch.mesh.distance_field_kernel`): the reach search asks for millions per run, and
numpy's passes over (n, 3) temporaries took 2.5-4 times as long.

**Size.** ``v`` is the larger of ``min_voxel_mm`` and the side that keeps the grid within
``max_voxels``: a 100 mm mug at 1.5 mm is 120k voxels; a 2 m table at the cap is coarser, and its
bounds looser, but still certain.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

#: the finest voxel side (mm): the transform's cost grows with the voxel count, its use falls off
#: slowly
MIN_VOXEL_MM = 1.5
#: at most this many voxels (bounds time and memory on very large objects)
MAX_VOXELS = 2_000_000
#: relative guard on the bounds against floating point (mm per mm of the object's size)
GUARD = 1e-9


@dataclass(frozen=True)
class DistanceField:
    """Bounds on the distance from any point to the nearest point of a sample.

    origin_mm : (3,) float64     the grid's lowest corner
    voxel_mm : float             the voxel side v
    distance_mm : (a, b, c) float32
        e(g): distance from each voxel centre to the nearest occupied voxel's centre
    margin_mm : float            every point outside the grid is at least this far from every sample
    """

    origin_mm: np.ndarray
    voxel_mm: float
    distance_mm: np.ndarray
    margin_mm: float

    @classmethod
    def of(cls, points: np.ndarray, *, margin_mm: float, min_voxel_mm: float = MIN_VOXEL_MM,
           max_voxels: int = MAX_VOXELS) -> "DistanceField":
        """The field of ``points`` (s, 3), exact outside the grid to ``margin_mm``."""
        points = np.asarray(points, dtype=np.float64)
        low, high = points.min(axis=0), points.max(axis=0)
        extent = high - low + 2.0 * margin_mm
        voxel = max(min_voxel_mm, float(np.prod(extent) / max_voxels) ** (1.0 / 3.0))
        shape = np.maximum(np.ceil(extent / voxel).astype(np.int64), 1)
        while np.prod(shape) > max_voxels:  # the cube root rounded down a hair
            voxel *= 1.01
            shape = np.maximum(np.ceil(extent / voxel).astype(np.int64), 1)
        origin = low - margin_mm
        empty = np.ones(tuple(shape), dtype=bool)
        cells = np.minimum(np.floor((points - origin) / voxel).astype(np.int64), shape - 1)
        empty[tuple(cells.T)] = False
        distance = ndimage.distance_transform_edt(empty, sampling=voxel).astype(np.float32)
        return cls(origin_mm=origin, voxel_mm=float(voxel), distance_mm=distance,
                   margin_mm=float(margin_mm))

    def bounds(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper), each (n,): the distance from each point to the nearest sample lies
        between them (``upper`` is inf outside the grid, ``lower`` the margin there)."""
        # numba: imported when bounds are first asked
        from .distance_field_kernel import field_bounds

        points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        lower, upper = np.empty(len(points)), np.empty(len(points))
        field_bounds(points, np.asarray(self.origin_mm, dtype=np.float64), 1.0 / self.voxel_mm,
                     float(self.voxel_mm), np.ascontiguousarray(self.distance_mm, dtype=np.float32),
                     GUARD, float(self.margin_mm), lower, upper)
        return lower, upper
