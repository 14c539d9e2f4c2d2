"""The fused patch-fit kernel: every pass of :mod:`curvature`'s method for one contact at a time.

:func:`fit_patches` runs, for each contact, the whole method that :mod:`curvature`
describes (normal vote, same-side cut, three jet fits with the outlier cut, the chord
correction and the osculating model) in one compiled loop over that contact's
neighbours. Nothing of size contacts × neighbours × monomials is ever built: the
normal equations of the degree-4 jet are assembled from the 45 weighted moments
Σ w uᵃ vᵇ (a + b ≤ 8) of the patch, which are all that AᵀWA holds, and Σ w h uⁱ vʲ.

The kernel is compiled by numba on first use (about 10 s, once) and cached on disk next
to this file (or in ``NUMBA_CACHE_DIR``); it releases the GIL, so :mod:`curvature` runs
chunks of contacts on several threads. Everything is float64. Only the two sums over a
patch's samples (the moments and the weighted squared residual) may be reassociated, so
that they vectorise; each contact is computed alone, so results do not depend on the
chunking or the thread count, and they agree with a batched numpy version of the same
steps (``tests/jet_reference.py``) to 1e-9.
"""

from __future__ import annotations

import math

import numpy as np
from ..compiled import njit

#: samples whose triangle normal is further than this from the contact normal are not in the patch
SAME_SIDE_DEG = 80.0
#: the contact triangle's normal is turned when this many times more sample weight faces against it
FLIP_VOTE = 3.0
#: degree of the osculating jet
JET_DEGREE = 4
#: a sample is an outlier when its residual exceeds max(this, 4 x rms)
OUTLIER_FLOOR_MM = 0.5
#: fits: the first in the contact triangle's frame, then refits with chord-corrected samples
FIT_PASSES = 3
#: below this effective number of trusted samples (Kish) a patch is fitted by a quadric
MIN_QUARTIC_SUPPORT = 40.0
#: patch sample centroid farther than this (in patch radii) from the contact: fit a quadric
MAX_CENTROID_OFFSET = 0.3
#: a triangle sample moved this far by the chord correction counts half
CHORD_TRUST_MM = 0.05
#: ridge pulling the quartic terms (left after the model correction) towards zero, relative to the
#: weighted L² norm of the quartic part over the patch
QUARTIC_RIDGE = 0.3


def monomials(degree: int) -> list[tuple[int, int]]:
    """Exponents (i, j) of the monomials u^i v^j of a jet, by degree."""
    return [(i, k - i) for k in range(degree + 1) for i in range(k, -1, -1)]


EXPONENTS = monomials(JET_DEGREE)
#: 1 on the cubic and quartic terms, pinned to zero where a patch supports only a quadric
HIGH_ORDER = np.array([1.0 if i + j > 2 else 0.0 for i, j in EXPONENTS])


def _disc_moment(a: int, b: int) -> float:
    """∫ over the unit disc of (1 - ρ²)² u^a v^b dA, divided by ∫ (1 - ρ²)² dA."""
    if a % 2 or b % 2:
        return 0.0
    n = a + b
    radial = 1.0 / (n + 2) - 2.0 / (n + 4) + 1.0 / (n + 6)
    angular = 2.0 * math.gamma((a + 1) / 2) * math.gamma((b + 1) / 2) / math.gamma((n + 2) / 2)
    return radial * angular / (np.pi / 3.0)  # the denominator: 2π (1/2 - 2/4 + 1/6)


def quartic_gram() -> np.ndarray:
    """(m, m) Gram matrix of the quartic monomials under the patch weight over the unit disc.

    cᵀ G c is the weighted L² norm of the jet's quartic part over the patch: it does not change
    when the tangent frame turns, so a ridge with it keeps curvature independent of how the
    object sits in its file.
    """
    m = len(EXPONENTS)
    G = np.zeros((m, m))
    quartic = [k for k, (i, j) in enumerate(EXPONENTS) if i + j == 4]
    for k in quartic:
        for l in quartic:
            G[k, l] = _disc_moment(EXPONENTS[k][0] + EXPONENTS[l][0],
                                   EXPONENTS[k][1] + EXPONENTS[l][1])
    return G


