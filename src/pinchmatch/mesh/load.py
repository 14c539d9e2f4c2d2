"""Read a mesh file into millimetres, repair what is safe to repair, refuse the rest.

Everything downstream works in millimetres, in the file's own frame (only
scaled), so a coordinate a user reads in their modelling tool is the one
they pass to ``--p1``.
"""

from __future__ import annotations

import logging
import os
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from ..errors import ConfigError, MeshError
from ..files import holds_result
from .frames import UNITS_MM, check_units, parse_up
from .gltf_apply import applied_glb, needs_applying
from .gltf_check import PercentDecoding, check_gltf
from . import topology
from .facing import turned_outward
from .file_checks import (check_binary_stl, check_memory, check_ply_counts, check_precision,
                          check_readable)
from .level import (LevelNode, level_nodes, merged_primitives, node_mesh, remembered_scene,
                    scene_node_digests)

log = logging.getLogger(__name__)

#: extensions trimesh reads that we accept, mapped to the trimesh file type
MESH_EXTENSIONS = {
    ".stl": "stl",
    ".obj": "obj",
    ".ply": "ply",
    ".off": "off",
    ".glb": "glb",
    ".gltf": "gltf",
}

#: glTF is metres and +Y up by its own specification; other formats carry no units
GLTF_TYPES = {"glb", "gltf"}

#: a connected piece with less than this fraction of the total area is a loose sliver
SLIVER_AREA_FRACTION = 1e-3
#: vertices equal to this many decimals (mm) are one: trimesh's merge tolerance
MERGE_DIGITS = trimesh.util.decimal_to_digits(trimesh.tol.merge)


@dataclass(frozen=True)
class LoadedMesh:
    """One object read from a file, in millimetres.

    mesh : trimesh.Trimesh
        Repaired triangle mesh, vertices in mm, in the file's frame.
    path : str
        The file it came from (as given).
    units_in : str
        Unit the file was read in (``mm``, ``cm``, ``m`` or ``in``).
    up_label : str
        The object's up direction as given (``z``, ``-y``, ...).
    up : (3,) float64
        Unit vector of ``up_label``.
    watertight : bool
        True when the surface is closed, consistently wound and encloses volume.
    repairs : list of str
        What was repaired, one human-readable entry each.
    warnings : list of str
        What the user should know about the result.
    node : str or None
        The scene node it is, for one node of a level (its name is then the object's name).
    """

    mesh: trimesh.Trimesh
    path: str
    units_in: str
    up_label: str
    up: np.ndarray
    watertight: bool
    repairs: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    node: str | None = None

    @property
    def name(self) -> str:
        return self.node if self.node is not None else Path(self.path).name


def mesh_files(paths, *, option: str) -> list[Path]:
    """Each path as given when it is a file (or missing: loading will say so), and every mesh file
    below each folder, searched recursively by extension (through links to folders, each folder
    once), hidden files and folders skipped, and folders holding a pinchmatch result skipped
    whole (their meshes are its outputs), sorted. A folder that cannot be read is listed as it
    is, so that loading names it and a run leaves it out under ``failed``.

    Raises ConfigError for a readable folder that holds no mesh file.
    """
    out: list[Path] = []
    for given in [paths] if isinstance(paths, (str, os.PathLike)) else paths:
        # one path, not its characters
        if not str(given).strip():
            raise ConfigError(f"{option}: an empty path; give a mesh file, a folder of them or a "
                              "manifest")
        path = Path(given)
        if path.exists() and not path.is_dir() and not path.is_file():
            raise ConfigError(f"{path}: not a regular file (a device, a pipe or a socket); "
                              f"{option} takes mesh files, folders of them or manifests")
        if not path.is_dir():
            out.append(path)
            continue
        found, unreadable = _walk_meshes(path)
        if not found and not unreadable:
            what = ("holds a pinchmatch result, whose meshes are outputs, not inputs"
                    if holds_result(path) else
                    f"has no mesh file in it ({', '.join(MESH_EXTENSIONS)}, searched recursively)")
            raise ConfigError(f"{path}: {option} names a folder that {what}; point it at your "
                              "meshes")
        out.extend(sorted(found + unreadable))
    return out


