"""Feasible tripod grasps: the thumb against the index and middle fingers.

After the thumb-index pinch, the tripod is the most common precision grasp of small household
objects (the GRASP taxonomy, Feix et al. 2016). A tripod is three contacts on the surface, the
thumb's p0, the index's p1 and the middle finger's p2, with unit outward normals n0, n1, n2,
each touched by a fingertip sphere of ``fingertip_radius_mm`` centred at c_i = p_i + r·n_i. It is
feasible when every rule of :data:`TRIPOD_RULES` holds:

``region``
    as for pinches: each contact where the object's regions allow.
``aperture``
    ``min_width_mm <= |m - p0| <= max_width_mm``, m = (p1 + p2) / 2 the middle of the two fingers:
    the span of thumb and fingers, a pinch's width.
``spacing``
    the fingertip centres c1 and c2 lie from 2r - 2·tol apart (two pads side by side, each as soft
    as the clearance allows) to ``MAX_SPACING_MM``: index and middle spread by about 25° at the
    fingertips of an 80 mm finger, 16 mm pads (hand anthropometry, Greiner 1991; a documented
    choice).
``balance``
    the grasp can balance a small disturbance: it is force closure. The test (Li, Liu and Cai 2003,
    after Ponce and Faverjon's planar test of 1995): three frictional point contacts hold an object
    in force closure when three forces in the plane of the contacts, each strictly inside its
    contact's friction cone (``friction_cone_deg`` about -n_i), meet at one point x strictly inside
    the contact triangle; the three forces, pointing from the contacts to x, then balance with
    positive magnitudes, and friction resists the rest. x is looked for on a fixed barycentric grid
    of the triangle, at least ``BALANCE_INSIDE`` from each side and ``BALANCE_MARGIN_DEG`` inside
    each cone (the disturbance's margin). The tests check it independently, by linear programming
    over the friction cones' edges (the grasp matrix spans every wrench positively).
``clearance``
    each fingertip sphere clears the object and what it stands on, as for pinches.
``reach``
    three fingers of one hand get to the contacts (:func:`pinchmatch.grasp.hand.reach` with three
    fingers): the band of approaches lies across the line from the thumb to m, the thumb comes from
    the other side, and index and middle lie at most ``finger_stagger_mm`` apart along the approach.
``patch``
    there is enough surface around each contact to fit its patch.

Sampling is :mod:`pinchmatch.grasp.tripods`'s.
"""


from __future__ import annotations

import numpy as np

from ..config import CLEARANCE_TOLERANCE_MM, PinchSettings
from ..mesh.surface import SurfaceContext
from .hand import Reach
from .pinches import (Pinches, assemble, check_patch_radius, clearance_broken, patches, reach_rule,
                      region_broken)
from .strata import grip_width_mm

TRIPOD_RULES = ("region", "aperture", "spacing", "balance", "clearance", "reach", "patch")
#: the fingers of a tripod, in the order of its contacts
FINGERS = ("thumb", "index", "middle")
#: the largest distance between the index's and the middle finger's fingertip centres (mm)
MAX_SPACING_MM = 45.0
#: the meeting point lies at least this barycentric share inside each side of the triangle
BALANCE_INSIDE = 0.04
#: in-plane directions tried for parallel forces
PARALLEL_DIRECTIONS = 72
#: each force lies at least this far inside its friction cone (degrees)
BALANCE_MARGIN_DEG = 2.0
#: a contact triangle whose smallest height is below this (mm) has no plane to balance in
MIN_HEIGHT_MM = 1.0


class Tripods(Pinches):
    """n tripod grasps on one mesh: the arrays of :class:`pinchmatch.grasp.pinches.Pinches`, with
    three contacts each (thumb, index, middle) and ``broken``'s columns in :data:`TRIPOD_RULES`
    order."""

    rules = TRIPOD_RULES