QUARTIC_GRAM = quartic_gram()
_EXP_U = np.array([i for i, _ in EXPONENTS], dtype=np.int64)
_EXP_V = np.array([j for _, j in EXPONENTS], dtype=np.int64)
_COS_SIDE = math.cos(math.radians(SAME_SIDE_DEG))
_POW = 9  # powers u⁰ … u⁸ for the moments of AᵀWA
#: which monomial u^a v^b is (its column in the jet), -1 beyond degree 4
_SLOT = np.full((_POW, _POW), -1, np.int64)
for _k, (_a, _b) in enumerate(EXPONENTS):
    _SLOT[_a, _b] = _k


@njit(cache=True, nogil=True)
def _tangents(n):
    """Two unit tangents completing the unit normal n (as curvature.tangent_frame)."""
    hx, hy, hz = (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0)
    t1 = np.empty(3)
    t1[0] = n[1] * hz - n[2] * hy
    t1[1] = n[2] * hx - n[0] * hz
    t1[2] = n[0] * hy - n[1] * hx
    t1 /= math.sqrt(t1[0] ** 2 + t1[1] ** 2 + t1[2] ** 2)
    t2 = np.empty(3)
    t2[0] = n[1] * t1[2] - n[2] * t1[1]
    t2[1] = n[2] * t1[0] - n[0] * t1[2]
    t2[2] = n[0] * t1[1] - n[1] * t1[0]
    return t1, t2


@njit(cache=True, nogil=True)
def _solve_spd(a, b):
    """x with a x = b for a symmetric positive definite a (Cholesky, a overwritten)."""
    m = len(b)
    for k in range(m):
        s = a[k, k]
        for p in range(k):
            s -= a[k, p] * a[k, p]
        a[k, k] = math.sqrt(s)
        for i in range(k + 1, m):
            s = a[i, k]
            for p in range(k):
                s -= a[i, p] * a[k, p]
            a[i, k] = s / a[k, k]
    x = b.copy()
    for i in range(m):
        s = x[i]
        for p in range(i):
            s -= a[i, p] * x[p]
        x[i] = s / a[i, i]
    for i in range(m - 1, -1, -1):
        s = x[i]
        for p in range(i + 1, m):
            s -= a[p, i] * x[p]
        x[i] = s / a[i, i]
    return x


#: the patch sums may be reassociated (vectorised); nothing else is
_SUMS = {"reassoc", "contract"}


@njit(cache=True, nogil=True, fastmath=_SUMS)
def _weighted_square(w, r, cnt):
    """Σ w r² over the first ``cnt`` samples."""
    s = 0.0
    for j in range(cnt):
        s += w[j] * r[j] * r[j]
    return s


@njit(cache=True, nogil=True, fastmath=_SUMS)
def _moments(u, v, w, h, cnt, mom, atb):
    """mom[a, b] = Σ w uᵃ vᵇ (a + b ≤ 8) and atb[k] = Σ w h uⁱ vʲ for the jet's
    monomials, one power of the samples at a time (each sum a pass over contiguous arrays)."""
    p = w[:cnt].copy()
    q = np.empty(cnt)
    for a in range(_POW):
        for j in range(cnt):
            q[j] = p[j]
        for b in range(_POW - a):
            s = 0.0
            for j in range(cnt):
                s += q[j]
            mom[a, b] = s
            k = _SLOT[a, b]
            if k >= 0:
                sh = 0.0
                for j in range(cnt):
                    sh += q[j] * h[j]
                atb[k] = sh
            for j in range(cnt):
                q[j] *= v[j]
        for j in range(cnt):
            p[j] *= u[j]


