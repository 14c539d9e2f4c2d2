"""Centre of mass and principal axis of an object.

The principal axis is the first principal component of the mass
distribution: the eigenvector of the covariance C = ∫(x-c)(x-c)ᵀ dm with the
largest eigenvalue. Since the inertia tensor is I = tr(C)·Id - C, it is also
the axis of smallest moment of inertia.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import trimesh

from ..errors import ConfigError

log = logging.getLogger(__name__)

#: when the two largest variances differ by less than this fraction, the axis is ill-defined
AXIS_AMBIGUITY = 0.05


@dataclass(frozen=True)
class ObjectProperties:
    """Mass properties of one object (lengths in mm).

    com_mm : (3,) float64
        Centre of mass.
    principal_axis : (3,) unit float64
        First principal component, sign chosen so that it points with ``up``
        (or, perpendicular to up, with its largest component positive).
    axis_source : str
        ``"pca"``, ``"up"`` (variances within 5 %, the up direction is used) or ``"user"``.
    com_source : str
        ``"solid"``, ``"surface"`` (open mesh) or ``"user"``.
    variances_mm2 : (3,) float64
        Eigenvalues of the mass covariance, largest first (per unit mass).
    volume_mm3 : float or None
        Enclosed volume, None for an open surface.
    area_mm2 : float
        Surface area.
    bounds_mm : (2, 3) float64
        Axis-aligned bounding box [min, max].
    """

    com_mm: np.ndarray
    principal_axis: np.ndarray
    axis_source: str
    com_source: str
    variances_mm2: np.ndarray
    volume_mm3: float | None
    area_mm2: float
    bounds_mm: np.ndarray


def _surface_moments(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    """Centroid and covariance of the surface, treated as a uniform shell."""
    tri = mesh.triangles
    area = mesh.area_faces
    total = area.sum()
    centroid = (area[:, None] * tri.mean(axis=1)).sum(axis=0) / total
    rel = tri - centroid
    s = rel.sum(axis=1)
    # exact second moment of a triangle: A/12 (Σ vi viᵀ + s sᵀ)
    second = np.einsum("f,fki,fkj->ij", area, rel, rel) + np.einsum("f,fi,fj->ij", area, s, s)
    return centroid, second / (12.0 * total)


def _orient(axis: np.ndarray, up: np.ndarray) -> np.ndarray:
    axis = axis / np.linalg.norm(axis)
    along = float(axis @ up)
    if abs(along) > 1e-9:
        return axis if along > 0 else -axis
    return axis if axis[np.argmax(np.abs(axis))] > 0 else -axis


def parse_vector(text: str, *, option: str) -> np.ndarray:
    """Parse ``"X,Y,Z"`` into a (3,) float array, with a clear error."""
    parts = [p for p in str(text).replace(" ", "").split(",") if p != ""]
    try:
        values = np.array([float(p) for p in parts], dtype=np.float64)
    except ValueError:
        values = np.zeros(0)
    if values.shape != (3,) or not np.isfinite(values).all():
        raise ConfigError(f"{option}: expected three finite numbers X,Y,Z, got {text!r}")
    if np.abs(values).max() >= 1e6:
        raise ConfigError(f"{option}: {text!r} is more than a kilometre from the origin; give mm "
                          "in the file's frame")
    return values


def _three_finite(value) -> bool:
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return array.shape == (3,) and bool(np.isfinite(array).all())


def object_properties(
    mesh: trimesh.Trimesh,
    *,
    up: np.ndarray,
    watertight: bool,
    com_mm: np.ndarray | None = None,
    axis: np.ndarray | None = None,
) -> ObjectProperties:
    """Centre of mass and principal axis of ``mesh`` (mm).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The object, in mm.
    up : (3,) float64
        The object's up direction: the axis used when the principal axis is
        ill-defined (two largest variances within 5 %: a cube, a sphere, a disc).
    watertight : bool
        Whether the solid's mass properties can be used (else the surface's).
    com_mm, axis : (3,) float64, optional
        User overrides (a prop with a weight inside it).

    Returns
    -------
    ObjectProperties
        The centre of mass (mm), the principal axis and what they were computed from.

    Examples
    --------
    >>> from pinchmatch import load_mesh
    >>> loaded = load_mesh(can_obj, units="m")
    >>> props = object_properties(loaded.mesh, up=loaded.up, watertight=loaded.watertight)
    >>> props.com_mm.round(1).tolist(), props.principal_axis.round(3).tolist(), props.com_source
    ([0.0, 0.0, 33.0], [0.0, 0.0, 1.0], 'solid')
    """
    if watertight:
        centroid = np.asarray(mesh.center_mass, dtype=np.float64)
        inertia = np.asarray(mesh.moment_inertia, dtype=np.float64) / mesh.mass
        cov = 0.5 * np.trace(inertia) * np.eye(3) - inertia
        com_source = "solid"
        volume = float(mesh.volume)
    else:
        centroid, cov = _surface_moments(mesh)
        com_source = "surface"
        volume = None

    values, vectors = np.linalg.eigh(0.5 * (cov + cov.T))
    order = np.argsort(values)[::-1]
    values, vectors = values[order], vectors[:, order]

    for name, value in (("--com", com_mm), ("--axis", axis)):
        if value is not None and not _three_finite(value):
            raise ConfigError(f"{name}: {str(value)[:60]} must be three finite numbers X,Y,Z (mm, "
                              "the file's frame)"
                              + (", a non-zero vector" if name == "--axis" else ""))
    if axis is not None:
        norm = float(np.linalg.norm(axis))
        if not np.isfinite(norm) or norm < 1e-12:
            raise ConfigError("--axis: the axis must be a non-zero vector X,Y,Z")
        principal, axis_source = _orient(np.asarray(axis, float), up), "user"
    elif values[0] <= 0 or (values[0] - values[1]) < AXIS_AMBIGUITY * values[0]:
        principal, axis_source = np.asarray(up, float) / np.linalg.norm(up), "up"
    else:
        principal, axis_source = _orient(vectors[:, 0], up), "pca"

    if com_mm is not None:
        centroid, com_source = np.asarray(com_mm, dtype=np.float64), "user"

    return ObjectProperties(
        com_mm=centroid,
        principal_axis=principal,
        axis_source=axis_source,
        com_source=com_source,
        variances_mm2=values,
        volume_mm3=volume,
        area_mm2=float(mesh.area),
        bounds_mm=np.asarray(mesh.bounds, dtype=np.float64),
    )
