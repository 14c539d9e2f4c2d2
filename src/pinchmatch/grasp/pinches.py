"""Feasible thumb-index pinches (Step #1 of the method).

A pinch is two contacts p1, p2 on the surface with unit outward normals
n1, n2. It is feasible when every rule holds:

``surface``
    (user-given contacts only) each point is within ``snap_tolerance_mm``
    of the surface; it is then snapped onto it.
``region``
    each contact lies in no ``exclude`` region of the object and, where it has ``only`` regions,
    in one of them (:mod:`pinchmatch.mesh.regions`; from a manifest).
``width``
    ``min_width_mm <= |p1p2| <= max_width_mm``.
``antipodal``
    p1→p2 is within ``friction_cone_deg`` of -n1, and p2→p1 within the same of -n2.
``clearance``
    a fingertip sphere of ``fingertip_radius_mm`` touching the surface at
    p_i from outside does not cut the object (no pinch in a slot narrower
    than a finger), nor what the object stands on (its support plane,
    :mod:`pinchmatch.mesh.support`). The sphere is centred at p_i + r·n_i, tangent at p_i.
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
sampled candidates (:mod:`sampling`, with triangle normals) and by the final check (with the
normals of the fitted contact patches, :mod:`curvature`), so a faceted
cylinder behaves like the cylinder it stands for.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .curvature import PatchGeometry, patch_geometry
from ..errors import ConfigError
from ..config import (CLEARANCE_TOLERANCE_MM, FINGERTIP_RADIUS_RANGE_MM, MAX_COUNT,  # noqa: F401
                      MAX_WIDTH_MM, PREFILTER_MARGIN_DEG, PinchSettings)
from .hand import Reach, hand_of, reach
from ..mesh.surface import SurfaceContext

RULES = ("surface", "region", "width", "antipodal", "clearance", "reach", "patch")

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

    #: the rules of ``broken``'s columns
    rules: ClassVar[tuple] = RULES

    def broken_rules(self, i: int) -> list[str]:
        return [rule for rule, bad in zip(self.rules, self.broken[i]) if bad]

    def subset(self, keep: np.ndarray) -> "Pinches":
        return type(self)(**{f: getattr(self, f)[keep] for f in ARRAY_FIELDS},
                          rejected=dict(self.rejected))


#: the per-pinch arrays of :class:`Pinches`, in declaration order
ARRAY_FIELDS = tuple(f.name for f in dataclasses.fields(Pinches) if f.name != "rejected")


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between unit vectors, rowwise, in degrees."""
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0)))


def _line(points):
    seg = points[:, 1] - points[:, 0]
    width = np.linalg.norm(seg, axis=1)
    return width, seg / np.maximum(width, 1e-300)[:, None]


def closing_directions(points: np.ndarray) -> np.ndarray:
    """(..., F, 3) unit directions the fingertips close along onto grasps' contacts (..., F, 3): the
    first (p1, the thumb) towards the others' middle, each other towards the first (a pinch's: along
    its line, both ways)."""
    toward = np.concatenate([points[..., 1:, :].mean(axis=-2, keepdims=True) - points[..., :1, :],
                             points[..., :1, :] - points[..., 1:, :]], axis=-2)
    return toward / np.maximum(np.linalg.norm(toward, axis=-1, keepdims=True), 1e-300)


# -- the rules, each written once ------------------------------------------------------------

def region_broken(context: SurfaceContext, points: np.ndarray) -> np.ndarray:
    if not context.regions:
        return np.zeros(len(points), dtype=bool)
    return ~context.regions.allows(points).all(axis=1)


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
    least = r - CLEARANCE_TOLERANCE_MM
    clear = context.min_distance_to_samples(centres, beyond_mm=least) >= least
    if context.support is not None:  # and above what the object stands on
        clear &= context.support.heights(centres) >= least
    return ~clear.reshape(len(points), points.shape[1]).all(axis=1)