def _walk_meshes(root: Path) -> tuple[list[Path], list[Path]]:
    """(mesh files, folders that cannot be read) below ``root``."""
    found: list[Path] = []
    unreadable: list[Path] = []
    seen: set[str] = set()
    for folder, dirs, files in os.walk(root, followlinks=True,
                                       onerror=lambda exc: unreadable.append(Path(exc.filename))):
        real = os.path.realpath(folder)
        if real in seen:  # a link back up the tree
            dirs[:] = []
            continue
        seen.add(real)
        if holds_result(folder):  # pinchmatch's own output (scenes, objects): never an input
            log.info("%s: holds a pinchmatch result; its meshes are left out", folder)
            dirs[:] = []
            continue
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        found += [Path(folder) / f for f in files
                  if not f.startswith(".") and Path(f).suffix.lower() in MESH_EXTENSIONS
                  and (Path(folder) / f).is_file()]
    return found, unreadable


def _file_type(path: Path) -> str:
    ext = path.suffix.lower()
    if ext not in MESH_EXTENSIONS:
        known = " ".join(MESH_EXTENSIONS)
        raise MeshError(
            f"{path}: unknown mesh format {ext or '(no extension)'!r}; export it as one of {known}"
        )
    return MESH_EXTENSIONS[ext]


def _load(path: Path, file_type: str, *, split: bool = False, **kwargs):
    source, read_as = str(path), file_type
    if file_type in GLTF_TYPES:
        # a .glb may name external buffers too: found beside it, as a .gltf's
        document = check_gltf(path, file_type, split=split)
        kwargs.setdefault("resolver", PercentDecoding(str(path)))
        if needs_applying(document):  # sparse accessors, default morph weights: applied first
            source, read_as = trimesh.util.wrap_as_stream(applied_glb(path, file_type,
                                                                      document)), "glb"
    try:
        loaded = trimesh.load(source, file_type=read_as, process=False, **kwargs)
        if isinstance(loaded, trimesh.Scene) and file_type in GLTF_TYPES:
            return merged_primitives(loaded)
        return loaded
    except (IndexError,) as exc:
        what = ("an index (of a node, mesh, accessor or vertex) points past its list"
                if file_type in GLTF_TYPES
                else "a face refers to a vertex that does not exist")
        raise MeshError(f"{path}: {what} ({exc}); the file is corrupt, re-export it") from None
    except Exception as exc:  # trimesh raises many types on malformed input
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise MeshError(
            f"{path}: cannot be read as {file_type.upper()} ({reason}); "
            "the file is corrupt or truncated, re-export it"
        ) from None


def node_digests(path: str | os.PathLike) -> dict[str, str]:
    """{node: digest of its triangles in the world} for every mesh node of a glTF/GLB level
    (:func:`pinchmatch.mesh.level.scene_node_digests`)."""
    return scene_node_digests(level_scene(Path(path)))


def level_scene(path: Path) -> trimesh.Scene:
    """A glTF/GLB file read as a scene of nodes, for splitting; MeshError for any other file."""
    check_readable(path)
    file_type = _file_type(path)
    if file_type not in GLTF_TYPES:
        raise MeshError(f"{path}: only a glTF or GLB scene can be split into its nodes; "
                        "leave out split = \"nodes\" for this file")
    return remembered_scene(path, lambda: _load(path, file_type, split=True, force="scene"),
                            split=True)


def read_level(path: str | os.PathLike) -> list[LevelNode]:
    """The mesh nodes of a glTF/GLB scene (see :mod:`pinchmatch.mesh.level`), for splitting it into
    one object per node. Raises MeshError for a file that cannot be read or holds no mesh node."""
    path = Path(path)
    nodes = level_nodes(level_scene(path))
    if not nodes:
        raise MeshError(f"{path}: the scene has no node holding triangles; re-export the level "
                        "with its meshes")
    return nodes