@njit(cache=True, nogil=True)
def _fit(fitted, cnt, origin, normal, weight, radius, quadric_only, u, v, h, w, residual):
    """One weighted jet fit; fills u, v, h, w, residual; returns (t1, t2, coef, rms)."""
    t1, t2 = _tangents(normal)
    m = len(_EXP_U)
    ox, oy, oz = origin[0], origin[1], origin[2]
    ax, ay, az = t1[0] / radius, t1[1] / radius, t1[2] / radius
    bx, by, bz = t2[0] / radius, t2[1] / radius, t2[2] / radius
    nx, ny, nz = normal[0], normal[1], normal[2]
    for j in range(cnt):
        rx = fitted[j, 0] - ox
        ry = fitted[j, 1] - oy
        rz = fitted[j, 2] - oz
        uj = rx * ax + ry * ay + rz * az
        vj = rx * bx + ry * by + rz * bz
        u[j] = uj
        v[j] = vj
        h[j] = rx * nx + ry * ny + rz * nz
        fall = max(1.0 - (uj * uj + vj * vj), 0.0)
        w[j] = weight[j] * fall * fall
    mom = np.empty((_POW, _POW))
    atb = np.empty(m)
    _moments(u, v, w, h, cnt, mom, atb)
    total = mom[0, 0]
    wsum = max(total, 1e-300)
    lopsided = math.sqrt(mom[1, 0] ** 2 + mom[0, 1] ** 2) / wsum > MAX_CENTROID_OFFSET
    pin = 1e8 if (quadric_only or lopsided) else 0.0
    ata = np.empty((m, m))
    trace = 0.0
    for k in range(m):
        for l in range(m):
            ata[k, l] = mom[_EXP_U[k] + _EXP_U[l], _EXP_V[k] + _EXP_V[l]]
        trace += ata[k, k]
    scale = trace / m + 1e-300
    for k in range(m):
        for l in range(m):
            ata[k, l] += QUARTIC_RIDGE * total * QUARTIC_GRAM[k, l]
        ata[k, k] += scale * (1e-10 + pin * HIGH_ORDER[k])
    coef = _solve_spd(ata, atb)
    c = np.zeros((5, 5))
    for k in range(m):
        c[_EXP_U[k], _EXP_V[k]] = coef[k]
    c00, c01, c02, c03, c04 = c[0, 0], c[0, 1], c[0, 2], c[0, 3], c[0, 4]
    c10, c11, c12, c13 = c[1, 0], c[1, 1], c[1, 2], c[1, 3]
    c20, c21, c22, c30, c31, c40 = c[2, 0], c[2, 1], c[2, 2], c[3, 0], c[3, 1], c[4, 0]
    for j in range(cnt):
        uj, vj = u[j], v[j]
        p0 = c00 + vj * (c01 + vj * (c02 + vj * (c03 + vj * c04)))
        p1 = c10 + vj * (c11 + vj * (c12 + vj * c13))
        p2 = c20 + vj * (c21 + vj * c22)
        p3 = c30 + vj * c31
        residual[j] = h[j] - (p0 + uj * (p1 + uj * (p2 + uj * (p3 + uj * c40))))
    return t1, t2, coef, math.sqrt(_weighted_square(w, residual, cnt) / wsum)


