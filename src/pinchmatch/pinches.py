"""Feasible thumb-index pinches (Step #1 of the method).

A pinch is two contacts p1, p2 on the surface with unit outward normals
n1, n2. It is feasible when every rule holds:

``surface``
    (user-given contacts only) each point is within ``snap_tolerance_mm``
    of the surface; it is then snapped onto it.
``width``
    ``min_width_mm <= |p1p2| <= max_width_mm``.
``antipodal``
    p1→p2 is within ``friction_cone_deg`` of -n1, and p2→p1 within the same of -n2.
``inside``
    the segment p1p2 runs inside the solid: cast from p1 towards p2, the
    first surface it meets is at p2 and is left from inside (the fingers
    squeeze one wall or body, not across a gap).
``clearance``
    a fingertip sphere of ``fingertip_radius_mm`` touching the surface at
    p_i from outside does not cut the object (no pinch in a slot narrower
    than a finger). The sphere is centred at p_i + r·n_i, tangent at p_i.
    The method's sketch centres it on the pinch line; with a 30° friction
    cone that sphere cuts even a flat face by r(1 - cos 30°) = 1.1 mm, so
    every oblique pinch on a flat face would fail. Penetration up to
    ``CLEARANCE_TOLERANCE_MM`` (fingertip pad compliance) is allowed.
``patch``
    there is enough surface around each contact to fit its patch.

Normals in the rules are those of the fitted contact patches
(:mod:`curvature`), not of single triangles, so a faceted cylinder behaves
like the cylinder it stands for.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from .curvature import PatchGeometry, patch_geometry, tangent_frame
from .errors import ConfigError, NoFeasiblePinchError
from .surface import SurfaceContext

log = logging.getLogger(__name__)

RULES = ("surface", "width", "antipodal", "inside", "clearance", "patch")

#: allowed fingertip-sphere penetration (mm): the pad is soft
CLEARANCE_TOLERANCE_MM = 0.3
#: candidates drawn per requested pinch
OVERSAMPLE = 6
#: pre-filter margin on the friction cone with triangle normals, before patch normals exist
PREFILTER_MARGIN_DEG = 2.0
#: how many more pinches than requested get patches before the final check
SELECT_MARGIN = 1.05
#: rounds of spreading and checking before giving up on reaching the count
MAX_ROUNDS = 4


@dataclass(frozen=True)
class PinchSettings:
    """Options of pinch sampling and feasibility (lengths in mm, angles in degrees)."""

    friction_cone_deg: float = 30.0
    min_width_mm: float = 2.0
    max_width_mm: float = 100.0
    fingertip_radius_mm: float = 8.0
    patch_radius_mm: float = 8.0
    count: int = 1000
    seed: int = 0
    snap_tolerance_mm: float = 2.0

    def __post_init__(self):
        checks = [
            ("--friction-cone-deg", self.friction_cone_deg, 0.0 < self.friction_cone_deg < 90.0, "between 0 and 90 (exclusive)"),
            ("--min-width-mm", self.min_width_mm, self.min_width_mm >= 0.0, "0 or more"),
            ("--max-width-mm", self.max_width_mm, self.max_width_mm > self.min_width_mm, "larger than --min-width-mm"),
            ("--fingertip-radius-mm", self.fingertip_radius_mm, self.fingertip_radius_mm > 0.0, "positive"),
            ("--patch-radius-mm", self.patch_radius_mm, self.patch_radius_mm > 0.0, "positive"),
            ("--count", self.count, int(self.count) == self.count and self.count >= 1, "a whole number of 1 or more"),
            ("--snap-tolerance-mm", self.snap_tolerance_mm, self.snap_tolerance_mm > 0.0, "positive"),
        ]
        for option, value, ok, want in checks:
            if not (np.isfinite(value) and ok):
                raise ConfigError(f"{option}: got {value!r}; it must be {want}")

    def as_dict(self) -> dict:
        return {
            "friction_cone_deg": self.friction_cone_deg,
            "min_width_mm": self.min_width_mm,
            "max_width_mm": self.max_width_mm,
            "fingertip_radius_mm": self.fingertip_radius_mm,
            "patch_radius_mm": self.patch_radius_mm,
            "count": int(self.count),
            "seed": int(self.seed),
            "snap_tolerance_mm": self.snap_tolerance_mm,
            "clearance_tolerance_mm": CLEARANCE_TOLERANCE_MM,
        }


@dataclass(frozen=True)
class Pinches:
    """n two-finger pinch poses on one mesh (lengths in mm).

    points : (n, 2, 3) float64          contacts [p1, p2] on the mesh surface
    normals : (n, 2, 3) float64         unit outward normals of the fitted patches
    face_index : (n, 2) int64           triangle holding each contact
    kappa_max_per_m : (n, 2) float64    principal curvatures of each patch, convex positive
    kappa_min_per_m : (n, 2) float64
    dir_max : (n, 2, 3) float64         unit direction of kappa_max
    feasible : (n,) bool                every rule holds
    broken : (n, len(RULES)) bool       which rules each pinch breaks, columns in RULES order
    snap_distance_mm : (n, 2) float64   how far each given contact was moved onto the surface
                                        (0 for sampled pinches)
    rejected : dict                     sampling only: candidates rejected per rule
    """

    points: np.ndarray
    normals: np.ndarray
    face_index: np.ndarray
    kappa_max_per_m: np.ndarray
    kappa_min_per_m: np.ndarray
    dir_max: np.ndarray
    feasible: np.ndarray
    broken: np.ndarray
    snap_distance_mm: np.ndarray
    rejected: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.points)

    def broken_rules(self, i: int) -> list[str]:
        return [rule for rule, bad in zip(RULES, self.broken[i]) if bad]

    def subset(self, keep: np.ndarray) -> "Pinches":
        return Pinches(
            points=self.points[keep], normals=self.normals[keep], face_index=self.face_index[keep],
            kappa_max_per_m=self.kappa_max_per_m[keep], kappa_min_per_m=self.kappa_min_per_m[keep],
            dir_max=self.dir_max[keep], feasible=self.feasible[keep], broken=self.broken[keep],
            snap_distance_mm=self.snap_distance_mm[keep], rejected=dict(self.rejected),
        )


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between unit vectors, rowwise, in degrees."""
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0)))


