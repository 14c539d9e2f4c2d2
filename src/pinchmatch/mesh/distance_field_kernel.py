"""The compiled loop of :meth:`pinchmatch.mesh.distance_field.DistanceField.bounds` (numba, cached
on disk next to this file).

The reach search asks the field for the bounds of a few million test centres per thousand pinches.
In numpy the bounds take a dozen passes over (n, 3) temporaries; one pass per point reads its voxel
and writes both bounds, 2.5-4 times as fast. The arithmetic is the module's; its last bits may
differ (by a few 1e-15 mm), which the field's rounding guard covers.

Imported when a field is first asked for bounds, so that starting pinchmatch does not load numba.
"""

from __future__ import annotations

import math

import numpy as np
from ..compiled import njit


@njit(cache=True, nogil=True)
def field_bounds(points, origin, inverse_voxel, voxel, distance, guard, margin, lower, upper):
    """For each row of ``points`` (n, 3): its voxel of the grid ``distance`` (a, b, c) float32,
    whose lowest corner is ``origin`` and side ``voxel`` (``inverse_voxel`` its inverse);
    ``lower[i]`` and ``upper[i]`` bound the distance to the nearest sample: e ∓ (|x - g| +
    v·√3/2 + guard·(1 + max |x|) + 2.4e-7·e), the voxel's value e and centre g, max |x| over
    the finite coordinates of ``points``; the margin and inf outside the grid (and for a point that
    is not finite)."""
    shape = distance.shape
    flat = distance.ravel()
    # over the finite coordinates: a point that is not one is outside, and spoils no other's guard
    largest = 0.0
    for i in range(points.shape[0]):
        for axis in range(3):
            if abs(points[i, axis]) < np.inf:
                largest = max(largest, abs(points[i, axis]))
    constant = voxel * math.sqrt(3.0) / 2.0 + guard * (1.0 + largest)
    for i in range(points.shape[0]):
        inside = True
        index = 0
        across2 = 0.0
        for axis in range(3):
            scaled = (points[i, axis] - origin[axis]) * inverse_voxel
            cell = np.floor(scaled)
            across = scaled - cell - 0.5  # from the voxel's centre, in voxels
            across2 += across * across
            if not cell >= 0.0:  # below the grid, or not a number
                inside = False
                cell = 0.0
            elif cell > shape[axis] - 1:
                inside = False
                cell = shape[axis] - 1
            index = index * shape[axis] + int(cell)
        if not inside:
            lower[i] = margin
            upper[i] = np.inf
            continue
        e = np.float64(flat[index])
        slack = voxel * math.sqrt(across2) + constant
        slack += 2.4e-7 * e  # e was rounded to float32
        lower[i] = max(e - slack, 0.0)
        upper[i] = e + slack