def _plane_frames(points: np.ndarray, normals: np.ndarray):
    """Each tripod's plane of forces: in-plane axes (n, 2, 3) and the contacts in them (n, 3, 2),
    origin p0.

    The contacts' plane; where the triangle's smallest height is below ``MIN_HEIGHT_MM`` (the thumb
    on a thin wall between the two fingers), the plane through the fingers' line along the thumb's
    normal, into which the thumb is projected (it lies within ``MIN_HEIGHT_MM`` of it). ``flat``:
    the fingers' line runs along the thumb's normal too, and no plane is left."""
    edges = points[:, [1, 2, 0]] - points  # side i runs from contact i to the next
    normal = np.cross(edges[:, 0], -edges[:, 2])
    twice_area = np.linalg.norm(normal, axis=1)
    thin = twice_area < MIN_HEIGHT_MM * np.maximum(np.linalg.norm(edges, axis=2).max(axis=1),
                                                   1e-300)
    across = np.cross(edges[:, 1], normals[:, 0])
    size = np.linalg.norm(across, axis=1)
    flat = thin & (size < 0.1 * np.linalg.norm(edges[:, 1], axis=1))
    normal = np.where(thin[:, None], across / np.maximum(size, 1e-300)[:, None],
                      normal / np.maximum(twice_area, 1e-300)[:, None])
    # index to middle
    ex = edges[:, 1] / np.maximum(np.linalg.norm(edges[:, 1], axis=1, keepdims=True), 1e-300)
    axes = np.stack([ex, np.cross(normal, ex)], axis=1)
    return axes, np.einsum("nkd,njd->nkj", points - points[:, :1], axes), flat