def _ray_offset(context: SurfaceContext) -> float:
    return 1e-4 * max(context.scale_mm, 10.0)


def _segment_inside(context: SurfaceContext, p1, p2) -> np.ndarray:
    """True where the first surface met from p1 towards p2 is p2, left from inside."""
    seg = p2 - p1
    width = np.linalg.norm(seg, axis=1)
    u = seg / np.maximum(width, 1e-300)[:, None]
    eps = _ray_offset(context)
    face, dist = context.first_hit(p1 + eps * u, u)
    tol = np.maximum(0.05, 2e-3 * width) + 2.0 * eps
    reaches = (face >= 0) & (np.abs(dist + eps - width) <= tol)
    exiting = np.zeros(len(p1), dtype=bool)
    hit = face >= 0
    exiting[hit] = np.einsum("ij,ij->i", context.face_normals[face[hit]], u[hit]) > 0
    return reaches & exiting


def _clearance_ok(context: SurfaceContext, points, normals, radius) -> np.ndarray:
    centres = points + radius * normals
    return context.min_distance_to_samples(centres) >= radius - CLEARANCE_TOLERANCE_MM


def _rule_table(context, points, normals, valid_patch, settings, surface_ok=None):
    """(n, len(RULES)) bool: which rules each pinch breaks."""
    n = len(points)
    p1, p2 = points[:, 0], points[:, 1]
    seg = p2 - p1
    width = np.linalg.norm(seg, axis=1)
    u = seg / np.maximum(width, 1e-300)[:, None]
    broken = np.zeros((n, len(RULES)), dtype=bool)
    broken[:, RULES.index("surface")] = ~surface_ok if surface_ok is not None else False
    broken[:, RULES.index("width")] = (width < settings.min_width_mm) | (width > settings.max_width_mm)
    cone = settings.friction_cone_deg
    broken[:, RULES.index("antipodal")] = (_angle_deg(u, -normals[:, 0]) > cone) | (_angle_deg(-u, -normals[:, 1]) > cone)
    broken[:, RULES.index("inside")] = ~_segment_inside(context, p1, p2)
    r = settings.fingertip_radius_mm
    clear = _clearance_ok(context, points.reshape(-1, 3), normals.reshape(-1, 3), r).reshape(n, 2).all(axis=1)
    broken[:, RULES.index("clearance")] = ~clear
    broken[:, RULES.index("patch")] = ~valid_patch.reshape(n, 2).all(axis=1)
    return broken


def _patches(context, points, face_normals, settings) -> PatchGeometry:
    return patch_geometry(
        context, points.reshape(-1, 3), face_normals.reshape(-1, 3), patch_radius_mm=settings.patch_radius_mm
    )


def _assemble(points, points_faces, geom: PatchGeometry, broken, rejected, snap=None) -> Pinches:
    n = len(broken)
    return Pinches(
        points=points.reshape(n, 2, 3),
        normals=geom.normal.reshape(n, 2, 3),
        face_index=points_faces.reshape(n, 2),
        kappa_max_per_m=geom.kappa_max_per_m.reshape(n, 2),
        kappa_min_per_m=geom.kappa_min_per_m.reshape(n, 2),
        dir_max=geom.dir_max.reshape(n, 2, 3),
        feasible=~broken.any(axis=1),
        broken=broken,
        snap_distance_mm=np.zeros((n, 2)) if snap is None else snap.reshape(n, 2),
        rejected=rejected,
    )


