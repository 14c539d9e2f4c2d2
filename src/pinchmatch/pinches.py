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
``clearance``
    a fingertip sphere of ``fingertip_radius_mm`` touching the surface at
    p_i from outside does not cut the object (no pinch in a slot narrower
    than a finger). The sphere is centred at p_i + r·n_i, tangent at p_i.
    The method's sketch centres it on the pinch line; with a 30° friction
    cone that sphere cuts even a flat face by r(1 - cos 30°) = 1.1 mm, so
    every oblique pinch on a flat face would fail. Penetration up to
    ``CLEARANCE_TOLERANCE_MM`` (fingertip pad compliance) is allowed.
``reach``
    two fingers of one hand get to the contacts: some approach direction
    lets both finger capsules clear the object (:mod:`hand`). The segment
    p1p2 may cross cavities and gaps: people squeeze across cups, bowls,
    boxes and handles.
``patch``
    there is enough surface around each contact to fit its patch.

Each rule is one function below, used both by the cheap pre-filter of
sampled candidates (with triangle normals) and by the final check (with the
normals of the fitted contact patches, :mod:`curvature`), so a faceted
cylinder behaves like the cylinder it stands for.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field

import numpy as np

from .curvature import PatchGeometry, patch_geometry, tangent_frame
from .errors import ConfigError, NoFeasiblePinchError
from .hand import PAD_TOLERANCE_MM, Hand, Reach, reach
from .surface import SurfaceContext

log = logging.getLogger(__name__)

RULES = ("surface", "width", "antipodal", "clearance", "reach", "patch")

#: allowed fingertip-sphere penetration (mm): the pad is soft
CLEARANCE_TOLERANCE_MM = PAD_TOLERANCE_MM
#: candidates drawn per requested pinch in the first, area-uniform round
OVERSAMPLE = 6
#: pre-filter margin on the friction cone with triangle normals, before patch normals exist
PREFILTER_MARGIN_DEG = 2.0
#: how many more pinches than requested get the full check in a round
SELECT_MARGIN = 1.05
#: rounds of checking before giving up on reaching the count
MAX_ROUNDS = 12
#: all rounds together draw at most this many candidates per requested pinch
MAX_DRAW_FACTOR = 40
#: the first round checks at most this many picks before judging how graspable the object is
PROBE_PICKS = 256
#: below this share of feasible picks, new candidates are drawn near the feasible ones found
LOCAL_BELOW = 0.5
#: a ray from p1 is followed through at most this many surfaces (exits are candidate p2)
MAX_EXITS = 8
#: local candidates start within this many fingertip radii of a feasible contact
LOCAL_RADIUS_TIPS = 1.5


