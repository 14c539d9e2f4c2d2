"""A scan's surface made fit to pinch: a point cloud reconstructed, the noise along the normal
smoothed away, the faces decimated to a size the pipeline handles quickly.

- **Reconstruction:** screened Poisson (Kazhdan & Hoppe 2013), MeshLab's, through pymeshlab (the
  ``scan`` extra). It is the reconstruction photogrammetry tools use for dense clouds, robust to the
  scan's noise (it fits an indicator function, never interpolates the points), and MeshLab keeps it
  maintained. The normals are estimated from ``NORMAL_NEIGHBOURS`` neighbours (MeshLab's), and each
  is turned toward the outside the scanner saw it from (:mod:`pinchmatch.scan.orient`): propagated
  from neighbour to neighbour, a sign crosses a thin wall and turns one of its sides inside out.
  Where the surface lies farther from every scanned point than ``TRIM_SPACINGS`` times the cloud's
  spacing (at least ``TRIM_MIN_MM``), it is trimmed: Poisson closes every gap (the bottom where the
  object stood) with a guess, and a guess is never pinched; the gap is then closed and marked as a
  mesh scan's is.
- **Smoothing:** Taubin's λ|μ filter (trimesh), which removes noise without shrinking the object:
  phone scans carry 0.5 to 1 mm of noise along the normal, which the 8 mm patches would read as
  curvature. The noise itself is measured as the RMS of what the filter moves. A mesh whose enclosed
  volume the filter would change by more than ``MAX_SMOOTH_VOLUME_CHANGE`` is left as it is: its
  vertices are shape (a model's), not noise. A surface rebuilt from a point cloud is always
  smoothed: a cloud is a scan's.
- **Decimation:** quadric edge collapse (fast-simplification, through trimesh) to ``MAX_FACES``. A
  surface rebuilt from a cloud comes at Poisson's resolution (half a million faces for a mug), and
  collapsed that far fast-simplification joins a thin wall's two sides (a mug's wall is 1 to
  1.5 mm): edges shared by four faces, holes the import then closes and marks unseen (98 on the
  YCB mug's cloud). It is decimated by MeshLab's collapse instead, which keeps the topology (7
  holes). A mesh scan keeps fast-simplification's: MeshLab's is three times slower on it and
  leaves its widths further off (the mug's largest error 0.74 JND against 0.65).
"""

from __future__ import annotations

import importlib.util

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from ..errors import MeshError
from .orient import outward_normals

#: a prop is decimated to at most this many faces: the pipeline samples a 16k-face scan in about a
#: second, and a hand feels nothing finer than the 8 mm patches
MAX_FACES = 40_000
#: Poisson faces farther than this many point spacings from the cloud are trimmed, or this many mm
TRIM_SPACINGS, TRIM_MIN_MM = 4.0, 2.0
#: the octree depth of the reconstruction: 2^8 cells across, 0.6 mm for a 150 mm object (finer
#: than the scan's noise; depth 9 takes four times as long)
POISSON_DEPTH = 8
#: Taubin's filter: λ, μ and the passes (λ < -μ: no shrinking)
TAUBIN_LAMBDA, TAUBIN_MU, TAUBIN_PASSES = 0.5, -0.53, 10
#: a smoothing that changes the enclosed volume by more than this share is undone (module notes)
MAX_SMOOTH_VOLUME_CHANGE = 0.03
#: a denser cloud is thinned to this many points before it is rebuilt (a point every 0.7 mm or so on
#: a hand-sized object; the rebuild's time grows with the points)
CLOUD_POINTS = 100_000
#: a cloud's normal lines are fitted to this many neighbours (MeshLab's, then smoothed twice)
NORMAL_NEIGHBOURS = 10
#: a cloud with more than this share of its points on walls too thin to tell their sides apart is
#: refused (:class:`pinchmatch.scan.orient.Faced`): the YCB bowl's (22 %) came out 5 % light with
#: its centre of mass 6 mm off; the mug's (8 %) within 4 % and 1.5 mm, its bottom unseen
MAX_UNSURE = 0.15
#: a cloud of fewer points than this cannot be a prop's surface
MIN_CLOUD_POINTS = 500


