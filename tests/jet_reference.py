"""The patch fit written as batched numpy, one array per pass for all contacts of a chunk.

The reference that the compiled kernel (:mod:`pinchmatch.jets`) is checked against: the
same method, step by step, with numpy's vectorised operations and LAPACK's batched solve.
"""

from __future__ import annotations

import numpy as np

from pinchmatch.grasp.curvature import (MAX_PATCH_SAMPLES, MIN_PATCH_SAMPLES, PatchGeometry,
                                        tangent_frame)
from pinchmatch.grasp.jets import (CHORD_TRUST_MM, EXPONENTS as _EXPONENTS, FIT_PASSES, FLIP_VOTE,
                                   HIGH_ORDER, MAX_CENTROID_OFFSET, MIN_QUARTIC_SUPPORT,
                                   OUTLIER_FLOOR_MM, QUARTIC_GRAM as _QUARTIC_GRAM, QUARTIC_RIDGE,
                                   SAME_SIDE_DEG)

_INDEX = {e: i for i, e in enumerate(_EXPONENTS)}
_HIGH_ORDER = np.diag(HIGH_ORDER)


def reference_patch_geometry(context, points_mm, normals, radius) -> PatchGeometry:
    """patch_geometry, all contacts in one batch."""
    points_mm = np.asarray(points_mm, dtype=np.float64).reshape(-1, 3)
    normal = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    normal = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    k = int(min(MAX_PATCH_SAMPLES, len(context.sample.points)))
    dist, idx = context.tree.query(points_mm, k=k, distance_upper_bound=radius)
    used = int(np.isfinite(dist).sum(axis=1).max())
    parts = _patch_chunk(context.sample, points_mm, normal, dist[:, :used], idx[:, :used], radius)
    contact, n_out, k_max, k_min, d_max, d_min, count, rms, _ = parts
    return PatchGeometry(contact, n_out, k_max, k_min, d_max, d_min, count, rms,
                         count >= MIN_PATCH_SAMPLES)


def _fit_jets(points, origin, normal, weight, radius, quadric_only):
    """Weighted least-squares jets; returns derivatives at the origin and residuals.

    points : (n, k, 3), origin : (n, 3), normal : (n, 3), weight : (n, k) (0 = not in patch),
    quadric_only : (n,) bool, fit degree 2 only (too little support for the quartic jet).
    """
    t1, t2 = tangent_frame(normal)
    rel = points - origin[:, None, :]
    frame = np.stack([t1, t2, normal], axis=-1)  # (n, 3, 3), columns t1 t2 n
    local = np.matmul(rel, frame)  # (n, k, 3)
    u = local[..., 0] / radius
    v = local[..., 1] / radius
    h = local[..., 2]
    rho2 = u * u + v * v
    w = weight * np.clip(1.0 - rho2, 0.0, None) ** 2
    # a contact at the rim of its patch (a corner, the edge of an open surface) has
    # samples on one side only: a quartic would be extrapolated there, a quadric is safer
    wsum = np.maximum(w.sum(axis=1), 1e-300)
    lopsided = np.hypot((w * u).sum(axis=1), (w * v).sum(axis=1)) / wsum > MAX_CENTROID_OFFSET
    quadric_only = quadric_only | lopsided

    A = np.empty(u.shape + (len(_EXPONENTS),))  # (n, k, m): monomials u^i v^j
    A[..., 0] = 1.0
    for col, (i, j) in enumerate(_EXPONENTS[1:], start=1):
        if i:
            np.multiply(A[..., _INDEX[(i - 1, j)]], u, out=A[..., col])
        else:
            np.multiply(A[..., _INDEX[(i, j - 1)]], v, out=A[..., col])
    AwT = (A * w[..., None]).transpose(0, 2, 1)  # (n, m, k)
    AtA = np.matmul(AwT, A)
    Atb = np.matmul(AwT, h[..., None])
    m = AtA.shape[-1]
    # where the samples cannot support the cubic and quartic terms (a patch spanning
    # two or three rows of coarse triangles) pin them to zero: an osculating quadric
    diag = np.einsum("nii->ni", AtA)
    scale = (diag.mean(axis=1) + 1e-300)[:, None, None]
    pin = np.where(quadric_only, 1e8, 0.0)[:, None, None]
    # the quartic ridge: QUARTIC_RIDGE times the fit's total weight times the weighted L² norm of
    # the quartic part over the disc (for evenly spread samples, its diagonal matches
    # QUARTIC_RIDGE x the quartic diagonal of AᵀWA), the same in any tangent frame
    total = w.sum(axis=1)[:, None, None]
    ridge = scale * (1e-10 * np.eye(m) + pin * _HIGH_ORDER) + QUARTIC_RIDGE * total * _QUARTIC_GRAM
    coef = np.linalg.solve(AtA + ridge, Atb)[..., 0]  # (n, m)

    residual = h - np.matmul(A, coef[..., None])[..., 0]
    rms = np.sqrt((w * residual**2).sum(axis=1) / wsum)

    c = lambda i, j: coef[:, _INDEX[(i, j)]]  # noqa: E731
    f0 = c(0, 0)
    fu, fv = c(1, 0) / radius, c(0, 1) / radius
    fuu, fuv, fvv = 2.0 * c(2, 0) / radius**2, c(1, 1) / radius**2, 2.0 * c(0, 2) / radius**2
    return (t1, t2, f0, fu, fv, fuu, fuv, fvv), residual, rms


