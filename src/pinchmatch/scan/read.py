"""A phone scan read as it was captured: a mesh or a point cloud, in mm, its up along +Z.

The scan's units and up come from the file where it carries them: a USD stage's ``metersPerUnit``
and ``upAxis`` (Apple's Object Capture writes centimetres with z up, or metres with y up) and the
transform of every mesh prim; glTF's metres and +Y. OBJ, PLY, STL and OFF carry neither: the object
options (``--units``, default mm; ``--up``, default z) say. A PLY with vertices and no faces is a
point cloud (photogrammetry's dense cloud).

Reading USD needs usd-core (``pip install 'pinchmatch[scan]'``, about 30 MB); without it a USD file
ends in one line that says so.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from ..errors import MeshError
from ..mesh.frames import UNITS_MM, parse_up, rotations_between

USD_SUFFIXES = (".usdz", ".usd", ".usda", ".usdc")
MESH_SUFFIXES = (".glb", ".gltf", ".obj", ".ply", ".stl", ".off")
#: USD's own default when a stage does not say (the USD specification: centimetres)
USD_DEFAULT_METERS_PER_UNIT = 0.01


@dataclass
class Scan:
    """A scan in mm with its up along +Z: ``faces`` is None for a point cloud; ``units_in`` and
    ``up_label`` say how it was read and ``source`` where that came from (the file or the
    options)."""

    path: Path
    vertices: np.ndarray
    faces: np.ndarray | None
    units_in: str
    up_label: str
    source: str
    #: (4, 4) the file's coordinates (its unit, its up; a USD stage's world) to ``vertices``
    from_file: np.ndarray = field(default_factory=lambda: np.eye(4))

    @property
    def is_cloud(self) -> bool:
        return self.faces is None


def read_scan(path, *, units: str | None = None, up: str | None = None) -> Scan:
    """The scan at ``path`` in mm, its up along +Z (module notes).

    Parameters
    ----------
    path : path-like
        A USDZ/USD, glTF/GLB, OBJ, PLY (mesh or point cloud), STL or OFF file.
    units : {"mm", "cm", "m", "in"}, optional
        The file's unit where it carries none (default mm).
    up : {"x", "y", "z", "-x", "-y", "-z"}, optional
        The object's up where the file carries none (default z).

    Returns
    -------
    Scan
        Its vertices (and faces, unless a point cloud), in mm, up along +Z.

    Examples
    --------
    >>> scan = read_scan(can_obj, units="m", up="z")
    >>> scan.is_cloud, scan.units_in, round(float(np.ptp(scan.vertices[:, 2])), 1)
    (False, 'm', 66.0)
    """
    path = Path(path)
    if not path.is_file():
        raise MeshError(f"{path}: no such file; give the scan's path")
    if path.stat().st_size == 0:
        raise MeshError(f"{path}: file is empty (0 bytes); export the scan again")
    suffix = path.suffix.lower()
    if suffix in USD_SUFFIXES:
        vertices, faces, mm_per_unit, up_label = _read_usd(path)
        units_in = _unit_name(mm_per_unit)
        source = "the file's metersPerUnit and upAxis"
    elif suffix in MESH_SUFFIXES:
        vertices, faces = _read_trimesh(path, suffix)
        is_gltf = suffix in (".glb", ".gltf")
        units_in = "m" if is_gltf else (units or "mm")
        up_label = "y" if is_gltf else (up or "z")
        source = "glTF's metres and +Y" if is_gltf else (
            "--units and --up" if units or up else "the defaults (mm, z up)")
        mm_per_unit = UNITS_MM[units_in]
    else:
        raise MeshError(f"{path}: not a scan format pinchmatch reads ({suffix or 'no suffix'}); "
                        f"export USDZ, GLB, OBJ, PLY or STL")
    if not len(vertices) or not np.isfinite(vertices).all():
        raise MeshError(f"{path}: the scan has no vertices, or some are not numbers (NaN or "
                        f"infinite); export it again")
    _, up_vector = parse_up(up_label, source=str(path))
    from_file = np.eye(4)
    from_file[:3, :3] = rotations_between(up_vector[None], np.array([[0.0, 0.0, 1.0]]))[0] \
        * mm_per_unit
    return Scan(path, vertices @ from_file[:3, :3].T, faces, units_in, up_label, source,
                from_file)


def _unit_name(mm_per_unit: float) -> str:
    """The name of a unit of this many mm, or the size itself."""
    for name, mm in UNITS_MM.items():
        if abs(mm - mm_per_unit) <= 1e-9 * mm:
            return name
    return f"{mm_per_unit:g} mm"


def _read_trimesh(path: Path, suffix: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Vertices and faces (None: a point cloud) of a mesh file, every part in its place."""
    try:
        loaded = trimesh.load(path, file_type=suffix[1:], process=False)
    except Exception as exc:  # trimesh raises many kinds on a corrupt file
        raise MeshError(f"{path}: cannot read the scan ({type(exc).__name__}: "
                        f"{str(exc).splitlines()[0] if str(exc) else 'corrupt'}); export it "
                        f"again") from None
    if isinstance(loaded, trimesh.Scene):
        geometry = loaded.dump(concatenate=False) if loaded.geometry else []
        meshes = [g for g in geometry if isinstance(g, trimesh.Trimesh) and len(g.faces)]
        clouds = [g for g in geometry if isinstance(g, trimesh.PointCloud)]
        if meshes:
            loaded = trimesh.util.concatenate(meshes)
        elif clouds:
            loaded = trimesh.PointCloud(np.concatenate([c.vertices for c in clouds]))
        else:
            raise MeshError(f"{path}: the file holds no mesh and no points; export the scan "
                            f"again")
    if isinstance(loaded, trimesh.PointCloud):
        return np.asarray(loaded.vertices, dtype=np.float64), None
    if not isinstance(loaded, trimesh.Trimesh):
        raise MeshError(f"{path}: the file holds no mesh and no points; export the scan again")
    faces = np.asarray(loaded.faces, dtype=np.int64)
    return np.asarray(loaded.vertices, dtype=np.float64), (faces if len(faces) else None)


