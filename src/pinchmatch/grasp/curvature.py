"""Contact patches: surface normal and principal curvatures at a contact.

Method (one batch for all contacts, no per-point Python loop):

1. The patch is the set of dense surface samples (see :mod:`surface`) within
   ``patch_radius_mm`` of the contact whose triangle faces the same way as
   the patch's mean normal (within 80°). This keeps the far face of a thin
   wall, and the other side of a sharp edge, out of the patch, while the
   noisy triangle normals of a scan stay in.
2. In a frame whose third axis is the current normal estimate, fit a
   height function h(u, v), a bivariate polynomial of degree 4 (an
   osculating jet, as CGAL's Monge fitting used by the method), by weighted
   least squares with the smooth weight (1 - ρ²/r²)².
3. The normal, the second fundamental form and the first fundamental form
   come from the jet's derivatives at the contact; the principal curvatures
   are the eigenvalues of the shape operator (convex positive, with the
   normal pointing out of the solid).
4. Refit twice in the frame of the fitted normal, after (a) dropping samples
   whose residual is an outlier (a neighbouring part, a scan artefact),
   (b) moving every triangle sample from its flat triangle onto the current
   curved estimate (the chord correction of :class:`surface.SurfaceSample`),
   and (c) subtracting from every sample the part of the osculating model
   h = -Q / (1 + sqrt(1 - S)) beyond its quadratic term, with Q and S from
   the current principal curvatures. That model is exact for spheres and
   circular cylinders, so the quartic terms left to the jet are small; a
   ridge on their L² norm over the patch (the same in any tangent frame, so
   curvature does not depend on how the object sits in its file) pulls them
   towards zero, which keeps the variance of a noisy scan
   down without the bias a plain quadric fit has (3-9 % at 8 mm).

The whole method runs per contact in one compiled loop (:mod:`jets`, numba), chunks of
contacts on every core; the tunables of the fit live there.

The passes, weights and thresholds are tested against closed-form curvature
on spheres, cylinders, tori and ellipsoids in several triangulations
(``tests/test_curvature.py``) and measured in ``benchmarks/bench_poses.py``.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..cores import thread_budget
from ..mesh.neighbours import neighbours_within
from ..mesh.surface import SurfaceContext

#: neighbours considered per contact (the patch is cut from these by radius)
MAX_PATCH_SAMPLES = 320
#: contacts fitted per task of the thread pool
CHUNK = 256
#: the jet needs at least this many samples, else the contact is flagged invalid
MIN_PATCH_SAMPLES = 24


@dataclass(frozen=True)
class PatchGeometry:
    """Local geometry of n contact patches.

    point_mm : (n, 3) float64        contact on the fitted surface
    normal : (n, 3) float64          unit outward normal of the fitted surface
    kappa_max_per_m : (n,) float64   largest principal curvature, convex positive
    kappa_min_per_m : (n,) float64   smallest principal curvature
    dir_max : (n, 3) float64         unit tangent direction of kappa_max
    dir_min : (n, 3) float64         unit tangent direction of kappa_min
    n_samples : (n,) int64           samples used in the final fit
    rms_mm : (n,) float64            weighted rms residual of the final fit
    valid : (n,) bool                enough samples for the fit
    """

    point_mm: np.ndarray
    normal: np.ndarray
    kappa_max_per_m: np.ndarray
    kappa_min_per_m: np.ndarray
    dir_max: np.ndarray
    dir_min: np.ndarray
    n_samples: np.ndarray
    rms_mm: np.ndarray
    valid: np.ndarray


def tangent_frame(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents (t1, t2) completing each normal to a right-handed frame."""
    helper = np.where(
        (np.abs(normal[:, 0]) < 0.9)[:, None], np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    )
    t1 = np.cross(normal, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(normal, t1)
    return t1, t2


def patch_geometry(
    context: SurfaceContext,
    points_mm: np.ndarray,
    normals: np.ndarray,
    *,
    patch_radius_mm: float | None = None,
) -> PatchGeometry:
    """Normal and principal curvatures of the patch around each contact.

    Parameters
    ----------
    context : SurfaceContext
        The surface.
    points_mm : (n, 3) float64
        Contacts on (or very near) the surface.
    normals : (n, 3) float64
        Initial outward normal at each contact (the hit triangle's normal).
    patch_radius_mm : float, optional
        Patch radius; default the context's.

    Returns
    -------
    PatchGeometry
        Per contact the patch's normal, principal curvatures (1/m) and directions.

    Examples
    --------
    >>> from pinchmatch import analyze_object
    >>> obj = analyze_object(box_stl)  # 60 x 40 x 20 mm, centred on the origin
    >>> up = np.array([[0.0, 0.0, 1.0]])
    >>> geom = patch_geometry(obj.context, up * 10.0, up)
    >>> geom.normal.round(3).tolist(), geom.kappa_max_per_m.round(2).tolist()  # the flat top face
    ([[0.0, 0.0, 1.0]], [0.0])
    """
    radius = float(patch_radius_mm or context.patch_radius_mm)
    points_mm = np.asarray(points_mm, dtype=np.float64).reshape(-1, 3)
    normal = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    normal = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    n = len(points_mm)
    if n == 0:
        empty3 = np.zeros((0, 3))
        empty = np.zeros(0)
        return PatchGeometry(empty3, empty3, empty, empty, empty3, empty3,
                             np.zeros(0, np.int64), empty, np.zeros(0, bool))

    # the samples within the radius (the nearest MAX_PATCH_SAMPLES where there are more), by index
    idx, counts = neighbours_within(context.tree, context.sample.points, points_mm, radius,
                                    MAX_PATCH_SAMPLES)
    out = (np.empty((n, 3)), np.empty((n, 3)), np.empty(n), np.empty(n), np.empty((n, 3)),
           np.empty((n, 3)), np.empty(n, np.int64), np.empty(n))


    from .jets import fit_patches  # numba: imported when a patch is first fitted

    def run(start):
        fit_patches(context.sample, points_mm, normal, idx, counts, radius, start,
                    min(start + CHUNK, n), out)

    starts = range(0, n, CHUNK)
    workers = min(len(starts), thread_budget())
    if workers > 1:
        # the kernel releases the GIL: chunks run on every core, each writing its own rows
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(run, starts))
    else:
        for start in starts:
            run(start)
    point, n_out, k_max, k_min, d_max, d_min, count, rms = out
    return PatchGeometry(point, n_out, k_max * 1000.0, k_min * 1000.0, d_max, d_min, count, rms,
                         count >= MIN_PATCH_SAMPLES)
