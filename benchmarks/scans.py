"""Synthetic phone scans of real meshes for the tests and the import benchmark: noise along the
normal, the bottom left open where the object stood, another unit, another up, many faces, or a
point cloud; with the map from the clean mesh's frame to the scan file's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from pinchmatch.mesh.frames import UNITS_MM, UP_VECTORS, rotations_between


#: a scan's edges (mm, 9 in 10): a phone scan of 10^5 faces or more is at least this dense
DENSE_MM = 1.0


def cup(wall_mm: float, *, base_mm: float | None = None, radius_mm: float = 40.0,
        height_mm: float = 90.0) -> trimesh.Trimesh:
    """An open cup standing on z = 0 (mm): a cylinder with one of ``wall_mm`` less radius taken
    out from above, down to a base ``base_mm`` thick (default ``wall_mm``): a thin-walled object
    whose every width is known."""
    outer = trimesh.creation.cylinder(radius=radius_mm, height=height_mm, sections=96)
    inner = trimesh.creation.cylinder(radius=radius_mm - wall_mm, height=height_mm, sections=96)
    inner.apply_translation([0.0, 0.0, wall_mm if base_mm is None else base_mm])
    out = outer.difference(inner, engine="manifold")
    out.apply_translation([0.0, 0.0, -out.bounds[0, 2]])
    return out


def clean_mesh(path) -> trimesh.Trimesh:
    """A real mesh (mm, +Z up) as the reference: its pieces merged, its windings made outward."""
    mesh = trimesh.load(path, force="mesh", process=True)
    trimesh.repair.fix_normals(mesh)
    return mesh


def scan_of(clean: trimesh.Trimesh, path: Path, *, rng, noise_mm: float = 0.0,
            open_bottom_mm: float | None = None, units: str = "mm", up: str = "z",
            faces: int | None = None, cloud_points: int | None = None) -> np.ndarray:
    """Write a scan of ``clean`` (mm, +Z up) to ``path`` (PLY or OBJ; a point cloud as PLY) and
    return the (4, 4) map from the clean frame to the file's coordinates.

    ``noise_mm``: Gaussian noise along the normal, σ; ``open_bottom_mm``: the underside's faces
    (facing down) within this height of the lowest point are missing (a cloud: every point there
    but those facing up, seen from above: a cup's inside floor);
    ``units`` and ``up``: how the file holds it; ``faces``: split until it has at least this many
    (and always until nine edges in ten are ``DENSE_MM`` at most, as a scan's); ``cloud_points``: a
    point cloud of this many points instead of a mesh.
    """
    mesh = clean.copy()
    while (faces and len(mesh.faces) < faces) or np.quantile(mesh.edges_unique_length,
                                                              0.9) > DENSE_MM:
        mesh = mesh.subdivide()
    low = float(mesh.vertices[:, 2].min())
    if cloud_points:
        points, index = trimesh.sample.sample_surface_even(mesh, cloud_points, seed=rng)
        normals = mesh.face_normals[index]
        # near the table only what faces up is seen (a cup's inside floor, from above)
        keep = (points[:, 2] >= low + (open_bottom_mm or 0.0)) | (normals[:, 2] > 0.5)
        points = points[keep] + normals[keep] * rng.normal(0, noise_mm, (keep.sum(), 1))
        vertices, triangles = points, None
    else:
        vertices = mesh.vertices + mesh.vertex_normals * rng.normal(0, noise_mm,
                                                                   (len(mesh.vertices), 1))
        triangles = mesh.faces
        if open_bottom_mm is not None:  # the underside: faces facing down near the lowest point
            under = (mesh.face_normals[:, 2] < -0.5) & (
                mesh.triangles_center[:, 2] < low + open_bottom_mm)
            triangles = triangles[~under]
    R = rotations_between(np.array([UP_VECTORS[up]], float), np.array([[0.0, 0.0, 1.0]]))[0]
    to_file = np.eye(4)
    to_file[:3, :3] = R.T / UNITS_MM[units]
    out = vertices @ to_file[:3, :3].T
    if triangles is None:
        trimesh.PointCloud(out).export(path)
    else:
        trimesh.Trimesh(out, triangles, process=False).export(path)
    return to_file