def contact_plane_normals(points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(n, 3) unit normal of each tripod's plane of forces (:func:`_plane_frames`)."""
    axes, _, _ = _plane_frames(points, normals)
    return np.cross(axes[:, 0], axes[:, 1])


def _in_plane_cones(axes, normals, cone_deg):
    """Per contact, the friction cone's cut with the contact plane: the unit in-plane direction of
    the inward normal (n, 3, 2), and the half-angle's cosine about it (n, 3); -inf where the cone
    misses the plane (the normal lies more than the cone's angle out of it)."""
    inward = -np.einsum("nkd,njd->nkj", normals, axes)  # (n, 3, 2)
    size = np.linalg.norm(inward, axis=2)
    cos_cone = np.cos(np.radians(max(cone_deg - BALANCE_MARGIN_DEG, 0.0)))
    # cos β, β the in-plane half-angle
    cut = np.where(size > cos_cone, cos_cone / np.maximum(size, 1e-300), np.inf)
    return inward / np.maximum(size, 1e-300)[..., None], cut


def _some_point_inside(G: np.ndarray, C: np.ndarray) -> np.ndarray:
    """(n,) bool: the half-planes G x >= C (n, m, 2), (n, m) have a common point. Their intersection
    lies in a pointed cone, so where it is not empty some two of their lines meet at a point inside
    all."""
    i, j = np.triu_indices(G.shape[1], k=1)
    det = G[:, i, 0] * G[:, j, 1] - G[:, i, 1] * G[:, j, 0]
    regular = np.abs(det) > 1e-12
    safe = np.where(regular, det, 1.0)
    x = np.stack([(C[:, i] * G[:, j, 1] - G[:, i, 1] * C[:, j]) / safe,
                  (G[:, i, 0] * C[:, j] - C[:, i] * G[:, j, 0]) / safe], axis=-1)
    slack = np.matmul(x, G.transpose(0, 2, 1)) - C[:, None, :]
    tol = 1e-9 * (1.0 + np.abs(C).max(axis=1) + np.abs(x).max(axis=(1, 2)))
    return ((slack >= -tol[:, None, None]).all(axis=2) & regular).any(axis=1)


def balance_broken(points: np.ndarray, normals: np.ndarray, cone_deg: float) -> np.ndarray:
    """(n,) bool: the tripods (n, 3, 3) whose forces cannot balance as the balance rule asks (module
    notes).

    Three forces in balance lie in the contacts' plane and meet at one point x, or are parallel. In
    the plane each contact's forces form a wedge about its inward normal's in-plane part. With λ
    the barycentric coordinates of x: forces meeting inside the triangle (every λ_k >=
    ``BALANCE_INSIDE``) each point from their contact to x; meeting behind contact j (the others'
    λ_k <= -``BALANCE_INSIDE``), contact j's points away from x. Each case is a set of half-planes
    with a common point or none. Parallel forces are tested over ``PARALLEL_DIRECTIONS``
    directions."""
    n = len(points)
    if n == 0:
        return np.zeros(0, dtype=bool)
    axes, q, flat = _plane_frames(points, normals)
    a, cut = _in_plane_cones(axes, normals, cone_deg)
    misses = ~np.isfinite(cut).all(axis=1)
    cos_b = np.minimum(cut, 1.0)
    sin_b = np.sqrt(np.maximum(1.0 - cos_b**2, 0.0))
    perp = np.stack([-a[..., 1], a[..., 0]], axis=-1)
    # each wedge's two sides: g·(x - p) >= 0 with g = sin β a ∓ cos β a⊥
    wedge = np.concatenate([sin_b[..., None] * a - cos_b[..., None] * perp,
                            sin_b[..., None] * a + cos_b[..., None] * perp], axis=1)  # (n, 6, 2)
    apex = np.concatenate([q, q], axis=1)
    # λ_k >= 0 as N_k·x >= N_k·q_(k+1), N_k across the side opposite contact k, towards it
    N = np.stack([q[:, [1, 2, 0], 1] - q[:, [2, 0, 1], 1], q[:, [2, 0, 1], 0] - q[:, [1, 2, 0], 0]],
                 axis=-1)
    height = np.einsum("nkj,nkj->nk", N, q - q[:, [1, 2, 0]])
    N *= np.where(height < 0, -1.0, 1.0)[..., None]
    on_side = np.einsum("nkj,nkj->nk", N, q[:, [1, 2, 0]])
    shrink = BALANCE_INSIDE * np.abs(height)
    ok = np.zeros(n, dtype=bool)
    for behind in (None, 0, 1, 2):
        sign = np.ones(3) if behind is None else np.where(np.arange(3) == behind, -1.0, 1.0)
        g = wedge * np.tile(sign, 2)[None, :, None]
        parts_G, parts_C = [g], [np.einsum("nkj,nkj->nk", g, apex)]
        others = [k for k in range(3) if k != behind]
        if behind is None:
            parts_G.append(N)
            parts_C.append(on_side + shrink)
        else:
            parts_G.append(-N[:, others])
            parts_C.append(-on_side[:, others] + shrink[:, others])
        ok |= _some_point_inside(np.concatenate(parts_G, axis=1), np.concatenate(parts_C, axis=1))
    ok &= ~misses
    # parallel forces (their meeting point at infinity): the fingers' along v, the thumb's against
    # it, the thumb's line strictly between the fingers' (a plate's rim held thumb inside, fingers
    # outside)
    theta = np.arange(PARALLEL_DIRECTIONS) * (2.0 * np.pi / PARALLEL_DIRECTIONS)
    v = np.stack([np.cos(theta), np.sin(theta)], axis=-1)  # (K, 2)
    # cosine of v against each contact's in-plane inward direction
    along = np.einsum("kj,nfj->nkf", v, a)
    cones = (-along[..., 0] >= cut[:, None, 0]) & (along[..., 1]
                                                   >= cut[:, None, 1]) & (along[..., 2]
                                                                          >= cut[:, None, 2])
    side = np.einsum("kj,nfj->nkf", np.stack([-v[:, 1], v[:, 0]], axis=-1), q)  # across the forces
    lo, hi = np.minimum(side[..., 1], side[..., 2]), np.maximum(side[..., 1], side[..., 2])
    margin = BALANCE_INSIDE * (hi - lo)
    parallel = (cones & (side[..., 0] > lo + margin) & (side[..., 0] < hi - margin)).any(axis=1)
    return flat | ~(ok | parallel)


def aperture_broken(points: np.ndarray, settings: PinchSettings) -> np.ndarray:
    width = grip_width_mm(points)
    return (width < settings.min_width_mm) | (width > settings.max_width_mm)


def spacing_mm(points: np.ndarray, normals: np.ndarray, radius_mm: float) -> np.ndarray:
    """(n,) distance between the index's and the middle finger's fingertip centres."""
    tips = points[:, 1:] + radius_mm * normals[:, 1:]
    return np.linalg.norm(tips[:, 1] - tips[:, 0], axis=1)


def spacing_broken(points: np.ndarray, normals: np.ndarray, settings: PinchSettings) -> np.ndarray:
    s = spacing_mm(points, normals, settings.fingertip_radius_mm)
    return (s < 2.0 * (settings.fingertip_radius_mm
                       - CLEARANCE_TOLERANCE_MM)) | (s > MAX_SPACING_MM)


def cheap_broken(context, points, normals, settings, cone_deg, *, every: bool = True) -> np.ndarray:
    """(n, len(TRIPOD_RULES)) bool of the rules that need no patches and no approach search. Without
    ``every``, balance, the dearest, is tested only where the others hold (a sampler's candidates:
    one broken rule is enough to drop them)."""
    broken = np.zeros((len(points), len(TRIPOD_RULES)), dtype=bool)
    broken[:, 0] = region_broken(context, points)
    broken[:, 1] = aperture_broken(points, settings)
    broken[:, 2] = spacing_broken(points, normals, settings)
    broken[:, 4] = clearance_broken(context, points, normals, settings)
    rows = np.arange(len(points)) if every else np.flatnonzero(~broken.any(axis=1))
    broken[rows, 3] = balance_broken(points[rows], normals[rows], cone_deg)
    return broken


def check_tripods(context: SurfaceContext, points: np.ndarray, faces: np.ndarray, *,
                  settings: PinchSettings = PinchSettings(), approach: np.ndarray | None = None,
                  rejected: dict | None = None, with_reach: bool = True) -> Tripods:
    """Every rule for n tripods whose contacts (n, 3, 3) lie on the triangles ``faces`` (n, 3), with
    the normals of fitted patches; ``approach`` (n, 3) a hand direction to try first. All n are
    returned, in order, with ``feasible`` and ``broken`` set; ``rejected`` counts the infeasible
    ones under the first rule each breaks. Without ``with_reach``, reach is left unchecked (as
    :func:`pinchmatch.grasp.pinches.check_pinches` leaves it, for
    :func:`~pinchmatch.grasp.pinches.check_reach`)."""
    check_patch_radius(context, settings)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3, 3)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    geom = patches(context, points, context.face_normals[faces], settings)
    normals = geom.normal.reshape(-1, 3, 3)
    broken = cheap_broken(context, points, normals, settings, settings.friction_cone_deg)
    if with_reach:
        found = reach_rule(context, points, normals, settings, approach)
        # contacts on one point or line: no hand direction
        lost = ~(np.linalg.norm(found.approach, axis=1) > 0.5)
        if lost.any():
            found = Reach(found.ok & ~lost, np.where(lost[:, None], np.nan, found.approach),
                          np.where(lost, np.nan, found.clearance_mm))
    else:
        found = Reach(np.ones(len(points), dtype=bool), np.full((len(points), 3), np.nan),
                      np.full(len(points), np.nan))
    broken[:, TRIPOD_RULES.index("reach")] = ~found.ok
    broken[:, TRIPOD_RULES.index("patch")] = ~geom.valid.reshape(-1, 3).all(axis=1)
    if rejected is not None:
        count_first(broken, rejected)
    return assemble(points, faces, geom, broken, found, dict(rejected or {}), kind=Tripods)


def count_first(broken, rejected):
    """Count each rejected tripod once, under the first rule it breaks."""
    bad = broken.any(axis=1)
    first = np.argmax(broken, axis=1)
    for j, rule in enumerate(TRIPOD_RULES):
        rejected[rule] += int((bad & (first == j)).sum())


