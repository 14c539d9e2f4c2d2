"""Checks of a mesh file before and after trimesh reads it, each ending in one line that names the
fix.

A file that cannot be read, a binary STL cut short, a PLY whose header claims more than the file
holds, a file too large for the memory left, and coordinates too large for the precision they are
stored in: :func:`pinchmatch.mesh.load.load_mesh` runs these so that a bad file ends in a
:class:`~pinchmatch.errors.MeshError` naming the file, what is wrong and what to do, not in a
traceback from deep inside a reader.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np
import trimesh

from ..errors import MeshError
from ..memory import memory_headroom


def check_binary_stl(path: Path, size: int) -> None:
    """Explain a truncated binary STL precisely (trimesh would read it as empty)."""
    with open(path, "rb") as fh:
        head = fh.read(84)
    if len(head) < 84 or head[:5].lower() == b"solid":
        return
    (count,) = struct.unpack("<I", head[80:84])
    expected = 84 + 50 * count
    if size < expected and expected > 10 * size:
        raise MeshError(
            f"{path}: not a valid STL: its header claims {count} triangles in a {size}-byte file; "
            "the file is corrupt or not an STL, re-export it"
        )
    if size < expected:
        raise MeshError(
            f"{path}: truncated binary STL: its header promises {count} triangles "
            f"({expected} bytes) but the file has {size} bytes; re-export or re-download it"
        )


#: peak memory of loading and analysing a mesh, per byte of its file (measured: a 5.2 M-face binary
#: STL of 260 MB peaked at 4.7 GB; text formats hold fewer faces per byte)
PEAK_BYTES_PER_FILE_BYTE = {"stl": 20.0, "ply": 20.0, "glb": 20.0, "gltf": 12.0, "obj": 12.0,
                            "off": 12.0}


def check_memory(path: Path, size: int, file_type: str) -> None:
    """Refuse, before reading it, a mesh whose analysis would need more memory than this process may
    still take (the machine's, ``ulimit -v``'s or its control group's:
    :func:`pinchmatch.memory.memory_headroom`)."""
    need = size * PEAK_BYTES_PER_FILE_BYTE.get(file_type, 20.0)
    headroom = memory_headroom()
    if headroom is not None and need > 0.9 * headroom[0]:
        raise MeshError(f"{path}: a {size / 2**20:.0f} MiB mesh needs about {need / 2**30:.1f} GiB "
                        "to analyse, more "
                        f"than the {headroom[1]}; decimate it (to about a million faces) or give "
                        "the run more memory")


PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2,
              "uint16": 2, "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4,
              "double": 8, "float64": 8}


def check_ply_counts(path: Path, size: int) -> None:
    """Refuse a PLY whose header counts fewer elements than the file holds (a reader would take
    the first ones and silently drop the rest). Binary files are checked when every face is a
    triangle and the elements are vertices then faces (what exporters write)."""
    with open(path, "rb") as fh:
        head = fh.read(65536)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        return  # the reader will say what is wrong
    body = head.index(b"\n", end) + 1 if b"\n" in head[end:] else len(head)
    lines = head[:end].decode("ascii", "replace").splitlines()
    fmt = next((line.split()[1] for line in lines if line.startswith("format ")), "")
    elements: list[tuple[str, int, list[list[str]]]] = []
    for line in lines:
        words = line.split()
        if words[:1] == ["element"] and len(words) == 3 and words[2].isdigit():
            elements.append((words[1], int(words[2]), []))
        elif words[:1] == ["property"] and elements:
            elements[-1][2].append(words[1:])
    claimed = {name: count for name, count, _ in elements}
    if fmt == "ascii":
        with open(path, "rb") as fh:
            fh.seek(body)
            held = sum(1 for line in fh if line.strip())
        if held > sum(claimed.values()):
            raise MeshError(f"{path}: its header counts {claimed.get('vertex', 0)} vertices and "
                            f"{claimed.get('face', 0)} "
                            f"faces, but the file holds {held} data lines; the header is wrong, "
                            "re-export it")
        return
    if fmt not in ("binary_little_endian",
                   "binary_big_endian") or [e[0] for e in elements] != ["vertex", "face"]:
        return
    vertex_props, face_props = elements[0][2], elements[1][2]
    if (any(p[0] == "list" or p[0] not in PLY_SIZES for p in vertex_props) or len(face_props) != 1
            or face_props[0][0] != "list" or face_props[0][1] not in PLY_SIZES
            or face_props[0][2] not in PLY_SIZES):
        return
    count_size, index_size = PLY_SIZES[face_props[0][1]], PLY_SIZES[face_props[0][2]]
    start = body + claimed["vertex"] * sum(PLY_SIZES[p[0]] for p in vertex_props)
    record = count_size + 3 * index_size
    expected = start + claimed["face"] * record
    if size <= expected or count_size != 1:
        return
    counts = np.memmap(path, dtype=np.uint8, mode="r", offset=start,
                       shape=(claimed["face"] * record,))[::record]
    if (counts == 3).all():
        raise MeshError(f"{path}: its header counts {claimed['face']} faces, but {size - expected} "
                        "more bytes follow them; the header is wrong, re-export it")


#: formats whose coordinates are 32-bit floats (binary STL and glTF always, binary PLY as written)
FLOAT32_TYPES = ("stl", "glb", "gltf", "ply")


#: the typical edge length is the median of at most about this many faces' first edges, evenly
#: spread
PRECISION_SAMPLE_FACES = 100_000


def check_precision(path: Path, file_type: str, mesh: trimesh.Trimesh) -> None:
    """Refuse coordinates so far from the origin that 32-bit floats cannot resolve the mesh's edges
    to 1 % (an object placed kilometres away in its scene's units)."""
    if file_type not in FLOAT32_TYPES or len(mesh.faces) == 0:
        return
    vertices = np.asarray(mesh.vertices)
    # a typical edge
    faces = np.asarray(mesh.faces)[::max(1, len(mesh.faces) // PRECISION_SAMPLE_FACES)]
    edges = np.linalg.norm(vertices[faces[:, 1]] - vertices[faces[:, 0]], axis=1)
    typical = float(np.median(edges[edges > 0])) if (edges > 0).any() else 0.0
    far = float(np.abs(vertices).max())
    if typical > 0 and far * 2.0**-23 > 0.01 * typical:
        raise MeshError(f"{path}: coordinates reach {far:.3g} while its edges are about "
                        f"{typical:.3g} long: 32-bit "
                        "floats cannot hold that detail so far out; move the object near the "
                        "origin and re-export")


def check_readable(path: Path) -> None:
    """Raise MeshError unless ``path`` is a regular file this process can read."""
    if not path.exists():
        raise MeshError(f"{path}: no such file; check the path")
    if path.is_dir():
        if not os.access(path, os.R_OK | os.X_OK):
            raise MeshError(f"{path}: a folder that cannot be read (permission denied), so its "
                            "meshes are left out; check its permissions")
        raise MeshError(f"{path}: is a folder, not a mesh file; give a mesh file inside it")
    try:
        with open(path, "rb") as fh:
            fh.read(1)
    except OSError as exc:
        raise MeshError(f"{path}: cannot be read ({exc.strerror or exc}); check its "
                        "permissions") from None
    if not path.is_file():
        raise MeshError(f"{path}: not a regular file (a device or a pipe); give a mesh file")