@dataclass(frozen=True)
class PinchSettings:
    """Options of pinch sampling and feasibility (lengths in mm, angles in degrees)."""

    friction_cone_deg: float = 30.0
    min_width_mm: float = 0.5
    max_width_mm: float = 100.0
    fingertip_radius_mm: float = 8.0
    patch_radius_mm: float = 8.0
    count: int = 1000
    seed: int = 0
    snap_tolerance_mm: float = 2.0
    finger_radius_mm: float = 8.0
    finger_length_mm: float = 45.0
    approach_tilt_deg: float = 30.0

    def __post_init__(self):
        checks = [
            ("--friction-cone-deg", self.friction_cone_deg, 0.0 < self.friction_cone_deg < 90.0, "between 0 and 90 (exclusive)"),
            ("--min-width-mm", self.min_width_mm, self.min_width_mm >= 0.0, "0 or more"),
            ("--max-width-mm", self.max_width_mm, self.max_width_mm > self.min_width_mm, "larger than --min-width-mm"),
            ("--fingertip-radius-mm", self.fingertip_radius_mm, self.fingertip_radius_mm > 0.0, "positive"),
            ("--patch-radius-mm", self.patch_radius_mm, self.patch_radius_mm > 0.0, "positive"),
            ("--count", self.count, int(self.count) == self.count and self.count >= 1, "a whole number of 1 or more"),
            ("--snap-tolerance-mm", self.snap_tolerance_mm, self.snap_tolerance_mm > 0.0, "positive"),
            ("--finger-radius-mm", self.finger_radius_mm,
             CLEARANCE_TOLERANCE_MM < self.finger_radius_mm <= self.fingertip_radius_mm,
             f"more than {CLEARANCE_TOLERANCE_MM:g} and at most --fingertip-radius-mm (the finger starts "
             "at the fingertip sphere's centre)"),
            ("--finger-length-mm", self.finger_length_mm, 0.0 < self.finger_length_mm <= 500.0, "between 0 and 500"),
            ("--approach-tilt-deg", self.approach_tilt_deg, 0.0 <= self.approach_tilt_deg < 90.0,
             "between 0 and 90 (0 included)"),
        ]
        for option, value, ok, want in checks:
            if not (np.isfinite(value) and ok):
                raise ConfigError(f"{option}: got {value!r}; it must be {want}")

    @property
    def hand(self) -> Hand:
        return Hand(fingertip_radius_mm=self.fingertip_radius_mm, finger_radius_mm=self.finger_radius_mm,
                    finger_length_mm=self.finger_length_mm, approach_tilt_deg=self.approach_tilt_deg,
                    tolerance_mm=CLEARANCE_TOLERANCE_MM)

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
            "finger_radius_mm": self.finger_radius_mm,
            "finger_length_mm": self.finger_length_mm,
            "approach_tilt_deg": self.approach_tilt_deg,
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
    approach : (n, 3) float64           unit direction from the fingertips towards the hand with the
                                        most clearance (:mod:`hand`); NaN where no approach clears
    approach_clearance_mm : (n,) float64  smallest distance from either finger's axis to the
                                        surface minus the finger radius, along ``approach``
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
    approach: np.ndarray
    approach_clearance_mm: np.ndarray
    rejected: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.points)

    def broken_rules(self, i: int) -> list[str]:
        return [rule for rule, bad in zip(RULES, self.broken[i]) if bad]

    def subset(self, keep: np.ndarray) -> "Pinches":
        return Pinches(**{f: getattr(self, f)[keep] for f in ARRAY_FIELDS}, rejected=dict(self.rejected))