def _read_usd(path: Path) -> tuple[np.ndarray, np.ndarray, float, str]:
    """Every mesh prim of a USD stage in the stage's world (its transforms applied), in the stage's
    unit, with the size of that unit in mm and the stage's up; polygons split into fans."""
    try:
        from pxr import Usd, UsdGeom
    except ImportError:
        raise MeshError(f"{path}: reading USD needs usd-core; install it with "
                        f"pip install 'pinchmatch[scan]'") from None
    stage, reason = None, "corrupt"
    try:
        stage = Usd.Stage.Open(str(path))
    except Exception as exc:  # pxr raises Tf.ErrorException on a corrupt layer
        reason = (str(exc).strip().splitlines() or [reason])[-1]
    if stage is None:
        raise MeshError(f"{path}: cannot open the USD stage ({reason[:120]}); export it again")
    meters = (UsdGeom.GetStageMetersPerUnit(stage)
              if stage.HasAuthoredMetadata("metersPerUnit") else USD_DEFAULT_METERS_PER_UNIT)
    up_label = str(UsdGeom.GetStageUpAxis(stage)).lower()
    cache = UsdGeom.XformCache()
    vertices, faces, offset = [], [], 0
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        mesh = UsdGeom.Mesh(prim)
        points = np.asarray(mesh.GetPointsAttr().Get() or [], dtype=np.float64).reshape(-1, 3)
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get() or [], dtype=np.int64)
        indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get() or [], dtype=np.int64)
        if not len(points) or not len(counts):
            continue
        if counts.sum() != len(indices) or (counts < 3).any() or indices.max() >= len(points):
            raise MeshError(f"{path}: the mesh {prim.GetPath()} has faces that do not match its "
                            f"points; export the scan again")
        M = np.asarray(cache.GetLocalToWorldTransform(prim), dtype=np.float64)  # row vectors
        vertices.append(points @ M[:3, :3] + M[3, :3])
        faces.append(_fans(counts, indices) + offset)
        offset += len(points)
    if not vertices:
        raise MeshError(f"{path}: the USD stage holds no mesh; export the scan as a mesh")
    if not meters > 0:
        raise MeshError(f"{path}: the stage's metersPerUnit is {meters}; export the scan again")
    return np.concatenate(vertices), np.concatenate(faces), meters * 1000.0, up_label


def _fans(counts: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(k, 3) triangles of polygons given by their vertex counts and concatenated indices: each
    polygon a fan from its first vertex (a scan's polygons are triangles or convex quads)."""
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    per = counts - 2
    owner = np.repeat(np.arange(len(counts)), per)
    k = np.arange(per.sum()) - np.repeat(np.cumsum(per) - per, per)
    first = starts[owner]
    return np.stack([indices[first], indices[first + k + 1], indices[first + k + 2]], axis=1)