def _read(path: Path, file_type: str, node: str | None = None) -> trimesh.Trimesh:
    if node is not None:
        mesh = node_mesh(remembered_scene(path, lambda: _load(path, file_type, force="scene"),
                                          split=False), node)
        if mesh is None:
            raise MeshError(f"{path}: the scene has no mesh node named {node!r}; "
                            "check the name against the file (pinchmatch names level nodes as the "
                            "file does)")
        return mesh
    binary = _binary_stl_triangles(path) if file_type == "stl" else None
    if binary is not None:
        return trimesh.Trimesh(vertices=binary, faces=np.arange(len(binary)).reshape(-1, 3),
                               process=False)
    loaded = _load(path, file_type)
    if isinstance(loaded, trimesh.Scene):
        meshes = [g for g in loaded.dump()
                  if isinstance(g, trimesh.Trimesh)] if loaded.geometry else []
        meshes = [m for m in meshes if len(m.faces)]
        if not meshes:
            kinds = sorted({type(g).__name__ for g in loaded.geometry.values()})
            what = f"only {', '.join(kinds)}" if kinds else "nothing"
            raise MeshError(
                f"{path}: no triangles could be read ({what}); the file is corrupt, "
                "truncated or not a triangle mesh, re-export it"
            )
        mesh = trimesh.util.concatenate(meshes) if len(meshes) > 1 else meshes[0]
    elif isinstance(loaded, trimesh.Trimesh):
        mesh = loaded
    else:
        raise MeshError(
            f"{path}: has no faces (it holds a {type(loaded).__name__}); "
            "export the object as a triangle mesh"
        )
    return mesh


#: a binary STL triangle: normal, three corners, attribute bytes (the format's fixed 50-byte record)
_STL_RECORD = np.dtype([("normal", "<f4", (3,)), ("corners", "<f4", (3, 3)), ("attributes", "<u2")])


def _binary_stl_triangles(path: Path) -> np.ndarray | None:
    """(3t, 3) float64 corners of a binary STL's triangles, read straight into an array, or None
    when the file is not a binary STL with triangles (ASCII, or none: trimesh reads and explains
    it).

    A file is binary when its size is the header's 84 bytes plus 50 per triangle it counts, as
    trimesh decides (some binary files begin with "solid" too). The corners are what trimesh reads,
    without the face normals, colours and cache keys it builds around them.
    """
    with open(path, "rb") as fh:
        head = fh.read(84)
        if len(head) < 84:
            return None
        (count,) = struct.unpack("<I", head[80:84])
        if count == 0 or os.fstat(fh.fileno()).st_size != 84 + _STL_RECORD.itemsize * count:
            return None
        records = np.fromfile(fh, dtype=_STL_RECORD, count=count)
    return records["corners"].reshape(-1, 3).astype(np.float64)


def _validate_arrays(path: Path, mesh: trimesh.Trimesh) -> None:
    vertices = np.asarray(mesh.vertices)
    faces = np.asarray(mesh.faces)
    if len(faces) == 0:
        raise MeshError(
            f"{path}: has {len(vertices)} vertices but no faces; export it as a triangle mesh"
        )
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise MeshError(
            f"{path}: a face refers to vertex {int(faces.max())} but there are only "
            f"{len(vertices)} vertices; the file is corrupt, re-export it"
        )
    if np.isfinite(vertices).all():  # the common case, without a reduction along the rows
        return
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        raise MeshError(
            f"{path}: {int(bad.sum())} of {len(vertices)} vertices are NaN or infinite; "
            "fix the export (or the modelling tool's modifiers) and re-export"
        )


