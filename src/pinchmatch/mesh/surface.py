"""Per-mesh context: everything expensive about a surface, built once.

A :class:`SurfaceContext` holds the mesh, a dense area-uniform sample of its
surface with a KD-tree over it (used for contact patches and fingertip
clearance), and a ray engine (Embree through ``embreex`` when installed,
trimesh's pure-numpy engine otherwise).

The dense sample is what makes curvature independent of triangulation: a
patch is the set of sample points within the patch radius, and samples are
spread by area, so a patch looks the same whether it was cut from long thin
CAD triangles, a fine scan or a random triangulation.
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from ..cores import query_tree
from .distance_field import DistanceField
from .regions import ContactRegions
from .support import SupportPlane

log = logging.getLogger(__name__)

#: samples per patch disc of radius r on a flat surface (sets the sample density)
SAMPLES_PER_PATCH = 120
#: at most this many samples per mesh (bounds memory on very large objects)
MAX_SAMPLES = 400_000
#: fixed seed of the dense sample: features of a pinch never depend on --seed
SAMPLE_SEED = 20190323
#: points per leaf of the sample's KD-tree: the hand's distance queries, most of its queries, run a
#: fifth faster with 32 than with scipy's 16 (the answers are the same)
TREE_LEAF_SIZE = 32
#: the distance field decides "farther than this" without a grid cell (mm): beyond any finger's
#: radius
FIELD_MARGIN_MM = 20.0


def _embree_installed() -> bool:
    """Whether trimesh's Embree engine imports (``embreex`` installed for this platform); the
    first time it does not, a warning says so once."""
    global _EMBREE
    if _EMBREE is None:
        try:
            import embreex  # noqa: F401

            _EMBREE = True
        except ImportError:
            _EMBREE = False
            log.warning("embreex is not installed; rays use trimesh's numpy engine, about 10x "
                        "slower (pip install embreex)")
    return _EMBREE


_EMBREE: bool | None = None


def ray_engine_name() -> str:
    """``embree`` or ``numpy``: the ray engine this machine has (known without building one)."""
    return "embree" if _embree_installed() else "numpy"


def ray_engine(mesh: trimesh.Trimesh):
    """Return (intersector, name): Embree when ``embreex`` is installed, else trimesh's own.
    Only a missing ``embreex`` falls back; any other failure of the engine is raised."""
    if _embree_installed():
        from trimesh.ray.ray_pyembree import RayMeshIntersector

        return RayMeshIntersector(mesh), "embree"
    from trimesh.ray.ray_triangle import RayMeshIntersector

    return RayMeshIntersector(mesh), "numpy"


@dataclass(frozen=True)
class SurfaceSample:
    """Area-uniform sample of a surface.

    points : (s, 3) float64, mm
    face_index : (s,) int64   triangle holding each sample
    normals : (s, 3) float64  unit normal of that triangle
    chord6 : (s, 6) float64   chord tensor Σ_{i<j} b_i b_j e_ij e_ijᵀ of the sample's
                              barycentric coordinates b and its triangle's edges e,
                              as (xx, yy, zz, xy, xz, yz), mm²
    weight : (s,) float64     fit weight: 1 for a triangle sample, the vertex's
                              area share in samples for a mesh vertex
    is_vertex : (s,) bool     the sample is a mesh vertex (its normal is an average
                              of its triangles', meaningless on a sharp edge)
    spacing_mm : float        mean distance between neighbouring samples

    The mesh vertices are included: they lie on the surface the mesh stands
    for, exactly. Their weights sum to the same total as the triangle
    samples', and each is its area share, so no triangulation weighs more.

    A flat triangle is a chord of the curved surface it stands for. For a
    surface with second fundamental form II, the surface lies
    ½ ⟨II, chord⟩ outside the triangle at the sample (exact for a locally
    quadratic surface); :mod:`curvature` uses this to undo the chord bias of
    coarse meshes.
    """

    points: np.ndarray
    face_index: np.ndarray
    normals: np.ndarray
    chord6: np.ndarray
    weight: np.ndarray
    is_vertex: np.ndarray
    spacing_mm: float


def sample_surface(
    mesh: trimesh.Trimesh,
    *,
    area_per_sample_mm2: float,
    max_chord_edge_mm: float = np.inf,
    seed: int = SAMPLE_SEED,
) -> SurfaceSample:
    """Deterministic area-uniform sample, about ``area / area_per_sample`` points.

    Each face gets floor(area / area_per_sample + U) points, U uniform in
    [0, 1): its expected share exactly, with no aliasing against the order
    of the faces.

    Triangles with an edge longer than ``max_chord_edge_mm`` get no chord
    correction: the quadratic model of a patch cannot be extrapolated along
    them, and such triangles (CAD exports) are flat to the exporter's
    chordal tolerance along their length anyway.
    """
    rng = np.random.default_rng(seed)
    area = mesh.area_faces
    # independent rounding: unbiased per face, and no aliasing with the face order
    # (systematic sampling of a regular CAD mesh can pick only one kind of face)
    counts = np.floor(area / area_per_sample_mm2 + rng.random(len(area))).astype(np.int64)
    face_index = np.repeat(np.arange(len(area)), counts)
    r1, r2 = rng.random((2, len(face_index)))
    flip = r1 + r2 > 1.0
    r1[flip], r2[flip] = 1.0 - r1[flip], 1.0 - r2[flip]
    tri = mesh.triangles[face_index]
    points = (tri[:, 0] + r1[:, None] * (tri[:, 1] - tri[:, 0]) + r2[:, None]
              * (tri[:, 2] - tri[:, 0]))
    bary = np.column_stack([1.0 - r1 - r2, r1, r2])
    chord = np.zeros((len(points), 6))
    for i, j in ((0, 1), (1, 2), (2, 0)):
        e = tri[:, i] - tri[:, j]
        w = bary[:, i] * bary[:, j]
        chord += w[:, None] * np.column_stack(
            [e[:, 0] ** 2, e[:, 1] ** 2, e[:, 2] ** 2, e[:, 0] * e[:, 1], e[:, 0] * e[:, 2],
             e[:, 1] * e[:, 2]]
        )
    # vertices: exact points, each weighted by a third of its triangles' area; on a
    # mesh finer than the sample, a random subset of them at the sample's density
    vertex_area = np.bincount(
        mesh.faces.ravel(), weights=np.repeat(area / 3.0, 3), minlength=len(mesh.vertices)
    )
    keep_prob = min(1.0, len(points) / max(len(mesh.vertices), 1))
    used = (vertex_area > 0) & (rng.random(len(vertex_area)) < keep_prob)
    vertex_area = vertex_area / keep_prob
    vertex_face = np.zeros(len(mesh.vertices), dtype=np.int64)  # any one triangle of each vertex
    vertex_face[mesh.faces.ravel()] = np.repeat(np.arange(len(mesh.faces)), 3)
    longest = np.linalg.norm(tri - np.roll(tri, 1, axis=1),
                             axis=-1).max(axis=1) if len(tri) else np.zeros(0)
    chord[longest > max_chord_edge_mm] = 0.0
    return SurfaceSample(
        points=np.vstack([points, mesh.vertices[used]]),
        face_index=np.concatenate([face_index, vertex_face[used]]),
        normals=np.vstack([mesh.face_normals[face_index], mesh.vertex_normals[used]]),
        chord6=np.vstack([chord, np.zeros((int(used.sum()), 6))]),
        weight=np.concatenate([np.ones(len(points)), vertex_area[used] / area_per_sample_mm2]),
        is_vertex=np.concatenate([np.zeros(len(points), bool), np.ones(int(used.sum()), bool)]),
        spacing_mm=float(np.sqrt(area_per_sample_mm2)),
    )


class SurfaceContext:
    """Everything expensive about one surface, computed once and shared.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The surface, in mm.
    patch_radius_mm : float
        Contact patch radius; sets the density of the dense sample.
    regions : ContactRegions, optional
        Where contacts may not, or must, lie (:mod:`pinchmatch.mesh.regions`); default: anywhere.
    support : SupportPlane, optional
        The plane the object stands on (:mod:`pinchmatch.mesh.support`), below which no hand
        reaches; default: none (held in the hand).
    """

    def __init__(self, mesh: trimesh.Trimesh, *, patch_radius_mm: float = 8.0,
                 regions: ContactRegions = ContactRegions(), support: SupportPlane | None = None):
        self.mesh = mesh
        self.patch_radius_mm = float(patch_radius_mm)
        self.regions = regions
        self.support = support

    # Everything below is computed on first use, each once: an object read back from the cache for
    # its features and the search alone never needs any of it.

    @functools.cached_property
    def contact_area_mm2(self) -> np.ndarray:
        """(f,) area of each triangle that contacts may be drawn from: 0 where the regions allow
        none."""
        area = np.asarray(self.mesh.area_faces, dtype=np.float64)
        if self.regions:
            area = area * self.regions.faces_that_may_hold_contacts(self.mesh.triangles)
        return area

    @functools.cached_property
    def face_normals(self) -> np.ndarray:
        return np.asarray(self.mesh.face_normals)

    @functools.cached_property
    def scale_mm(self) -> float:
        return float(self.mesh.scale)

    @functools.cached_property
    def sample(self) -> SurfaceSample:
        per_sample = max(np.pi * self.patch_radius_mm**2 / SAMPLES_PER_PATCH,
                         float(self.mesh.area) / MAX_SAMPLES)
        sample = sample_surface(self.mesh, area_per_sample_mm2=per_sample,
                                max_chord_edge_mm=2.0 * self.patch_radius_mm)
        log.debug("surface context: %d faces, %d samples (%.2f mm apart)", len(self.mesh.faces),
                  len(sample.points), sample.spacing_mm)
        return sample

    @functools.cached_property
    def tree(self) -> cKDTree:
        return cKDTree(self.sample.points, leafsize=TREE_LEAF_SIZE)

    @functools.cached_property
    def distance_field(self) -> DistanceField:
        """Sure bounds on the distance to the dense sample, from a grid (exact beyond
        ``FIELD_MARGIN_MM``)."""
        return DistanceField.of(self.sample.points, margin_mm=FIELD_MARGIN_MM)

    def keep_distance_field(self, field: DistanceField) -> None:
        """Take ``field`` as this surface's :attr:`distance_field`: one made for the same sample
        elsewhere (a run's workers take a tangible's, made once with its poses)."""
        self.__dict__["distance_field"] = field

    @functools.cached_property
    def rays(self):
        return ray_engine(self.mesh)[0]

    @property
    def ray_engine_name(self) -> str:
        """``embree`` or ``numpy``: the engine :attr:`rays` is (known without building it)."""
        return ray_engine_name()

    @functools.cached_property
    def centroid_mm(self) -> np.ndarray:
        """Area-weighted centroid of the surface: "outward" for the hand's approach."""
        return np.average(self.sample.points, axis=0, weights=self.sample.weight)

    @functools.cached_property
    def principal_axes(self) -> np.ndarray:
        """(3, 3) principal directions of the surface, as columns, least spread first (a ring's, a
        plate's or a disc's symmetry axis comes first)."""
        centred = self.sample.points - self.centroid_mm
        cov = (centred * self.sample.weight[:, None]).T @ centred / self.sample.weight.sum()
        return np.linalg.eigh(cov)[1]

    def first_hit(self, origins: np.ndarray, directions: np.ndarray):
        """First surface hit along each ray.

        Returns
        -------
        face : (n,) int64      hit triangle, -1 where the ray escapes
        distance : (n,) float  distance along the unit direction, inf where it escapes
        """
        directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
        face = np.asarray(self.rays.intersects_first(origins, directions), dtype=np.int64)
        distance = np.full(len(origins), np.inf)
        hit = face >= 0
        if hit.any():
            n = self.face_normals[face[hit]]
            v0 = self.mesh.triangles[face[hit], 0]
            denom = np.einsum("ij,ij->i", directions[hit], n)
            with np.errstate(divide="ignore", invalid="ignore"):
                t = np.einsum("ij,ij->i", v0 - origins[hit], n) / denom
            distance[hit] = np.where(np.isfinite(t), t, 0.0)
        return face, distance

    def exits(self, origins: np.ndarray, directions: np.ndarray, *, max_distance: float,
              max_hits: int):
        """Every point where each ray leaves the solid, up to ``max_distance`` along it.

        The ray is followed through the surfaces it meets (walls, cavities, gaps): each hit
        whose triangle faces along the ray is an exit.

        Returns
        -------
        ray : (h,) int64       which ray each exit belongs to
        face : (h,) int64      the exit triangle
        distance : (h,) float  distance from the ray's origin along its unit direction
        """
        directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
        step = 1e-4 * max(self.scale_mm, 10.0)
        live = np.arange(len(origins))
        start = np.zeros(len(origins))
        rays, faces, dists = [], [], []
        for _ in range(max_hits):
            if len(live) == 0:
                break
            face, dist = self.first_hit(origins[live] + (start[live] + step)[:, None]
                                        * directions[live],
                                        directions[live])
            total = start[live] + step + dist
            hit = (face >= 0) & (total <= max_distance)
            exiting = hit.copy()
            exiting[hit] = np.einsum("ij,ij->i", self.face_normals[face[hit]],
                                     directions[live][hit]) > 0
            rays.append(live[exiting])
            faces.append(face[exiting])
            dists.append(total[exiting])
            start[live[hit]] = total[hit]
            live = live[hit]
        if not rays:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        ray, face, dist = np.concatenate(rays), np.concatenate(faces), np.concatenate(dists)
        order = np.lexsort((dist, ray))
        return ray[order], face[order], dist[order]

    def closest_points(self, points: np.ndarray):
        """Exact closest surface point, distance (mm) and triangle for each query point."""
        closest, distance, face = trimesh.proximity.closest_point(self.mesh, points)
        return np.asarray(closest), np.asarray(distance), np.asarray(face, dtype=np.int64)

    def min_distance_to_samples(self, points: np.ndarray, *,
                                beyond_mm: float = np.inf) -> np.ndarray:
        """Distance (mm) from each point to the nearest dense surface sample; inf where it is
        ``beyond_mm`` or more (the tree's search stops there: a caller that only compares with it
        pays less)."""
        distance, _ = query_tree(self.tree, points, k=1, distance_upper_bound=beyond_mm,
                                 work=len(points))
        return distance