def _beyond_quadric(rel, k_max, k_min, d_max, d_min):
    """Height (mm, along the outward normal) of the osculating model beyond its quadratic part.

    The model h = -Q / (1 + sqrt(1 - S)), Q = κ1 x² + κ2 y², S = κ1² x² + κ2² y² in the
    principal frame, is exact for spheres and circular cylinders; its quadratic part is -Q/2.
    """
    x = np.einsum("nkd,nd->nk", rel, d_max)
    y = np.einsum("nkd,nd->nk", rel, d_min)
    Q = k_max[:, None] * x * x + k_min[:, None] * y * y
    S = np.clip((k_max[:, None] * x) ** 2 + (k_min[:, None] * y) ** 2, 0.0, 0.96)
    return 0.5 * Q - Q / (1.0 + np.sqrt(1.0 - S))


def _chord_offset(chord6, k_max, k_min, d_max, d_min):
    """Height (mm) of the curved surface above each flat-triangle sample: ½⟨II, chord⟩."""
    def quad(d):  # d (n, 3) -> (n, 6) coefficients of dᵀ C d for C as (xx, yy, zz, xy, xz, yz)
        x, y, z = d[:, 0], d[:, 1], d[:, 2]
        return np.stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z], axis=-1)

    II6 = k_max[:, None] * quad(d_max) + k_min[:, None] * quad(d_min)  # (n, 6), per mm
    return 0.5 * np.einsum("nkc,nc->nk", chord6, II6)


def _shape(t1, t2, normal, fu, fv, fuu, fuv, fvv):
    """Unit normal, principal curvatures (convex positive, per mm) and directions."""
    W = np.sqrt(1.0 + fu * fu + fv * fv)
    n_out = (normal - fu[:, None] * t1 - fv[:, None] * t2) / W[:, None]
    # first fundamental form and minus the second (convex positive with outward normal)
    E, F, G = 1.0 + fu * fu, fu * fv, 1.0 + fv * fv
    L, M, N = -fuu / W, -fuv / W, -fvv / W
    det = E * G - F * F
    # Weingarten map S = I^-1 II, as a 2x2 matrix [[a, b], [c, d]]
    a = (G * L - F * M) / det
    b = (G * M - F * N) / det
    c = (E * M - F * L) / det
    d = (E * N - F * M) / det
    half_tr = 0.5 * (a + d)
    disc = np.sqrt(np.maximum(half_tr**2 - (a * d - b * c), 0.0))
    k_max, k_min = half_tr + disc, half_tr - disc
    # eigenvector of k_max: the better conditioned of (b, k-a) and (k-d, c)
    e1 = np.stack([b, k_max - a], axis=-1)
    e2 = np.stack([k_max - d, c], axis=-1)
    use2 = np.linalg.norm(e2, axis=1) > np.linalg.norm(e1, axis=1)
    e = np.where(use2[:, None], e2, e1)
    degenerate = np.linalg.norm(e, axis=1) < 1e-12
    e[degenerate] = (1.0, 0.0)
    xu = t1 + fu[:, None] * normal
    xv = t2 + fv[:, None] * normal
    d_max = e[:, :1] * xu + e[:, 1:] * xv
    d_max -= np.einsum("ij,ij->i", d_max, n_out)[:, None] * n_out
    d_max /= np.linalg.norm(d_max, axis=1, keepdims=True)
    d_min = np.cross(n_out, d_max)
    return n_out, k_max, k_min, d_max, d_min


