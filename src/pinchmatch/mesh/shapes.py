"""Analytic test shapes in several triangulations, with closed-form truth.

Used by the tests, the benchmarks and the built-in example. Every shape is
centred on the origin with its axis along +Z, lengths in mm. A ``truth``
function maps points on (or within a fraction of a mm of) the surface to the
exact outward normal, principal curvatures (1/m, convex positive) and the
direction of the largest one.

Triangulations:

- ``regular``: the usual structured mesh (icosphere, longitude-latitude grid);
- ``cad``: coarse, with long thin triangles, as CAD tools export;
- ``random``: an irregular triangulation of random surface points.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import trimesh
from scipy.spatial import ConvexHull, Delaunay


@dataclass(frozen=True)
class Truth:
    """Closed-form geometry at surface points.

    normal : (n, 3) unit outward normal
    kappa_max_per_m, kappa_min_per_m : (n,)
    dir_max : (n, 3) unit direction of kappa_max (NaN where umbilic)
    """

    normal: np.ndarray
    kappa_max_per_m: np.ndarray
    kappa_min_per_m: np.ndarray
    dir_max: np.ndarray


@dataclass(frozen=True)
class Shape:
    """An analytic solid, its mesh, and its truth.

    interior : callable (n, 3) -> (n,) bool: points far enough from edges
    (more than a patch radius) that the smooth truth applies to the whole patch.
    """

    name: str
    mesh: trimesh.Trimesh
    truth: Callable[[np.ndarray], Truth]
    interior: Callable[[np.ndarray, float], np.ndarray]
    com_mm: np.ndarray
    volume_mm3: float


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _hull_mesh(points: np.ndarray) -> trimesh.Trimesh:
    hull = ConvexHull(points)
    mesh = trimesh.Trimesh(points, hull.simplices, process=True)
    trimesh.repair.fix_normals(mesh)
    return mesh


def _periodic_delaunay(uv: np.ndarray) -> np.ndarray:
    """Triangulate points on the unit torus [0, 1)^2 (both directions periodic)."""
    n = len(uv)
    shifts = np.array([(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1)], float)
    tiled = (uv[None, :, :] + shifts[:, None, :]).reshape(-1, 2)
    tri = Delaunay(tiled).simplices
    centroid = tiled[tri].mean(axis=1)
    keep = ((centroid >= 0) & (centroid < 1)).all(axis=1)
    return tri[keep] % n


def _uniform_sphere_points(n, rng):
    return _unit(rng.normal(size=(n, 3)))


# --------------------------------------------------------------------- sphere
def sphere(radius_mm: float = 20.0, *, triangulation: str = "regular", faces: int = 20000,
           seed=0) -> Shape:
    rng = np.random.default_rng(seed)
    if triangulation == "regular":
        level = int(np.clip(np.round(np.log(faces / 20) / np.log(4)), 1, 8))
        mesh = trimesh.creation.icosphere(subdivisions=level, radius=radius_mm)
    elif triangulation == "cad":
        count = max(8, int(np.sqrt(faces / 8)))
        mesh = trimesh.creation.uv_sphere(radius=radius_mm, count=[count, 2 * count])
    elif triangulation == "random":
        mesh = _hull_mesh(radius_mm * _uniform_sphere_points(faces // 2 + 2, rng))
    else:
        raise ValueError(triangulation)

    def truth(p):
        n = _unit(p)
        k = np.full(len(p), 1000.0 / radius_mm)
        return Truth(n, k, k.copy(), np.full((len(p), 3), np.nan))

    return Shape(f"sphere_{triangulation}", mesh, truth, lambda p, r: np.ones(len(p), bool),
                 np.zeros(3), 4.0 / 3.0 * np.pi * radius_mm**3)


# ------------------------------------------------------------------- cylinder
def cylinder(radius_mm: float = 20.0, height_mm: float = 80.0, *, triangulation: str = "regular",
             faces: int = 20000, seed=0) -> Shape:
    rng = np.random.default_rng(seed)
    h2 = height_mm / 2.0
    if triangulation == "cad":
        mesh = trimesh.creation.cylinder(radius=radius_mm, height=height_mm,
                                         sections=max(16, faces // 4))
    elif triangulation == "regular":
        # square-ish quad grid on the side (split into triangles), fans on the caps
        sections = max(16, int(np.sqrt(faces * np.pi * radius_mm / height_mm)))
        rings = max(2, int(round(sections * height_mm / (2 * np.pi * radius_mm))))
        mesh = _cylinder_grid(radius_mm, height_mm, sections, rings)
    elif triangulation == "random":
        side_area = 2 * np.pi * radius_mm * height_mm
        cap_area = np.pi * radius_mm**2
        total = faces // 2
        n_side = int(total * side_area / (side_area + 2 * cap_area))
        n_cap = (total - n_side) // 2
        theta = rng.uniform(0, 2 * np.pi, n_side)
        side = np.column_stack([radius_mm * np.cos(theta), radius_mm * np.sin(theta),
                                rng.uniform(-h2, h2, n_side)])
        rim_t = np.linspace(0, 2 * np.pi, max(32, int(np.sqrt(total) * 2)), endpoint=False)
        rims = [np.column_stack([radius_mm * np.cos(rim_t), radius_mm * np.sin(rim_t),
                                 np.full(len(rim_t), z)]) for z in (-h2, h2)]
        caps = []
        for z in (-h2, h2):
            rr = radius_mm * np.sqrt(rng.uniform(0, 0.97, n_cap))
            tt = rng.uniform(0, 2 * np.pi, n_cap)
            caps.append(np.column_stack([rr * np.cos(tt), rr * np.sin(tt), np.full(n_cap, z)]))
        mesh = _hull_mesh(np.vstack([side, *rims, *caps]))
    else:
        raise ValueError(triangulation)

    def truth(p):
        radial = _unit(p * np.array([1.0, 1.0, 0.0]))
        around = np.cross(np.array([0.0, 0.0, 1.0]), radial)
        return Truth(radial, np.full(len(p), 1000.0 / radius_mm), np.zeros(len(p)), around)

    def interior(p, r):
        rho = np.linalg.norm(p[:, :2], axis=1)
        return (np.abs(p[:, 2]) < h2 - r) & (rho > radius_mm * 0.99)

    return Shape(f"cylinder_{triangulation}", mesh, truth, interior, np.zeros(3),
                 np.pi * radius_mm**2 * height_mm)


def _cylinder_grid(radius, height, sections, rings):
    t = 2 * np.pi * np.arange(sections) / sections
    z = np.linspace(-height / 2, height / 2, rings + 1)
    side = np.column_stack([np.tile(radius * np.cos(t), rings + 1),
                            np.tile(radius * np.sin(t), rings + 1), np.repeat(z, sections)])
    verts = np.vstack([side, [[0, 0, -height / 2], [0, 0, height / 2]]])
    i, j = np.meshgrid(np.arange(sections), np.arange(rings), indexing="ij")
    a = (j * sections + i).ravel()
    b = (j * sections + (i + 1) % sections).ravel()
    c = ((j + 1) * sections + (i + 1) % sections).ravel()
    d = ((j + 1) * sections + i).ravel()
    ring = np.arange(sections)
    bottom, top = len(side), len(side) + 1
    tris = np.vstack([
        np.column_stack([a, b, c]), np.column_stack([a, c, d]),
        np.column_stack([np.full(sections, bottom), (ring + 1) % sections, ring]),
        np.column_stack([np.full(sections, top), rings * sections + ring,
                         rings * sections + (ring + 1) % sections]),
    ])
    mesh = trimesh.Trimesh(verts, tris, process=True)
    trimesh.repair.fix_normals(mesh)
    return mesh


# ---------------------------------------------------------------------- torus
def torus(major_mm: float = 30.0, minor_mm: float = 12.0, *, triangulation: str = "regular",
          faces: int = 20000, seed=0) -> Shape:
    rng = np.random.default_rng(seed)
    if triangulation in ("regular", "cad"):
        ratio = major_mm / minor_mm
        if triangulation == "cad":
            ratio *= 4.0  # long thin triangles around the tube axis
        nv = max(6, int(np.sqrt(faces / (2 * ratio))))
        nu = max(8, int(faces / (2 * nv)))
        u, v = np.meshgrid(np.arange(nu) / nu, np.arange(nv) / nv, indexing="ij")
        uv = np.column_stack([u.ravel(), v.ravel()])
        i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
        a = (i * nv + j).ravel()
        b = (((i + 1) % nu) * nv + j).ravel()
        c = (((i + 1) % nu) * nv + (j + 1) % nv).ravel()
        d = (i * nv + (j + 1) % nv).ravel()
        tri = np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    elif triangulation == "random":
        # area-uniform points: accept v with probability proportional to (R + r cos v)
        n = faces // 2
        u = rng.random(4 * n)
        v = rng.random(4 * n)
        accept = rng.random(4 * n) < (major_mm + minor_mm
                                      * np.cos(2 * np.pi * v)) / (major_mm + minor_mm)
        uv = np.column_stack([u[accept], v[accept]])[:n]
        tri = _periodic_delaunay(uv)
    else:
        raise ValueError(triangulation)
    phi, th = 2 * np.pi * uv[:, 0], 2 * np.pi * uv[:, 1]
    ring = major_mm + minor_mm * np.cos(th)
    verts = np.column_stack([ring * np.cos(phi), ring * np.sin(phi), minor_mm * np.sin(th)])
    mesh = trimesh.Trimesh(verts, tri, process=True)
    trimesh.repair.fix_normals(mesh)

    def truth(p):
        rho = np.linalg.norm(p[:, :2], axis=1)
        radial = p * np.array([1.0, 1.0, 0.0]) / rho[:, None]
        centre = major_mm * radial
        normal = _unit(p - centre)
        cos_v = np.einsum("ij,ij->i", normal, radial)
        k_tube = np.full(len(p), 1000.0 / minor_mm)
        k_ring = 1000.0 * cos_v / (major_mm + minor_mm * cos_v)
        around = np.cross(np.array([0.0, 0.0, 1.0]), radial)
        meridian = np.cross(normal, around)
        return Truth(normal, np.maximum(k_tube, k_ring), np.minimum(k_tube, k_ring), meridian)

    return Shape(f"torus_{triangulation}", mesh, truth, lambda p, r: np.ones(len(p), bool),
                 np.zeros(3), 2 * np.pi**2 * major_mm * minor_mm**2)


# ------------------------------------------------------------------ ellipsoid
def ellipsoid(axes_mm=(40.0, 25.0, 18.0), *, triangulation: str = "regular", faces: int = 20000,
              seed=0) -> Shape:
    rng = np.random.default_rng(seed)
    axes = np.asarray(axes_mm, float)
    if triangulation == "regular":
        level = int(np.clip(np.round(np.log(faces / 20) / np.log(4)), 1, 8))
        unit = trimesh.creation.icosphere(subdivisions=level).vertices
        faces_ = trimesh.creation.icosphere(subdivisions=level).faces
        mesh = trimesh.Trimesh(unit * axes, faces_, process=True)
    elif triangulation == "cad":
        count = max(8, int(np.sqrt(faces / 8)))
        base = trimesh.creation.uv_sphere(radius=1.0, count=[count, 2 * count])
        mesh = trimesh.Trimesh(base.vertices * axes, base.faces, process=True)
    elif triangulation == "random":
        # near area-uniform: oversample directions, thin by the local area factor
        d = _uniform_sphere_points(8 * faces, rng)
        p = d * axes
        grad = p / axes**2
        factor = np.linalg.norm(grad, axis=1) * np.prod(axes)
        keep = rng.random(len(d)) < factor / factor.max()
        mesh = _hull_mesh(p[keep][: faces // 2 + 2])
    else:
        raise ValueError(triangulation)
    trimesh.repair.fix_normals(mesh)

    def truth(p):
        q = p / np.sqrt((p**2 / axes**2).sum(axis=1))[:, None]
        grad = 2.0 * q / axes**2
        g = np.linalg.norm(grad, axis=1)
        normal = grad / g[:, None]
        hess = np.diag(2.0 / axes**2)
        t1 = _unit(np.cross(normal,
                            np.where(np.abs(normal[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])))
        t2 = np.cross(normal, t1)
        T = np.stack([t1, t2], axis=-1)  # (n, 3, 2)
        S = np.einsum("nai,ab,nbj->nij", T, hess, T) / g[:, None, None]
        vals, vecs = np.linalg.eigh(S)
        dmax = np.einsum("nai,ni->na", T, vecs[:, :, 1])
        return Truth(normal, 1000.0 * vals[:, 1], 1000.0 * vals[:, 0], dmax)

    return Shape(f"ellipsoid_{triangulation}", mesh, truth, lambda p, r: np.ones(len(p), bool),
                 np.zeros(3), 4.0 / 3.0 * np.pi * np.prod(axes))


# ------------------------------------------------------------------------ box
def box(extents_mm=(60.0, 40.0, 20.0), *, subdivide_mm: float | None = None) -> Shape:
    mesh = trimesh.creation.box(extents=extents_mm)
    if subdivide_mm:
        mesh = mesh.subdivide_to_size(max_edge=subdivide_mm)
    half = np.asarray(extents_mm, float) / 2.0

    def truth(p):
        rel = np.abs(p) / half
        axis = np.argmax(rel, axis=1)
        normal = np.zeros_like(p)
        normal[np.arange(len(p)), axis] = np.sign(p[np.arange(len(p)), axis])
        z = np.zeros(len(p))
        return Truth(normal, z, z.copy(), np.full((len(p), 3), np.nan))

    def interior(p, r):
        near = np.sort(half - np.abs(p), axis=1)
        return near[:, 1] > r

    return Shape("box", mesh, truth, interior, np.zeros(3), float(np.prod(extents_mm)))


# ------------------------------------------------------ the paper's tangible
def stacked_prop(order=("cylinder", "cube", "cone"), *, sections: int = 96) -> trimesh.Trimesh:
    """The method's study object: three coaxial 40 mm parts stacked along +Z.

    ``cylinder`` Ø40, ``cube`` 40, ``cone`` a frustum Ø60 -> Ø20 (Ø40 at
    mid-height, widening downwards). Parts are unioned into one watertight
    solid; the bottom is at z = 0.
    """
    parts = []
    for level, name in enumerate(order):
        z0 = 40.0 * level
        if name == "cylinder":
            part = trimesh.creation.cylinder(radius=20.0, height=40.0, sections=sections)
        elif name == "cube":
            part = trimesh.creation.box(extents=(40.0, 40.0, 40.0))
        elif name == "cone":
            part = _frustum(30.0, 10.0, 40.0, sections)
        else:
            raise ValueError(f"unknown part {name!r}")
        part.apply_translation((0.0, 0.0, z0 + 20.0))
        parts.append(part)
    return trimesh.boolean.union(parts, engine="manifold")


def _frustum(r_bottom, r_top, height, sections):
    t = np.linspace(0, 2 * np.pi, sections, endpoint=False)
    bottom = np.column_stack([r_bottom * np.cos(t), r_bottom * np.sin(t),
                              np.full(sections, -height / 2)])
    top = np.column_stack([r_top * np.cos(t), r_top * np.sin(t), np.full(sections, height / 2)])
    return _hull_mesh(np.vstack([bottom, top]))