def _meshlab(path, work: str = "a point cloud is reconstructed"):
    try:
        import pymeshlab
    except ImportError:
        raise MeshError(f"{path}: {work} by pymeshlab; install it with "
                        f"pip install 'pinchmatch[scan]'") from None
    return pymeshlab


def flat(points: np.ndarray) -> bool:
    """Is the point set a sheet (its thinnest spread under a thousandth of its widest)?"""
    spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    return bool(spread[2] < 1e-3 * spread[0])


def _poisson(ms, *, process: bool) -> trimesh.Trimesh:
    """The screened Poisson surface of the MeshSet's mesh (its points and normals)."""
    ms.generate_surface_reconstruction_screened_poisson(depth=POISSON_DEPTH, preclean=True)
    rebuilt = ms.current_mesh()
    return trimesh.Trimesh(rebuilt.vertex_matrix(), rebuilt.face_matrix(), process=process)


def reconstruct(points: np.ndarray, path) -> trimesh.Trimesh:
    """The surface of a point cloud (mm): screened Poisson, trimmed where the cloud was thin."""
    if len(points) < MIN_CLOUD_POINTS:
        raise MeshError(f"{path}: a point cloud of {len(points)} points is too sparse to rebuild a "
                        f"surface (at least {MIN_CLOUD_POINTS}); export the dense cloud or the "
                        f"mesh")
    if flat(points):
        raise MeshError(f"{path}: the point cloud is flat (a sheet, not an object); scan the "
                        f"object all round")
    ml = _meshlab(path)
    if len(points) > CLOUD_POINTS:  # a fixed draw: the same prop every run
        points = points[np.sort(np.random.default_rng(0).choice(len(points), CLOUD_POINTS,
                                                                 replace=False))]
    points = np.ascontiguousarray(points, dtype=np.float64)
    ms = ml.MeshSet()
    ms.add_mesh(ml.Mesh(vertex_matrix=points))
    ms.compute_normal_for_point_clouds(k=NORMAL_NEIGHBOURS, smoothiter=2)
    faced = outward_normals(points, ms.current_mesh().vertex_normal_matrix())
    if faced.unsure > MAX_UNSURE:
        raise MeshError(f"{path}: {100 * faced.unsure:.0f} % of the point cloud lies on walls too "
                        f"thin for its noise to tell their two sides apart (a bowl's, a plate's); "
                        f"export the scan as a mesh")
    ms = ml.MeshSet()
    ms.add_mesh(ml.Mesh(vertex_matrix=points,
                        v_normals_matrix=np.ascontiguousarray(faced.normals)))
    mesh = _poisson(ms, process=False)
    tree = cKDTree(points)
    spacing = float(np.median(tree.query(points, k=2)[0][:, 1]))
    far, _ = tree.query(mesh.triangles_center)
    mesh.update_faces(far <= max(TRIM_MIN_MM, TRIM_SPACINGS * spacing))
    mesh.remove_unreferenced_vertices()
    if not len(mesh.faces):
        raise MeshError(f"{path}: no surface could be rebuilt from the point cloud; export the "
                        f"mesh instead")
    return mesh


def rebuild(mesh: trimesh.Trimesh, path) -> trimesh.Trimesh:
    """A closed surface through a mesh whose holes cannot be closed as they are (edges shared by
    three faces, loops through one vertex twice): screened Poisson on its vertices and normals,
    untrimmed, so that it is watertight."""
    ml = _meshlab(path)
    mesh = decimate(mesh, MAX_FACES)
    ms = ml.MeshSet()
    ms.add_mesh(ml.Mesh(vertex_matrix=np.ascontiguousarray(mesh.vertices, dtype=np.float64),
                        v_normals_matrix=np.ascontiguousarray(mesh.vertex_normals,
                                                              dtype=np.float64)))
    out = _poisson(ms, process=True)
    trimesh.repair.fix_normals(out)
    if not out.is_watertight or abs(out.volume - _enclosed(mesh)) > 0.05 * abs(_enclosed(mesh)):
        raise MeshError(f"{path}: the scan could not be closed into a solid (its open edges do "
                        f"not form loops a face can close, and a surface rebuilt through it "
                        f"does not keep its volume); repair it in the scanning app or MeshLab")
    return out