def reach_rule(context: SurfaceContext, points: np.ndarray, normals: np.ndarray,
               settings: PinchSettings, approach: np.ndarray | None = None,
               thorough: bool = True) -> Reach:
    return reach(context, points, normals, hand_of(settings), approach=approach, thorough=thorough)


def cheap_broken(context, points, normals, settings, cone_deg):
    """(n, len(RULES)) bool of the rules that need no patches and no approach search."""
    broken = np.zeros((len(points), len(RULES)), dtype=bool)
    broken[:, RULES.index("region")] = region_broken(context, points)
    broken[:, RULES.index("width")] = width_broken(points, settings)
    broken[:, RULES.index("antipodal")] = antipodal_broken(points, normals, cone_deg)
    broken[:, RULES.index("clearance")] = clearance_broken(context, points, normals, settings)
    return broken


def rule_table(context, points, normals, valid_patch, settings, surface_ok=None, approach=None,
               thorough=True, with_reach=True):
    """Which rules each pinch breaks, (n, len(RULES)) bool, and its reach (``thorough``: see
    :func:`pinchmatch.grasp.hand.reach`; without ``with_reach``, reach is not checked: see
    :func:`check_reach`)."""
    broken = cheap_broken(context, points, normals, settings, settings.friction_cone_deg)
    if surface_ok is not None:
        broken[:, RULES.index("surface")] = ~surface_ok
    if with_reach:
        found = reach_rule(context, points, normals, settings, approach, thorough)
    else:
        found = Reach(np.ones(len(points), dtype=bool), np.full((len(points), 3), np.nan),
                      np.full(len(points), np.nan))
    broken[:, RULES.index("reach")] = ~found.ok
    broken[:, RULES.index("patch")] = ~valid_patch.reshape(-1, 2).all(axis=1)
    return broken, found


def check_patch_radius(context: SurfaceContext, settings: PinchSettings) -> None:
    """The patch radius is one setting: the surface context was sampled for it (about 120 samples
    per patch) and the fits use it. Raise ConfigError when an object was analysed for another."""
    if not np.isclose(context.patch_radius_mm, settings.patch_radius_mm, rtol=1e-9, atol=0.0):
        raise ConfigError("--patch-radius-mm: the object was analysed for "
                          f"{context.patch_radius_mm:g} mm patches "
                          f"but the pinch settings ask for {settings.patch_radius_mm:g} mm; "
                          "analyse it with patch_radius_mm equal to PinchSettings.patch_radius_mm")


def patches(context, points, face_normals, settings) -> PatchGeometry:
    return patch_geometry(
        context, points.reshape(-1, 3), face_normals.reshape(-1, 3),
        patch_radius_mm=settings.patch_radius_mm
    )