def _patch_chunk(sample, points_mm, normal, dist, idx, radius):
    """patch_geometry for one chunk of contacts, with their neighbour lists."""
    n = len(points_mm)
    inside = np.isfinite(dist)
    idx = np.where(inside, idx, 0)
    nbr = sample.points[idx]
    nbr_normal = sample.normals[idx]
    # a robust start: the mean normal of the samples facing the contact triangle's way
    # (one triangle's normal is noisy on scans; the far face of a thin wall faces away)
    # A triangle flipped by scan noise (a sliver) has an inverted normal: when the
    # samples facing against it outweigh those facing with it threefold, turn it.
    # triangle samples vote
    weighted = inside * np.where(sample.is_vertex[idx], 0.0, sample.weight[idx])
    cosine = np.einsum("nkd,nd->nk", nbr_normal, normal)
    agree = (weighted * (cosine > 0)).sum(axis=1)
    oppose = (weighted * (cosine < 0)).sum(axis=1)
    normal = np.where((oppose > FLIP_VOTE * agree)[:, None], -normal, normal)
    cos_side = np.cos(np.radians(SAME_SIDE_DEG))
    facing = inside & (np.einsum("nkd,nd->nk", nbr_normal, normal) > cos_side)
    mean = np.einsum("nk,nkd->nd", facing * weighted, nbr_normal)
    norm = np.linalg.norm(mean, axis=1, keepdims=True)
    normal = np.where(norm > 1e-12, mean / np.maximum(norm, 1e-300), normal)
    same_side = np.einsum("nkd,nd->nk", nbr_normal, normal) > cos_side
    valid = inside & same_side
    chord6 = sample.chord6[idx]
    base_weight = sample.weight[idx]
    sample_weight = base_weight

    origin, fitted = points_mm, nbr
    quadric_only = np.zeros(n, dtype=bool)
    for it in range(FIT_PASSES):
        weight = np.where(valid, sample_weight, 0.0)
        jets, residual, rms = _fit_jets(fitted, origin, normal, weight, radius, quadric_only)
        t1, t2, f0, fu, fv, fuu, fuv, fvv = jets
        n_out, k_max, k_min, d_max, d_min = _shape(t1, t2, normal, fu, fv, fuu, fuv, fvv)
        contact = origin + f0[:, None] * normal
        if it == 0:
            threshold = np.maximum(OUTLIER_FLOOR_MM, 4.0 * rms)
            valid = valid & (np.abs(residual) <= threshold[:, None])
        # move each sample from its flat triangle onto the curved surface of the current
        # estimate; trust a sample less the more it had to be moved (large triangles)
        offset = _chord_offset(chord6, k_max, k_min, d_max, d_min)
        fitted = nbr + offset[..., None] * n_out[:, None, :]
        beyond = _beyond_quadric(fitted - contact[:, None, :], k_max, k_min, d_max, d_min)
        fitted = fitted - beyond[..., None] * n_out[:, None, :]
        sample_weight = base_weight / (1.0 + (offset / CHORD_TRUST_MM) ** 2)
        trusted = np.where(valid, sample_weight / base_weight, 0.0)
        support = trusted.sum(axis=1) ** 2 / np.maximum((trusted**2).sum(axis=1), 1e-300)
        quadric_only = support < MIN_QUARTIC_SUPPORT
        origin, normal = contact, n_out

    count = valid.sum(axis=1)
    return (contact, n_out, k_max * 1000.0, k_min * 1000.0, d_max, d_min,
            count.astype(np.int64), rms, count >= MIN_PATCH_SAMPLES)