@njit(cache=True, nogil=True)
def _shape(t1, t2, normal, fu, fv, fuu, fuv, fvv):
    """Unit normal, principal curvatures (per mm, convex positive) and directions of a jet."""
    W = math.sqrt(1.0 + fu * fu + fv * fv)
    n_out = (normal - fu * t1 - fv * t2) / W
    E, F, G = 1.0 + fu * fu, fu * fv, 1.0 + fv * fv
    L, M, N = -fuu / W, -fuv / W, -fvv / W
    det = E * G - F * F
    a = (G * L - F * M) / det
    b = (G * M - F * N) / det
    c = (E * M - F * L) / det
    d = (E * N - F * M) / det
    half_tr = 0.5 * (a + d)
    disc = math.sqrt(max(half_tr * half_tr - (a * d - b * c), 0.0))
    k_max, k_min = half_tr + disc, half_tr - disc
    e1x, e1y = b, k_max - a
    e2x, e2y = k_max - d, c
    if math.hypot(e2x, e2y) > math.hypot(e1x, e1y):
        ex, ey = e2x, e2y
    else:
        ex, ey = e1x, e1y
    if math.hypot(ex, ey) < 1e-12:
        ex, ey = 1.0, 0.0
    d_max = ex * (t1 + fu * normal) + ey * (t2 + fv * normal)
    d_max -= (d_max[0] * n_out[0] + d_max[1] * n_out[1] + d_max[2] * n_out[2]) * n_out
    d_max /= math.sqrt(d_max[0] ** 2 + d_max[1] ** 2 + d_max[2] ** 2)
    d_min = np.empty(3)
    d_min[0] = n_out[1] * d_max[2] - n_out[2] * d_max[1]
    d_min[1] = n_out[2] * d_max[0] - n_out[0] * d_max[2]
    d_min[2] = n_out[0] * d_max[1] - n_out[1] * d_max[0]
    return n_out, k_max, k_min, d_max, d_min


