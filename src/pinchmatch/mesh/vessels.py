"""Hollow and thin-walled household objects with known geometry, in mm.

The shapes people hold most are not solid blocks: cups, mugs, bowls, plates
and tubes have thin walls and cavities. These are built as closed solids
(manifold3d booleans, or a revolved cross-section) with their axis along +Z,
standing on z = 0, for the tests and benchmarks of the hand model.
"""

from __future__ import annotations

import numpy as np
import trimesh


def _cylinder(radius, height, z0, sections):
    c = trimesh.creation.cylinder(radius=radius, height=height, sections=sections)
    c.apply_translation((0.0, 0.0, z0 + height / 2.0))
    return c


def _fine(mesh: trimesh.Trimesh, edge_mm: float) -> trimesh.Trimesh:
    """Split long triangles (cylinder sides) so that rays and samples see a fine mesh."""
    v, f = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge=edge_mm)
    out = trimesh.Trimesh(v, f)
    out.fix_normals()
    return out


def cup(outer_diameter_mm: float = 70.0, height_mm: float = 90.0, wall_mm: float = 2.0,
        bottom_mm: float = 2.0, *, sections: int = 128) -> trimesh.Trimesh:
    """A cup: closed bottom, open top, walls ``wall_mm`` thick."""
    r = outer_diameter_mm / 2.0
    outer = _cylinder(r, height_mm, 0.0, sections)
    inner = _cylinder(r - wall_mm, height_mm, bottom_mm, sections)
    return _fine(trimesh.boolean.difference([outer, inner], engine="manifold"), 6.0)


def mug(outer_diameter_mm: float = 70.0, height_mm: float = 90.0, wall_mm: float = 2.0, *,
        handle_major_mm: float = 24.0, handle_minor_mm: float = 5.0,
        sections: int = 128) -> trimesh.Trimesh:
    """The cup with a ring handle on the +X side, in the XZ plane, at mid-height."""
    r = outer_diameter_mm / 2.0
    body = _cylinder(r, height_mm, 0.0, sections)
    handle = trimesh.creation.torus(major_radius=handle_major_mm, minor_radius=handle_minor_mm,
                                    major_sections=96, minor_sections=24)
    handle.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2.0, (1.0, 0.0, 0.0)))
    handle.apply_translation((r + handle_major_mm - handle_minor_mm - 6.0, 0.0, height_mm / 2.0))
    solid = trimesh.boolean.union([body, handle], engine="manifold")
    inner = _cylinder(r - wall_mm, height_mm, wall_mm, sections)
    return _fine(trimesh.boolean.difference([solid, inner], engine="manifold"), 6.0)


def bowl(outer_diameter_mm: float = 160.0, wall_mm: float = 1.5, *,
         subdivisions: int = 5) -> trimesh.Trimesh:
    """A hemispherical shell, opening up, its rim at z = R and its bottom at z = 0."""
    r = outer_diameter_mm / 2.0
    outer = trimesh.creation.icosphere(subdivisions=subdivisions, radius=r)
    inner = trimesh.creation.icosphere(subdivisions=subdivisions, radius=r - wall_mm)
    lower = trimesh.creation.box(extents=(3 * r, 3 * r, 2 * r))
    lower.apply_translation((0.0, 0.0, -r))
    shell = trimesh.boolean.difference([outer, inner], engine="manifold")
    half = trimesh.boolean.intersection([shell, lower], engine="manifold")
    half.apply_translation((0.0, 0.0, r))
    return _fine(half, 6.0)


def scanned_bowl(diameter_mm: float = 161.0, height_mm: float = 55.0, wall_mm: float = 1.5, *,
                 edge_mm: float = 2.5, noise_mm: float = 0.05, seed: int = 0) -> trimesh.Trimesh:
    """A shallow bowl as a scan gives it: a spherical cap ``wall_mm`` thick with a rounded rim.

    The outer surface is the cap of the sphere through the bottom (z = 0) and the rim (the
    diameter at ``height_mm``); the inner one is ``wall_mm`` inside it; a half circle joins them
    at the rim. Triangles split to ``edge_mm`` and every vertex moved by Gaussian noise of
    ``noise_mm`` (seeded) stand for a scan's dense, slightly rough triangulation.
    """
    a, h = diameter_mm / 2.0, height_mm
    radius = (a * a + h * h) / (2.0 * h)
    theta = np.linspace(0.0, np.arcsin(a / radius), 80)
    outer = np.c_[radius * np.sin(theta), radius * (1.0 - np.cos(theta))]
    r_in = radius - wall_mm
    inner = np.c_[r_in * np.sin(theta), radius - r_in * np.cos(theta)][::-1]
    centre, half = (outer[-1] + inner[0]) / 2.0, wall_mm / 2.0
    start = np.arctan2(*(outer[-1] - centre)[::-1])
    turn = start + np.linspace(0.0, np.pi, 12)[1:-1]
    rim = centre + half * np.c_[np.cos(turn), np.sin(turn)]
    profile = np.vstack([outer, rim, inner])
    profile[[0, -1], 0] = 0.0
    mesh = trimesh.creation.revolve(profile, sections=256)
    v, f = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge=edge_mm)
    v = v + np.random.default_rng(seed).normal(0.0, noise_mm, v.shape)
    out = trimesh.Trimesh(v, f)
    out.fix_normals()
    return out


def plate(diameter_mm: float = 260.0, thickness_mm: float = 2.5, *, well_diameter_mm: float = 200.0,
          rim_height_mm: float = 15.0, sections: int = 256) -> trimesh.Trimesh:
    """A plate: a flat well and a raised, sloping rim, one sheet ``thickness_mm`` thick."""
    R, r_well, t = diameter_mm / 2.0, well_diameter_mm / 2.0, thickness_mm
    slope = np.array([R - r_well, rim_height_mm])
    normal = np.array([-slope[1], slope[0]]) / np.linalg.norm(slope)
    top_end = np.array([R, rim_height_mm]) + t * normal
    # the top of the well meets the top of the rim where z = t
    knee_x = top_end[0] - (top_end[1] - t) * slope[0] / slope[1]
    profile = np.array([[0.0, 0.0], [r_well, 0.0], [R, rim_height_mm], top_end, [knee_x, t],
                        [0.0, t]])
    mesh = trimesh.creation.revolve(profile, sections=sections)
    mesh.fix_normals()
    return _fine(mesh, 6.0)


def tube(outer_diameter_mm: float = 16.0, inner_diameter_mm: float = 12.0, length_mm: float = 100.0,
         *, sections: int = 96) -> trimesh.Trimesh:
    """A test tube: a narrow deep hole, closed at the bottom (1 mm thick), open at the top."""
    outer = _cylinder(outer_diameter_mm / 2.0, length_mm, 0.0, sections)
    inner = _cylinder(inner_diameter_mm / 2.0, length_mm, 1.0, sections)
    return _fine(trimesh.boolean.difference([outer, inner], engine="manifold"), 4.0)