def _repair(mesh: trimesh.Trimesh, *, indexed: bool, scale: float,
            say: Callable[[str], None] = lambda stage: None) \
        -> tuple[list[str], bool]:
    """Repair in place what is safe to repair; return what was done, and whether the result is a
    closed solid (watertight, consistently wound, enclosing a positive volume).

    ``indexed``: the format shares vertices between faces (not STL, where
    every triangle has its own copies and merging them is routine).

    Each step is trimesh's, computed by :mod:`pinchmatch.mesh.topology` (the same result, in a
    fraction of the time and memory on large meshes).
    """
    repairs: list[str] = []

    n_vertices = len(mesh.vertices)
    say("repairing: merging vertices")
    merged = None if "vertex_normals" in mesh._cache else \
        topology.merge_vertices(mesh.vertices, mesh.faces, MERGE_DIGITS)
    if merged is None:
        mesh.merge_vertices()
    else:
        mesh.update_vertices(mask=merged[0], inverse=merged[1])
    if len(mesh.vertices) < n_vertices and indexed:
        repairs.append(f"merged {n_vertices - len(mesh.vertices)} duplicate vertices")

    say("repairing: degenerate and duplicate faces")
    keep = topology.nondegenerate_faces(mesh.vertices, mesh.faces, height=1e-9 * max(scale, 1e-12))
    if not keep.all():
        repairs.append(f"removed {int((~keep).sum())} degenerate faces")
        mesh.update_faces(keep)

    unique = topology.unique_faces(mesh.faces)
    if not unique.all():
        repairs.append(f"removed {int((~unique).sum())} duplicate faces")
        mesh.update_faces(unique)
    if len(mesh.faces) == 0:
        return repairs, False

    say("repairing: edges and bodies")
    e = topology.edges(mesh.faces)
    labels = topology.component_labels(topology.face_adjacency(e), len(mesh.faces))
    n_parts = int(labels.max()) + 1 if len(labels) else 0
    if n_parts > 1:
        part_area = np.bincount(labels, weights=mesh.area_faces, minlength=n_parts)
        tiny = part_area < SLIVER_AREA_FRACTION * part_area.sum()
        if tiny.any() and not tiny.all():
            mesh.update_faces(~tiny[labels])
            e = topology.edges(mesh.faces)
            labels = topology.component_labels(topology.face_adjacency(e), len(mesh.faces))
            repairs.append(
                f"removed {int(tiny.sum())} loose sliver(s) under "
                f"{SLIVER_AREA_FRACTION:.1%} of the surface"
            )
        inside = topology.enclosed_parts(mesh.vertices, mesh.faces, labels)
        if inside.any():
            # a hand touches the outer shell only: pages in a cover, a liner in a shell
            mesh.update_faces(~inside[labels])
            e = topology.edges(mesh.faces)
            labels = topology.component_labels(topology.face_adjacency(e), len(mesh.faces))
            repairs.append(f"removed {int(inside.sum())} part(s) lying inside another (only the "
                           "outer shell is touched)")
    mesh.remove_unreferenced_vertices()

    say("repairing: orientation")
    # removing unreferenced vertices renumbers the corners, but keeps the faces and their edges
    watertight, consistent_before = topology.watertight_and_wound(e)
    if not consistent_before:  # winding to make consistent first: trimesh's traversal
        before = topology.cyclic(mesh.faces)
        volume_before = 0.0
        trimesh.repair.fix_normals(mesh, multibody=True)
        flipped = int((topology.cyclic(mesh.faces) != before).any(axis=1).sum())
        watertight, wound = topology.watertight_and_wound(topology.edges(mesh.faces))
        volume = float(topology.signed_volumes(mesh.vertices, mesh.faces).sum())
    else:  # consistent: only whole bodies turned inside out are turned back, as trimesh does
        volumes = topology.signed_volumes(mesh.vertices, mesh.faces)
        volume_before = float(volumes.sum())
        flip = topology.inverted_bodies(mesh.vertices, mesh.faces, e, labels, volumes)
        if flip.any():
            faces = mesh.faces.copy()
            faces[flip] = faces[flip][:, ::-1]
            mesh.faces = faces
            volumes[flip] = -volumes[flip]
        # whole consistent bodies turned: still consistent
        wound, volume = True, float(volumes.sum())
        # a face of three distinct corners, reversed, is another orientation
        flipped = int(flip.sum())
    if consistent_before and volume_before < 0 and flipped:
        repairs.append("turned the surface right side out (it was inside-out)")
    elif flipped:
        repairs.append(f"made winding consistent ({flipped} faces flipped)")
    if not watertight and (line := turned_outward(mesh)):
        # an open part's volume says nothing: rays do
        repairs.append(line)
    return repairs, bool(watertight and wound and volume > 0)