@njit(cache=True, nogil=True)
def _fit_patches(s_points, s_normals, s_chord6, s_weight, s_is_vertex, points, normals, idx, counts,
                 radius, start, stop,
                 out_point, out_normal, out_kmax, out_kmin, out_dmax, out_dmin, out_count, out_rms):
    kcols = idx.shape[1]
    nbr = np.empty((kcols, 3))
    nrm = np.empty((kcols, 3))
    chord = np.empty((kcols, 6))
    base = np.empty(kcols)
    voter = np.empty(kcols)
    valid = np.empty(kcols, np.bool_)
    fitted = np.empty((kcols, 3))
    weight = np.empty(kcols)
    offset = np.empty(kcols)
    u = np.empty(kcols)
    v = np.empty(kcols)
    h = np.empty(kcols)
    residual = np.empty(kcols)
    w = np.empty(kcols)
    for c in range(start, stop):
        cnt = counts[c]
        normal = normals[c].copy()
        agree = 0.0
        oppose = 0.0
        for j in range(cnt):
            s = idx[c, j]
            for a in range(3):
                nbr[j, a] = s_points[s, a]
                nrm[j, a] = s_normals[s, a]
            for a in range(6):
                chord[j, a] = s_chord6[s, a]
            base[j] = s_weight[s]
            voter[j] = 0.0 if s_is_vertex[s] else s_weight[s]  # triangle samples vote
            cos = nrm[j, 0] * normal[0] + nrm[j, 1] * normal[1] + nrm[j, 2] * normal[2]
            if cos > 0.0:
                agree += voter[j]
            elif cos < 0.0:
                oppose += voter[j]
        if oppose > FLIP_VOTE * agree:
            normal = -normal
        mx = my = mz = 0.0
        for j in range(cnt):
            if nrm[j, 0] * normal[0] + nrm[j, 1] * normal[1] + nrm[j, 2] * normal[2] > _COS_SIDE:
                mx += voter[j] * nrm[j, 0]
                my += voter[j] * nrm[j, 1]
                mz += voter[j] * nrm[j, 2]
        norm = math.sqrt(mx * mx + my * my + mz * mz)
        if norm > 1e-12:
            normal = np.array([mx / norm, my / norm, mz / norm])
        for j in range(cnt):
            valid[j] = (nrm[j, 0] * normal[0] + nrm[j, 1] * normal[1] + nrm[j, 2] * normal[2]
                        > _COS_SIDE)
            for a in range(3):
                fitted[j, a] = nbr[j, a]
            weight[j] = base[j] if valid[j] else 0.0
        origin = points[c].copy()
        quadric_only = False
        contact = origin
        n_out = normal
        k_max = k_min = rms = 0.0
        d_max = d_min = normal
        for it in range(FIT_PASSES):
            t1, t2, coef, rms = _fit(fitted, cnt, origin, normal, weight, radius, quadric_only,
                                     u, v, h, w, residual)
            fu, fv = coef[1] / radius, coef[2] / radius
            fuu, fuv, fvv = (2.0 * coef[3] / radius**2, coef[4] / radius**2,
                             2.0 * coef[5] / radius**2)
            n_out, k_max, k_min, d_max, d_min = _shape(t1, t2, normal, fu, fv, fuu, fuv, fvv)
            contact = origin + coef[0] * normal
            if it == 0:
                threshold = max(OUTLIER_FLOOR_MM, 4.0 * rms)
                for j in range(cnt):
                    valid[j] = valid[j] and abs(residual[j]) <= threshold
            # the second fundamental form as (xx, yy, zz, 2xy, 2xz, 2yz), per mm
            q = np.empty(6)
            q[0] = k_max * d_max[0] ** 2 + k_min * d_min[0] ** 2
            q[1] = k_max * d_max[1] ** 2 + k_min * d_min[1] ** 2
            q[2] = k_max * d_max[2] ** 2 + k_min * d_min[2] ** 2
            q[3] = 2.0 * (k_max * d_max[0] * d_max[1] + k_min * d_min[0] * d_min[1])
            q[4] = 2.0 * (k_max * d_max[0] * d_max[2] + k_min * d_min[0] * d_min[2])
            q[5] = 2.0 * (k_max * d_max[1] * d_max[2] + k_min * d_min[1] * d_min[2])
            trusted = 0.0
            trusted2 = 0.0
            for j in range(cnt):
                off = 0.5 * (chord[j, 0] * q[0] + chord[j, 1] * q[1] + chord[j, 2] * q[2]
                             + chord[j, 3] * q[3] + chord[j, 4] * q[4] + chord[j, 5] * q[5])
                offset[j] = off
                px = nbr[j, 0] + off * n_out[0]
                py = nbr[j, 1] + off * n_out[1]
                pz = nbr[j, 2] + off * n_out[2]
                rx, ry, rz = px - contact[0], py - contact[1], pz - contact[2]
                x = rx * d_max[0] + ry * d_max[1] + rz * d_max[2]
                y = rx * d_min[0] + ry * d_min[1] + rz * d_min[2]
                Q = k_max * x * x + k_min * y * y
                S = min(max((k_max * x) ** 2 + (k_min * y) ** 2, 0.0), 0.96)
                beyond = 0.5 * Q - Q / (1.0 + math.sqrt(1.0 - S))
                fitted[j, 0] = px - beyond * n_out[0]
                fitted[j, 1] = py - beyond * n_out[1]
                fitted[j, 2] = pz - beyond * n_out[2]
                trust = 1.0 / (1.0 + (off / CHORD_TRUST_MM) ** 2)
                weight[j] = base[j] * trust if valid[j] else 0.0
                if valid[j]:
                    trusted += trust
                    trusted2 += trust * trust
            quadric_only = trusted * trusted / max(trusted2, 1e-300) < MIN_QUARTIC_SUPPORT
            origin, normal = contact, n_out
        n_valid = 0
        for j in range(cnt):
            n_valid += valid[j]
        out_point[c] = contact
        out_normal[c] = n_out
        out_kmax[c] = k_max
        out_kmin[c] = k_min
        out_dmax[c] = d_max
        out_dmin[c] = d_min
        out_count[c] = n_valid
        out_rms[c] = rms


def fit_patches(sample, points_mm, normals, idx, counts, radius, start, stop, out):
    """Fit contacts ``start:stop`` into the preallocated arrays ``out``.

    sample : surface.SurfaceSample; points_mm, normals : (n, 3) float64 (unit normals);
    idx : (n, k) int64 neighbour indices, the first ``counts[i]`` of row i inside the patch;
    out : (point, normal, k_max, k_min, d_max, d_min, count, rms) arrays of length n,
    curvatures per mm.
    """
    _fit_patches(sample.points, sample.normals, sample.chord6, sample.weight, sample.is_vertex,
                 points_mm, normals, idx, counts, float(radius), int(start), int(stop),
                 *out)