def assemble(points, points_faces, geom: PatchGeometry, broken, found: Reach, rejected, snap=None,
             kind: type | None = None) -> Pinches:
    """The grasps (a :class:`Pinches`, or ``kind``) of n checked candidates, points (n, F, 3)."""
    n, f = len(broken), points.shape[1]
    return (kind or Pinches)(
        points=points.reshape(n, f, 3),
        normals=geom.normal.reshape(n, f, 3),
        face_index=points_faces.reshape(n, f),
        kappa_max_per_m=geom.kappa_max_per_m.reshape(n, f),
        kappa_min_per_m=geom.kappa_min_per_m.reshape(n, f),
        dir_max=geom.dir_max.reshape(n, f, 3),
        feasible=~broken.any(axis=1),
        broken=broken,
        snap_distance_mm=np.zeros((n, f)) if snap is None else snap.reshape(n, f),
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
    approach: np.ndarray | None = None,
    thorough: bool = True,
    with_reach: bool = True,
) -> Pinches:
    """Snap user-given contacts onto the surface and check every rule.

    Parameters
    ----------
    context : SurfaceContext
        The object's surface.
    p1_mm, p2_mm : (n, 3) float64
        Candidate contacts, near the surface.
    settings : PinchSettings
        The rules a pinch must pass and how far a contact may be snapped.
    faces : (n, 2) int, optional
        The triangles the contacts lie on, when they are known to be on the surface (ray hits):
        they are then taken as they are, with no closest-point search.
    approach : (n, 3) float, optional
        A hand direction to try first for each pinch (a nearby pinch's): where it clears, the
        reach search stops there (:func:`pinchmatch.grasp.hand.reach`).
    thorough : bool
        False: the reach search tries its quick directions only, and a pinch it does not reach
        that way counts as unreachable (never the other way round).
    with_reach : bool
        False: every rule but ``reach`` is checked, and ``approach`` is left NaN; the pinches are
        not feasible until :func:`check_reach` has checked it (for candidates of which only a few
        will be kept).

    Returns
    -------
    Pinches
        All n candidates, in order, with ``feasible``, ``broken`` and ``approach`` set.

    Examples
    --------
    >>> from pinchmatch import analyze_object
    >>> obj = analyze_object(box_stl)  # 60 x 40 x 20 mm, centred on the origin
    >>> top, bottom, side = [0.0, 0.0, 10.0], [0.0, 0.0, -10.0], [30.0, 0.0, 0.0]
    >>> pinches = check_pinches(obj.context, np.array([top, top]), np.array([bottom, side]))
    >>> pinches.feasible.tolist(), pinches.broken_rules(1)
    ([True, False], ['antipodal'])
    """
    check_patch_radius(context, settings)
    p1_mm = np.asarray(p1_mm, dtype=np.float64).reshape(-1, 3)
    p2_mm = np.asarray(p2_mm, dtype=np.float64).reshape(-1, 3)
    n = len(p1_mm)
    raw = np.stack([p1_mm, p2_mm], axis=1).reshape(-1, 3)
    if faces is None:
        closest, distance, face = context.closest_points(raw)
    else:
        closest, distance, face = raw, np.zeros(len(raw)), np.asarray(faces,
                                                                      dtype=np.int64).reshape(-1)
    surface_ok = (distance <= settings.snap_tolerance_mm).reshape(n, 2).all(axis=1)
    geom = patches(context, closest, context.face_normals[face], settings)
    points = closest.reshape(n, 2, 3)
    normals = geom.normal.reshape(n, 2, 3)
    broken, found = rule_table(context, points, normals, geom.valid, settings, surface_ok, approach,
                               thorough, with_reach)
    return assemble(points, face, geom, broken, found, {}, distance)


def check_reach(context: SurfaceContext, pinches: Pinches, *,
                settings: PinchSettings = PinchSettings(), approach: np.ndarray | None = None,
                thorough: bool = True, rows: np.ndarray | None = None) -> Pinches:
    """``pinches`` (checked without reach: :func:`check_pinches`) with the reach rule checked too:
    ``feasible``, ``broken``, ``approach`` and ``approach_clearance_mm`` as :func:`check_pinches`
    would have given them in one go. With ``rows``, only those pinches are checked (``approach``,
    where given, one per row); the others keep what they have."""
    rows = np.arange(len(pinches)) if rows is None else np.asarray(rows, dtype=np.int64)
    found = reach_rule(context, pinches.points[rows], pinches.normals[rows], settings, approach,
                       thorough)
    broken = pinches.broken.copy()
    broken[rows, pinches.rules.index("reach")] = ~found.ok
    out_approach, clearance = pinches.approach.copy(), pinches.approach_clearance_mm.copy()
    out_approach[rows], clearance[rows] = found.approach, found.clearance_mm
    return dataclasses.replace(pinches, broken=broken, feasible=~broken.any(axis=1),
                               approach=out_approach, approach_clearance_mm=clearance)


def concat_pinches(parts: list[Pinches], rejected: dict | None = None) -> Pinches:
    """The pinches of ``parts`` in order; ``rejected`` from the last part unless given."""
    arrays = {f: np.concatenate([getattr(p, f) for p in parts]) for f in ARRAY_FIELDS}
    return type(parts[-1])(**arrays,
                           rejected=dict(parts[-1].rejected if rejected is None else rejected))