def load_mesh(
    path: str | os.PathLike,
    *,
    units: str | None = None,
    up: str | None = None,
    progress: Callable[[str], None] | None = None,
    node: str | None = None,
) -> LoadedMesh:
    """Read one object from a mesh file, in millimetres.

    Parameters
    ----------
    path : path-like
        STL, OBJ, PLY, OFF, glTF or GLB file. A file with several meshes is
        one object (all its parts together, with their node transforms).
    units : {"mm", "cm", "m", "in"}, optional
        Unit of the file's coordinates. Default: metres for glTF/GLB (the
        format's rule), millimetres for the others.
    up : {"x", "y", "z", "-x", "-y", "-z"}, optional
        The object's up direction. Default: ``y`` for glTF/GLB, ``z`` otherwise.
    progress : callable, optional
        Called with the name of each stage as it starts ("reading 250 MiB", "repairing"), so that
        a large file shows where its load is.
    node : str, optional
        Only this mesh node of a glTF/GLB scene, in world coordinates (a level split into its
        nodes, :func:`read_level`).

    Returns
    -------
    LoadedMesh
        The mesh in mm with its up along +Z, and how it was read and repaired.

    Raises
    ------
    MeshError
        The file is missing, empty, corrupt, not a solid or of implausible size.
    ConfigError
        ``units`` or ``up`` is not a known value.

    Examples
    --------
    >>> loaded = load_mesh(can_obj, units="m")  # a file in metres, read in mm
    >>> loaded.mesh.extents.round(1).tolist(), loaded.units_in, loaded.watertight
    ([54.0, 54.0, 66.0], 'm', True)
    """
    path = Path(path)
    if units is not None and units not in UNITS_MM:
        raise ConfigError(f"--units: unknown unit {units!r}; use one of {', '.join(UNITS_MM)}")
    if up is not None:
        parse_up(up)
    check_readable(path)
    file_type = _file_type(path)
    size = path.stat().st_size
    if size == 0:
        raise MeshError(f"{path}: file is empty (0 bytes); re-export the mesh")
    check_memory(path, size, file_type)
    if file_type == "stl":
        check_binary_stl(path, size)
    elif file_type == "ply":
        check_ply_counts(path, size)

    say = progress or (lambda stage: None)
    say(f"reading {size / 2**20:.0f} MiB" if size >= 2**20 else "reading")
    mesh = _read(path, file_type, node)
    # what the messages name: the file, and its node
    shown = Path(f"{path}#{node}") if node else path
    _validate_arrays(shown, mesh)
    check_precision(shown, file_type, mesh)

    is_gltf = file_type in GLTF_TYPES
    units_in = units or ("m" if is_gltf else "mm")
    up_label, up_vector = parse_up(up or ("y" if is_gltf else "z"))

    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    factor = UNITS_MM[units_in]
    mesh = trimesh.Trimesh(vertices=vertices * factor if factor != 1.0 else vertices,
                           faces=np.asarray(mesh.faces, dtype=np.int64), process=False)
    sizes = topology.extents(mesh.vertices)
    extent = float(sizes.max())
    check_units(shown, extent, units_in)

    if topology.thickness(mesh.vertices) < 1e-6 * extent:
        raise MeshError(
            f"{shown}: the mesh is flat (all vertices in one plane), so it has no volume "
            "to pinch; give it thickness (solidify) and re-export"
        )

    # trimesh's ``scale`` (its bounding box diagonal), for the degenerate-face height
    scale = float((sizes**2).sum() ** 0.5)
    repairs, watertight = _repair(mesh, indexed=file_type != "stl", scale=scale, say=say)
    if len(mesh.faces) == 0:
        raise MeshError(f"{shown}: every face is degenerate (zero area); re-export the mesh")

    warnings: list[str] = []
    if not watertight:
        warnings.append(
            f"{shown.name}: surface is not closed; centre of mass is that of the surface, and "
            "pinches come only from where the ray along the pinch line leaves through a surface"
        )
    for line in repairs:
        log.info("%s: %s", shown.name, line)
    return LoadedMesh(
        mesh=mesh,
        path=str(path),
        units_in=units_in,
        up_label=up_label,
        up=up_vector,
        watertight=watertight,
        repairs=repairs,
        warnings=warnings,
        node=node,
    )