def smooth(mesh: trimesh.Trimesh, *, rebuilt: bool = False) -> tuple[trimesh.Trimesh, float]:
    """The mesh with its noise along the normal smoothed away (Taubin), and the noise: the RMS of
    the vertices' moves along their normals, mm (NaN: a coarse mesh, left as it is). A surface
    ``rebuilt`` from a point cloud is a scan's whatever its volume does: it is always smoothed (the
    volume of an open, thin-walled one, a cup's, is its walls' alone, and a tenth of a millimetre
    changes it by more than the check allows)."""
    smoothed = _taubin(mesh)
    before_v, after_v = _enclosed(mesh), _enclosed(smoothed)
    if not rebuilt and abs(after_v - before_v) > MAX_SMOOTH_VOLUME_CHANGE * abs(before_v):
        return mesh, float("nan")  # the filter moved the shape, not the noise: not a scan
    return smoothed, _along_normals_rms(smoothed.vertices, mesh)


def _taubin(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """A copy of ``mesh`` smoothed by Taubin's filter (the import's one setting)."""
    smoothed = mesh.copy()
    trimesh.smoothing.filter_taubin(smoothed, lamb=TAUBIN_LAMBDA, nu=TAUBIN_MU,
                                    iterations=TAUBIN_PASSES)
    return smoothed


def _along_normals_rms(vertices: np.ndarray, reference: trimesh.Trimesh) -> float:
    """The RMS of ``vertices``' moves from ``reference``'s along its vertex normals, mm."""
    moved = np.einsum("nd,nd->n", vertices - reference.vertices, reference.vertex_normals)
    return float(np.sqrt(np.mean(moved ** 2))) if len(moved) else 0.0


def residual(smoothed: trimesh.Trimesh, noise_mm: float, *, seed: int = 0) -> float:
    """The error the smoothing leaves (mm RMS along the normal): ``smoothed`` given a fresh draw of
    Gaussian noise of ``noise_mm`` along its normals and smoothed again as :func:`smooth` does, its
    distance from ``smoothed``. At the scan's own density, before any decimation: what the prop's
    surface is still off by, for :mod:`pinchmatch.match.trust`."""
    if not np.isfinite(noise_mm) or noise_mm <= 0 or not len(smoothed.vertices):
        return 0.0
    draw = np.random.default_rng(seed).standard_normal(len(smoothed.vertices))
    noisy = smoothed.copy()
    noisy.vertices = smoothed.vertices + smoothed.vertex_normals * (noise_mm * draw)[:, None]
    return _along_normals_rms(_taubin(noisy).vertices, smoothed)


def _enclosed(mesh: trimesh.Trimesh) -> float:
    """The volume the faces enclose as seen from their centroid (an open scan's too: the cones
    from the centroid to each face, summed with their signs)."""
    tri = mesh.triangles - mesh.vertices.mean(axis=0)
    return float(np.einsum("nd,nd->n", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)


def decimate(mesh: trimesh.Trimesh, faces: int = MAX_FACES, *,
             keep_topology: bool = False) -> trimesh.Trimesh:
    """The mesh with at most ``faces`` faces (quadric edge collapse), unchanged when it has
    fewer: fast-simplification's, or with ``keep_topology`` MeshLab's, which never joins two sheets
    of the surface (module notes)."""
    if len(mesh.faces) <= faces:
        return mesh
    where = mesh.metadata.get("file_path", "the scan")
    if keep_topology:
        ml = _meshlab(where, "a surface rebuilt from a cloud is decimated")
        ms = ml.MeshSet()
        ms.add_mesh(ml.Mesh(vertex_matrix=np.ascontiguousarray(mesh.vertices, dtype=np.float64),
                            face_matrix=np.ascontiguousarray(mesh.faces, dtype=np.int32)))
        ms.meshing_decimation_quadric_edge_collapse(targetfacenum=int(faces),
                                                    preservetopology=True)
        out = ms.current_mesh()
        return trimesh.Trimesh(out.vertex_matrix(), out.face_matrix(), process=True)
    if importlib.util.find_spec("fast_simplification") is None:  # trimesh's decimation calls it
        raise MeshError(f"{where}: decimating {len(mesh.faces)} faces needs fast-simplification; "
                        f"install it with pip install 'pinchmatch[scan]'") from None
    out = mesh.simplify_quadric_decimation(face_count=faces)
    return trimesh.Trimesh(out.vertices, out.faces, process=True)
