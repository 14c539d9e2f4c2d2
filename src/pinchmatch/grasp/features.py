"""The seven haptic features of a pinch (Step #2 of the method).

For the midpoint m, centre of mass c, unit principal axis a and unit pinch
direction u = (p2 - p1) / |p2 - p1|:

- ``width_mm``          w = |p1p2|
- ``com_distance_mm``   d = |(m - c)·a|
- ``tilt_deg``          φ = angle between u and the plane orthogonal to a, 0-90

and per patch (at p1, at p2):

- ``normal_angle_deg``           ψ = angle between the pinch line and the patch normal, 0-90
- ``curvature_axis_angle_deg``   ρ = angle between the κmax direction and a projected on
                                 the tangent plane, 0-90; NaN (``null`` in JSON) where it is
                                 undefined: an umbilic patch (κmax - κmin < ``UMBILIC_PER_M``)
                                 or a within ``AXIS_NORMAL_DEG`` of the normal
- ``kappa_max_per_m``, ``kappa_min_per_m``

and, for the ``mass`` criterion (beyond the paper), the offset o = c - m of
the centre of mass from the pinch midpoint, split in the pinch's own frame:

- ``mass_along_mm``  (n, 2) o·u seen from each finger: at p1 along u, at p2 along -u
- ``mass_perp_mm``   (n,)  |o - (o·u)u|, the lever arm about the pinch line

All features are invariant under rigid motions of the object (tested).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .pinches import Pinches
from .tripod_rules import Tripods, contact_plane_normals
from ..mesh.properties import ObjectProperties

#: below this anisotropy (1/m) the κmax direction is undefined: the curvature
#: discrimination threshold of 2 cm stimuli (about 2 m⁻¹, perception.md)
UMBILIC_PER_M = 2.0
#: an axis within this angle of the normal has no meaningful tangent projection
AXIS_NORMAL_DEG = 5.0


@dataclass(frozen=True)
class PinchFeatures:
    """Features of n pinches.

    width_mm, com_distance_mm, tilt_deg : (n,) float64
    normal_angle_deg, curvature_axis_angle_deg : (n, 2) float64, NaN where undefined
    kappa_max_per_m, kappa_min_per_m : (n, 2) float64
    mass_along_mm : (n, 2) float64;  mass_perp_mm : (n,) float64
    """

    width_mm: np.ndarray
    com_distance_mm: np.ndarray
    tilt_deg: np.ndarray
    normal_angle_deg: np.ndarray
    curvature_axis_angle_deg: np.ndarray
    kappa_max_per_m: np.ndarray
    kappa_min_per_m: np.ndarray
    mass_along_mm: np.ndarray
    mass_perp_mm: np.ndarray


def _acute_deg(cosine: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.abs(cosine), 0.0, 1.0)))


def _axis_angles(grasps: Pinches, a: np.ndarray) -> np.ndarray:
    """(n, F) ρ per contact: the angle between its κmax direction and the axis ``a`` projected on
    its tangent plane, 0-90; NaN where undefined (module notes)."""
    normals = grasps.normals
    a_t = a[None, None, :] - (normals @ a)[..., None] * normals
    a_t_norm = np.linalg.norm(a_t, axis=-1)
    rho = _acute_deg(np.einsum("nkd,nkd->nk", grasps.dir_max, a_t) / np.maximum(a_t_norm, 1e-300))
    undefined = (grasps.kappa_max_per_m - grasps.kappa_min_per_m < UMBILIC_PER_M) | (
        a_t_norm < np.sin(np.radians(AXIS_NORMAL_DEG))
    )
    return np.where(undefined, np.nan, rho)


def pinch_features(pinches: Pinches, props: ObjectProperties) -> PinchFeatures:
    """The seven features of every pinch, from its contacts and patches.

    Parameters
    ----------
    pinches : Pinches
        The pinches (or tripods) and their patches.
    props : ObjectProperties
        The object's centre of mass and principal axis.

    Returns
    -------
    PinchFeatures
        Per pinch its width (mm), distance from the centre of mass along the axis (mm), tilt (deg)
        and its fingertip patches' orientations and curvatures.

    Examples
    --------
    >>> from pinchmatch import PinchSettings, analyze_object, sample_pinches
    >>> obj = analyze_object(box_stl)  # 60 x 40 x 20 mm: a pinch spans 20, 40, 60 mm or a diagonal
    >>> pinches = sample_pinches(obj.context, settings=PinchSettings(count=50, seed=0))
    >>> features = pinch_features(pinches, obj.props)
    >>> bool(features.width_mm.min() >= 20.0 - 1e-6), bool(features.width_mm.max() <= 100.0)
    (True, True)
    """
    p1, p2 = pinches.points[:, 0], pinches.points[:, 1]
    seg = p2 - p1
    width = np.linalg.norm(seg, axis=1)
    u = seg / np.maximum(width, 1e-300)[:, None]
    a = props.principal_axis / np.linalg.norm(props.principal_axis)
    mid = 0.5 * (p1 + p2)
    com_distance = np.abs((mid - props.com_mm) @ a)
    tilt = np.degrees(np.arcsin(np.clip(np.abs(u @ a), 0.0, 1.0)))

    normals = pinches.normals  # (n, 2, 3)
    psi = _acute_deg(np.einsum("nkd,nd->nk", normals, u))
    rho = _axis_angles(pinches, a)

    offset = props.com_mm - mid
    along = np.einsum("nd,nd->n", offset, u)
    perp = np.linalg.norm(offset - along[:, None] * u, axis=1)

    return PinchFeatures(
        width_mm=width,
        com_distance_mm=com_distance,
        tilt_deg=tilt,
        normal_angle_deg=psi,
        curvature_axis_angle_deg=rho,
        kappa_max_per_m=pinches.kappa_max_per_m.copy(),
        kappa_min_per_m=pinches.kappa_min_per_m.copy(),
        mass_along_mm=np.stack([along, -along], axis=-1),
        mass_perp_mm=perp,
    )


@dataclass(frozen=True)
class TripodFeatures(PinchFeatures):
    """Features of n tripods (thumb, index, middle), the per-contact arrays (n, 3).

    ``width_mm`` is the aperture: from the thumb's contact to the middle of the two fingers'.
    ``com_distance_mm`` is measured from the contacts' centroid g along the principal axis;
    ``tilt_deg`` is the angle between the plane of the contacts and the plane orthogonal to the axis
    (0-90); ``normal_angle_deg`` is, per contact, the angle between its normal and the line to the
    other side (the thumb's to the fingers' middle, each finger's to the thumb), 0-90.
    ``spacing_mm`` (n,) is the distance between the two fingers' contacts, and ``lever_arm_mm`` (n,)
    the centre of mass's distance from g: the lever of the torque the weight pulls with about the
    fingertips, its largest over the orientations the object is held in. ``mass_along_mm`` (n, 3)
    holds the lever arm for each contact and ``mass_perp_mm`` (n,) is 0: the only part of the offset
    that no turn of the object changes, so that the search's separable bound holds whatever the
    registration.
    """

    spacing_mm: np.ndarray = None
    lever_arm_mm: np.ndarray = None


def tripod_shape(points: np.ndarray, normals: np.ndarray, props: ObjectProperties) -> dict:
    """The features of tripods that need no patch curvature, from contacts and normals (n, 3, 3):
    ``width_mm`` (the aperture), ``com_distance_mm``, ``tilt_deg``, ``normal_angle_deg`` (n, 3),
    ``spacing_mm`` and ``lever_arm_mm`` (:class:`TripodFeatures`)."""
    a = props.principal_axis / np.linalg.norm(props.principal_axis)
    middle = points[:, 1:].mean(axis=1)
    centroid = points.mean(axis=1)
    towards = np.stack([middle - points[:, 0], points[:, 0] - points[:, 1],
                        points[:, 0] - points[:, 2]], axis=1)
    towards /= np.maximum(np.linalg.norm(towards, axis=2, keepdims=True), 1e-300)
    return {"width_mm": np.linalg.norm(middle - points[:, 0], axis=1),
            "com_distance_mm": np.abs((centroid - props.com_mm) @ a),
            "tilt_deg": _acute_deg(contact_plane_normals(points, normals) @ a),
            "normal_angle_deg": _acute_deg(np.einsum("nkd,nkd->nk", normals, towards)),
            "spacing_mm": np.linalg.norm(points[:, 2] - points[:, 1], axis=1),
            "lever_arm_mm": np.linalg.norm(props.com_mm - centroid, axis=1)}


def tripod_features(tripods: Tripods, props: ObjectProperties) -> TripodFeatures:
    """The features of every tripod (:class:`TripodFeatures`), from its contacts and patches."""
    shape = tripod_shape(tripods.points, tripods.normals, props)
    a = props.principal_axis / np.linalg.norm(props.principal_axis)
    lever = shape["lever_arm_mm"]
    return TripodFeatures(
        **shape,
        curvature_axis_angle_deg=_axis_angles(tripods, a),
        kappa_max_per_m=tripods.kappa_max_per_m.copy(),
        kappa_min_per_m=tripods.kappa_min_per_m.copy(),
        mass_along_mm=np.repeat(lever[:, None], 3, axis=1),
        mass_perp_mm=np.zeros(len(lever)),
    )


def grasp_features(grasps: Pinches, props: ObjectProperties) -> PinchFeatures:
    """The features of pinches or of tripods, as their kind has them."""
    return tripod_features(grasps, props) if isinstance(grasps, Tripods) else pinch_features(grasps,
                                                                                             props)