#: the per-pinch arrays of :class:`Pinches`, in declaration order
ARRAY_FIELDS = tuple(f.name for f in dataclasses.fields(Pinches) if f.name != "rejected")


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between unit vectors, rowwise, in degrees."""
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0)))


def _line(points):
    seg = points[:, 1] - points[:, 0]
    width = np.linalg.norm(seg, axis=1)
    return width, seg / np.maximum(width, 1e-300)[:, None]


# -- the rules, each written once ------------------------------------------------------------

def width_broken(points: np.ndarray, settings: PinchSettings) -> np.ndarray:
    width, _ = _line(points)
    return (width < settings.min_width_mm) | (width > settings.max_width_mm)


def antipodal_broken(points: np.ndarray, normals: np.ndarray, cone_deg: float) -> np.ndarray:
    _, u = _line(points)
    return (_angle_deg(u, -normals[:, 0]) > cone_deg) | (_angle_deg(-u, -normals[:, 1]) > cone_deg)


def clearance_broken(context: SurfaceContext, points: np.ndarray, normals: np.ndarray,
                     settings: PinchSettings) -> np.ndarray:
    r = settings.fingertip_radius_mm
    centres = (points + r * normals).reshape(-1, 3)
    clear = context.min_distance_to_samples(centres) >= r - CLEARANCE_TOLERANCE_MM
    return ~clear.reshape(-1, 2).all(axis=1)


def reach_rule(context: SurfaceContext, points: np.ndarray, normals: np.ndarray, settings: PinchSettings,
               approach: np.ndarray | None = None) -> Reach:
    return reach(context, points, normals, settings.hand, approach=approach)


def _cheap_broken(context, points, normals, settings, cone_deg):
    """(n, len(RULES)) bool of the rules that need no patches and no approach search."""
    broken = np.zeros((len(points), len(RULES)), dtype=bool)
    broken[:, RULES.index("width")] = width_broken(points, settings)
    broken[:, RULES.index("antipodal")] = antipodal_broken(points, normals, cone_deg)
    broken[:, RULES.index("clearance")] = clearance_broken(context, points, normals, settings)
    return broken


def _rule_table(context, points, normals, valid_patch, settings, surface_ok=None, approach=None):
    """Which rules each pinch breaks, (n, len(RULES)) bool, and its reach."""
    broken = _cheap_broken(context, points, normals, settings, settings.friction_cone_deg)
    if surface_ok is not None:
        broken[:, RULES.index("surface")] = ~surface_ok
    found = reach_rule(context, points, normals, settings, approach)
    broken[:, RULES.index("reach")] = ~found.ok
    broken[:, RULES.index("patch")] = ~valid_patch.reshape(-1, 2).all(axis=1)
    return broken, found


def _patches(context, points, face_normals, settings) -> PatchGeometry:
    return patch_geometry(
        context, points.reshape(-1, 3), face_normals.reshape(-1, 3), patch_radius_mm=settings.patch_radius_mm
    )


def _assemble(points, points_faces, geom: PatchGeometry, broken, found: Reach, rejected, snap=None) -> Pinches:
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
        approach=found.approach,
        approach_clearance_mm=found.clearance_mm,
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
        All n candidates, in order, with ``feasible``, ``broken`` and ``approach`` set.
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
    broken, found = _rule_table(context, points, normals, geom.valid, settings, surface_ok)
    return _assemble(points, face, geom, broken, found, {}, distance)


def _cone_directions(normals: np.ndarray, half_angle_deg: float, rng) -> np.ndarray:
    """Unit directions uniform in solid angle within the cone around -normal."""
    n = len(normals)
    cos_t = 1.0 - rng.random(n) * (1.0 - np.cos(np.radians(half_angle_deg)))
    sin_t = np.sqrt(1.0 - cos_t**2)
    phi = rng.random(n) * 2.0 * np.pi
    t1, t2 = tangent_frame(normals)
    return -(cos_t[:, None] * normals + sin_t[:, None] * (np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2))


def _pair_vectors(points: np.ndarray):
    """Centred 6-vectors of pinches in both finger orders, for the spread distance."""
    n = len(points)
    return points.reshape(n, 6), points[:, ::-1].reshape(n, 6)


def spread_order(points: np.ndarray, count: int, nearest: np.ndarray | None = None):
    """Farthest-point order of pinches, treating (p1, p2) and (p2, p1) as the same.

    points : (n, 2, 3). Each next pick is the pinch farthest from all picked
    so far, so any prefix covers the graspable regions evenly, without clumps.

    Returns ``(chosen, nearest)``: the indices of up to ``count`` new picks
    and each pinch's squared distance to its nearest pick (-1 for picks).
    Pass ``nearest`` back in to continue the same order.
    """
    n = len(points)
    a, b = _pair_vectors(points - points.reshape(-1, 3).mean(axis=0))
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


def _nearest_to(points: np.ndarray, picked: np.ndarray) -> np.ndarray:
    """Squared spread distance from each pinch to the nearest of ``picked`` (inf when none)."""
    out = np.full(len(points), np.inf)
    if len(picked) == 0 or len(points) == 0:
        return out
    origin = points.reshape(-1, 3).mean(axis=0)
    a, b = _pair_vectors(points - origin)
    q, _ = _pair_vectors(picked - origin)
    sq_a, sq_q = (a * a).sum(axis=1), (q * q).sum(axis=1)
    for s in range(0, len(q), 2048):
        block = q[s:s + 2048]
        d = sq_a[:, None] + sq_q[None, s:s + 2048] - 2.0 * np.maximum(a @ block.T, b @ block.T)
        np.minimum(out, d.min(axis=1), out=out)
    return out


@dataclass
class _Pool:
    """Candidates that passed the cheap rules, with their spread distance to every pick so far."""

    points: np.ndarray
    faces: np.ndarray
    nearest: np.ndarray  # squared spread distance to the nearest pick, -1 once picked

    @classmethod
    def empty(cls) -> "_Pool":
        return cls(np.zeros((0, 2, 3)), np.zeros((0, 2), np.int64), np.zeros(0))

    def add(self, points, faces, picked_points):
        self.nearest = np.concatenate([self.nearest, _nearest_to(points, picked_points)])
        self.points = np.concatenate([self.points, points])
        self.faces = np.concatenate([self.faces, faces])

    def pick(self, count: int) -> np.ndarray:
        if len(self.points) == 0 or count <= 0:
            return np.zeros(0, np.int64)
        order, self.nearest = spread_order(self.points, count, self.nearest)
        return order

    def saw(self, picked_points):
        """Picks made from another pool count for this one's spread too."""
        live = self.nearest >= 0
        self.nearest[live] = np.minimum(self.nearest[live], _nearest_to(self.points[live], picked_points))