def check_pinches(
    context: SurfaceContext,
    p1_mm: np.ndarray,
    p2_mm: np.ndarray,
    *,
    settings: PinchSettings = PinchSettings(),
    faces: np.ndarray | None = None,
) -> Pinches:
    """Snap user-given contacts onto the surface and check every rule.

    Parameters
    ----------
    p1_mm, p2_mm : (n, 3) float64
        Candidate contacts, near the surface.
    faces : (n, 2) int, optional
        The triangles the contacts lie on, when they are known to be on the surface (ray hits):
        they are then taken as they are, with no closest-point search.

    Returns
    -------
    Pinches
        All n candidates, in order, with ``feasible`` and ``broken`` set.
    """
    p1_mm = np.asarray(p1_mm, dtype=np.float64).reshape(-1, 3)
    p2_mm = np.asarray(p2_mm, dtype=np.float64).reshape(-1, 3)
    n = len(p1_mm)
    raw = np.stack([p1_mm, p2_mm], axis=1).reshape(-1, 3)
    if faces is None:
        closest, distance, face = context.closest_points(raw)
    else:
        closest, distance, face = raw, np.zeros(len(raw)), np.asarray(faces, dtype=np.int64).reshape(-1)
    surface_ok = (distance <= settings.snap_tolerance_mm).reshape(n, 2).all(axis=1)
    geom = _patches(context, closest, context.face_normals[face], settings)
    points = closest.reshape(n, 2, 3)
    normals = geom.normal.reshape(n, 2, 3)
    broken = _rule_table(context, points, normals, geom.valid, settings, surface_ok)
    return _assemble(points, face, geom, broken, {}, distance)


def _cone_directions(normals: np.ndarray, half_angle_deg: float, rng) -> np.ndarray:
    """Unit directions uniform in solid angle within the cone around -normal."""
    n = len(normals)
    cos_t = 1.0 - rng.random(n) * (1.0 - np.cos(np.radians(half_angle_deg)))
    sin_t = np.sqrt(1.0 - cos_t**2)
    phi = rng.random(n) * 2.0 * np.pi
    t1, t2 = tangent_frame(normals)
    return -(cos_t[:, None] * normals + sin_t[:, None] * (np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2))


def spread_order(points: np.ndarray, count: int, nearest: np.ndarray | None = None):
    """Farthest-point order of pinches, treating (p1, p2) and (p2, p1) as the same.

    points : (n, 2, 3). Each next pick is the pinch farthest from all picked
    so far, so any prefix covers the graspable regions evenly, without clumps.

    Returns ``(chosen, nearest)``: the indices of up to ``count`` new picks
    and each pinch's squared distance to its nearest pick (-1 for picks).
    Pass ``nearest`` back in to continue the same order.
    """
    n = len(points)
    centred = points - points.reshape(-1, 3).mean(axis=0)
    a = centred.reshape(n, 6)
    b = centred[:, ::-1].reshape(n, 6)
    sq = (a * a).sum(axis=1)  # same for both finger orders
    if nearest is None:
        nearest = np.full(n, np.inf)
        current = 0
    else:
        nearest = nearest.copy()
        current = int(np.argmax(nearest))
    count = min(count, int((nearest >= 0).sum()))
    chosen = np.empty(count, dtype=np.int64)
    for i in range(count):
        chosen[i] = current
        q = a[current]
        # |x - q|² = |x|² + |q|² - 2 x·q, with the better of the two finger orders
        d = sq + sq[current] - 2.0 * np.maximum(a @ q, b @ q)
        np.minimum(nearest, d, out=nearest)
        nearest[current] = -1.0
        current = int(np.argmax(nearest))
    return chosen, nearest