def _draw(context, p1, face1, settings, rng, rejected):
    """Candidates from contacts p1: exits along directions in the friction cone, cheap rules applied."""
    n1 = context.face_normals[face1]
    d = _cone_directions(n1, settings.friction_cone_deg, rng)
    ray, face2, dist = context.exits(p1, d, max_distance=settings.max_width_mm * (1 + 1e-6), max_hits=MAX_EXITS)
    n_rays = len(p1)
    # a ray with no exit within the largest width offers no second contact
    rejected["width"] += int(n_rays - len(np.unique(ray)))
    points = np.stack([p1[ray], p1[ray] + dist[:, None] * d[ray]], axis=1)
    faces = np.stack([face1[ray], face2], axis=1)
    normals = context.face_normals[faces]
    broken = _cheap_broken(context, points, normals, settings, settings.friction_cone_deg + PREFILTER_MARGIN_DEG)
    _count_first(broken, rejected)
    keep = ~broken.any(axis=1)
    return points[keep], faces[keep]


def _count_first(broken, rejected):
    """Count each rejected candidate once, under the first rule it breaks."""
    bad = broken.any(axis=1)
    first = np.argmax(broken, axis=1)
    for j, rule in enumerate(RULES):
        rejected[rule] += int((bad & (first == j)).sum())


def _uniform_contacts(context, n, rng):
    mesh = context.mesh
    area = mesh.area_faces
    faces = rng.choice(len(area), size=n, p=area / area.sum())
    r = rng.random((n, 2))
    flip = r.sum(axis=1) > 1
    r[flip] = 1.0 - r[flip]
    tri = mesh.triangles[faces]
    p1 = tri[:, 0] + r[:, :1] * (tri[:, 1] - tri[:, 0]) + r[:, 1:] * (tri[:, 2] - tri[:, 0])
    return p1, faces


def _local_contacts(context, seeds, n, radius, rng):
    """n contacts near ``seeds`` (contacts of feasible pinches): random dense-sample points within ``radius``."""
    sample = context.sample
    k = int(min(64, len(sample.points)))
    which = rng.integers(0, len(seeds), size=n)
    dist, idx = context.tree.query(seeds, k=k, distance_upper_bound=radius, workers=-1)
    dist, idx = dist.reshape(len(seeds), k), idx.reshape(len(seeds), k)
    valid = np.isfinite(dist)
    counts = valid.sum(axis=1)  # at least 1: the seed's own nearest sample
    pick = np.minimum((rng.random(n) * counts[which]).astype(np.int64), counts[which] - 1)
    chosen = idx[which, pick]
    ok = np.isfinite(dist[which, pick])
    chosen = chosen[ok]
    return sample.points[chosen], sample.face_index[chosen]