def sample_pinches(
    context: SurfaceContext,
    *,
    settings: PinchSettings = PinchSettings(),
    source: str = "mesh",
) -> Pinches:
    """About ``settings.count`` feasible pinches spread over every graspable region.

    Candidates: contacts p1 drawn area-uniformly (seeded), a direction drawn
    uniformly within the friction cone around -n1, and p2 the first surface
    hit along it. Cheap rules prune them with triangle normals, a
    farthest-point order spreads the survivors, and the first of those get
    fitted patches and the full check with patch normals.

    Raises
    ------
    NoFeasiblePinchError
        No candidate passes; the message says how many each rule rejected.
    """
    rng = np.random.default_rng(settings.seed)
    mesh = context.mesh
    n_cand = max(OVERSAMPLE * settings.count, 2000)
    area = mesh.area_faces
    faces = rng.choice(len(area), size=n_cand, p=area / area.sum())
    r = rng.random((n_cand, 2))
    flip = r.sum(axis=1) > 1
    r[flip] = 1.0 - r[flip]
    tri = mesh.triangles[faces]
    p1 = tri[:, 0] + r[:, :1] * (tri[:, 1] - tri[:, 0]) + r[:, 1:] * (tri[:, 2] - tri[:, 0])
    n1 = context.face_normals[faces]
    d = _cone_directions(n1, settings.friction_cone_deg, rng)

    eps = _ray_offset(context)
    face2, dist = context.first_hit(p1 + eps * d, d)
    rejected = dict.fromkeys(RULES, 0)
    escaped = face2 < 0
    hit_n = context.face_normals[np.maximum(face2, 0)]
    exiting = np.einsum("ij,ij->i", hit_n, d) > 0
    bad_inside = escaped | ~exiting
    rejected["inside"] += int(bad_inside.sum())
    width = dist + eps
    bad_width = ~bad_inside & ((width < settings.min_width_mm) | (width > settings.max_width_mm))
    rejected["width"] += int(bad_width.sum())
    keep = ~bad_inside & ~bad_width
    loose_cone = settings.friction_cone_deg + PREFILTER_MARGIN_DEG
    bad_cone = keep & (_angle_deg(d, hit_n) > loose_cone)
    rejected["antipodal"] += int(bad_cone.sum())
    keep &= ~bad_cone

    p2 = p1[keep] + width[keep, None] * d[keep]
    p1, face_pairs = p1[keep], np.stack([faces, face2], axis=1)[keep]
    r_tip = settings.fingertip_radius_mm
    clear = _clearance_ok(context, p1, n1[keep], r_tip) & _clearance_ok(context, p2, hit_n[keep], r_tip)
    rejected["clearance"] += int((~clear).sum())
    points = np.stack([p1, p2], axis=1)[clear]
    face_pairs = face_pairs[clear]
    if len(points) == 0:
        raise NoFeasiblePinchError(_no_pinch_message(source, n_cand, rejected, settings))

    # spread the survivors, then fit patches and check every rule on the first picks;
    # where picks fail with patch normals, continue the same spread order
    parts, n_feasible, nearest = [], 0, None
    for _ in range(MAX_ROUNDS):
        want = int(np.ceil(SELECT_MARGIN * (settings.count - n_feasible)))
        order, nearest = spread_order(points, want, nearest)
        if len(order) == 0:
            break
        geom = _patches(context, points[order], context.face_normals[face_pairs[order]], settings)
        broken = _rule_table(context, points[order], geom.normal.reshape(-1, 2, 3), geom.valid, settings)
        first_broken = np.argmax(broken, axis=1)
        for j, rule in enumerate(RULES):
            rejected[rule] += int((broken.any(axis=1) & (first_broken == j)).sum())
        part = _assemble(points[order], face_pairs[order], geom, broken, rejected)
        part = part.subset(part.feasible)
        parts.append(part)
        n_feasible += len(part)
        if n_feasible >= settings.count:
            break
    if n_feasible == 0:
        raise NoFeasiblePinchError(_no_pinch_message(source, n_cand, rejected, settings))
    # concatenated in spread order, so the first `count` are evenly spread
    result = _concat(parts).subset(np.arange(min(settings.count, n_feasible)))
    log.info("%s: %d feasible pinches from %d candidates", source, len(result), n_cand)
    return result


def _concat(parts: list[Pinches]) -> Pinches:
    fields = ("points", "normals", "face_index", "kappa_max_per_m", "kappa_min_per_m",
              "dir_max", "feasible", "broken", "snap_distance_mm")
    arrays = {f: np.concatenate([getattr(p, f) for p in parts]) for f in fields}
    return Pinches(**arrays, rejected=dict(parts[-1].rejected))


_RULE_HINTS = {
    "width": "the object may be too wide or thin for the width limits: check --min-width-mm/--max-width-mm and --units",
    "antipodal": "no opposite surfaces face each other: try a wider --friction-cone-deg",
    "inside": "the segments leave the solid: is the mesh open or inside-out?",
    "clearance": "a fingertip does not fit: try a smaller --fingertip-radius-mm",
    "patch": "too little surface around the contacts: try a smaller --patch-radius-mm",
    "surface": "the points are far from the surface",
}


def _no_pinch_message(source, n_cand, rejected, settings) -> str:
    parts = [f"{rule} {count}" for rule, count in rejected.items() if count]
    worst = max(rejected, key=rejected.get)
    return (
        f"{source}: no feasible pinch among {n_cand} candidates (rejected by "
        f"{', '.join(parts) or 'nothing'}); {_RULE_HINTS[worst]}"
    )