def sample_pinches(
    context: SurfaceContext,
    *,
    settings: PinchSettings = PinchSettings(),
    source: str = "mesh",
) -> Pinches:
    """About ``settings.count`` feasible pinches spread over every graspable region.

    Candidates: contacts p1 drawn area-uniformly (seeded), a direction drawn
    uniformly within the friction cone around -n1, and as p2 every point
    where the ray along it leaves the solid within the largest width. The
    cheap rules prune them with triangle normals; a farthest-point order
    spreads the survivors; in rounds, the next picks get the reach search,
    fitted patches and the full check with patch normals.

    When the first picks show that few places are graspable (a bowl's rim, a
    mug's handle), later rounds draw new candidates near the contacts of the
    feasible pinches found so far, and the spread order, which keeps its
    distances to every earlier pick, takes them in turn. All rounds together
    draw at most ``MAX_DRAW_FACTOR`` candidates per requested pinch.

    Raises
    ------
    NoFeasiblePinchError
        No candidate passes; the message says how many each rule rejected.
    """
    rng = np.random.default_rng(settings.seed)
    count = settings.count
    rejected = dict.fromkeys(RULES, 0)
    n_first = max(OVERSAMPLE * count, 2000)
    budget = MAX_DRAW_FACTOR * max(count, 50)
    p1, f1 = _uniform_contacts(context, n_first, rng)
    points, faces = _draw(context, p1, f1, settings, rng, rejected)
    drawn = n_first
    if len(points) == 0:
        raise NoFeasiblePinchError(_no_pinch_message(source, drawn, rejected, settings))
    uniform = _Pool(points, faces, np.full(len(points), np.inf))
    local = _Pool.empty()

    parts: list[Pinches] = []
    picked = np.zeros((0, 2, 3))
    n_feasible, n_checked = 0, 0
    local_radius = LOCAL_RADIUS_TIPS * settings.fingertip_radius_mm
    for round_ in range(MAX_ROUNDS):
        need = count - n_feasible
        if need <= 0:
            break
        share = n_feasible / n_checked if n_checked else 1.0
        want = int(np.ceil(SELECT_MARGIN * need / max(share, 0.05)))
        want = min(want, PROBE_PICKS) if round_ == 0 else min(want, 4 * need + PROBE_PICKS)
        local_mode = n_checked > 0 and n_feasible > 0 and share < LOCAL_BELOW
        if local_mode and drawn < budget:
            seeds = np.concatenate([p.points.reshape(-1, 3) for p in parts])
            n_local = int(min(budget - drawn, OVERSAMPLE * want))
            lp, lf = _local_contacts(context, seeds, n_local, local_radius, rng)
            drawn += n_local
            new_points, new_faces = _draw(context, lp, lf, settings, rng, rejected)
            local.add(new_points, new_faces, picked)
        # in local mode the candidates near feasible pinches go first
        first, second = (local, uniform) if local_mode else (uniform, local)
        a = first.pick(want)
        second.saw(first.points[a])
        b = second.pick(want - len(a))
        first.saw(second.points[b])
        chosen = np.concatenate([first.points[a], second.points[b]])
        chosen_f = np.concatenate([first.faces[a], second.faces[b]])
        if len(chosen) == 0:
            break
        picked = np.concatenate([picked, chosen])
        n_checked += len(chosen)
        part = _check_picks(context, chosen, chosen_f, settings, rejected)
        parts.append(part)
        n_feasible += len(part)
    if n_feasible == 0:
        raise NoFeasiblePinchError(_no_pinch_message(source, drawn, rejected, settings))
    # concatenated in spread order, so the first `count` are evenly spread
    result = concat_pinches(parts, rejected).subset(np.arange(min(count, n_feasible)))
    log.info("%s: %d feasible pinches from %d candidates", source, len(result), drawn)
    return result


def _check_picks(context, points, faces, settings, rejected) -> Pinches:
    """The feasible ones among spread picks: reach first (triangle normals), then patches and every rule."""
    early = reach_rule(context, points, context.face_normals[faces], settings)
    rejected["reach"] += int((~early.ok).sum())
    points, faces = points[early.ok], faces[early.ok]
    geom = _patches(context, points, context.face_normals[faces], settings)
    broken, found = _rule_table(context, points, geom.normal.reshape(-1, 2, 3), geom.valid, settings,
                                approach=early.approach[early.ok])
    _count_first(broken, rejected)
    part = _assemble(points, faces, geom, broken, found, rejected)
    return part.subset(part.feasible)


def concat_pinches(parts: list[Pinches], rejected: dict | None = None) -> Pinches:
    """The pinches of ``parts`` in order; ``rejected`` from the last part unless given."""
    arrays = {f: np.concatenate([getattr(p, f) for p in parts]) for f in ARRAY_FIELDS}
    return Pinches(**arrays, rejected=dict(parts[-1].rejected if rejected is None else rejected))


_RULE_HINTS = {
    "width": "the object may be too wide or thin for the width limits: check --min-width-mm/--max-width-mm and --units",
    "antipodal": "no opposite surfaces face each other: try a wider --friction-cone-deg",
    "clearance": "a fingertip does not fit: try a smaller --fingertip-radius-mm",
    "reach": "no approach lets both fingers get to the contacts: try a shorter --finger-length-mm, a thinner "
             "--finger-radius-mm or a larger --approach-tilt-deg",
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
