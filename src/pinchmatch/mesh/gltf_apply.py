"""What the specification says a glTF reader applies and trimesh does not: sparse accessors and
morph targets' default weights, applied to the document before trimesh reads it.

A sparse accessor stores only the elements that differ from its base (a buffer view, or zeros); a
mesh's ``weights`` are the default weights of its morph targets, and its vertices are the base
positions plus the weighted targets' displacements. trimesh reads the base alone (wrong geometry, no
error). So a document with either is rewritten in memory: every accessor it reads is made dense, the
positions of a morphed primitive get its targets' weighted displacements, and the result is handed
to trimesh as one GLB whose single binary buffer holds the original buffers and the new arrays. Node
``weights`` (per instance) differ from mesh to node, so one mesh would need two geometries: refused
(:mod:`gltf_check`).
"""

from __future__ import annotations

import base64
import json
import struct
import urllib.parse
from pathlib import Path

import numpy as np

from ..errors import MeshError

#: glTF component types and element sizes
COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
              5126: np.float32}
ELEMENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


def needs_applying(document: dict) -> bool:
    """Whether the document has sparse accessors or meshes with non-zero default morph weights."""
    accessors = document.get("accessors") or []
    meshes = document.get("meshes") or []
    return any(isinstance(a, dict) and "sparse" in a for a in accessors) or any(
        isinstance(m, dict) and any(m.get("weights") or []) for m in meshes)


def buffer_bytes(path: Path, file_type: str, document: dict) -> list[bytes]:
    """The bytes of each buffer: a GLB's binary chunk, data URIs, or files beside ``path``."""
    out = []
    chunk = b""
    if file_type == "glb":
        data = path.read_bytes()
        offset = 12
        while offset + 8 <= len(data):
            length, kind = struct.unpack("<I4s", data[offset:offset + 8])
            if kind == b"BIN\0":
                chunk = data[offset + 8:offset + 8 + length]
            offset += 8 + length + (-length % 4)
    for buffer in document.get("buffers") or []:
        uri = buffer.get("uri")
        if uri is None:
            out.append(chunk)
        else:
            out.append(uri_bytes(path, uri))
    return out


def uri_bytes(path: Path, uri: str) -> bytes:
    """The bytes a glTF URI of the file ``path`` names: a data URI's, or a file's beside
    ``path``."""
    if uri.startswith("data:"):
        return base64.b64decode(uri.split(",", 1)[1])
    return (path.parent / urllib.parse.unquote(uri)).read_bytes()


def _view(document: dict, buffers: list[bytes], index: int) -> bytes:
    view = document["bufferViews"][index]
    start = view.get("byteOffset", 0)
    return buffers[view["buffer"]][start:start + view["byteLength"]]


def _read(document: dict, buffers: list[bytes], view: int | None, offset: int, count: int,
          component: int, per: int) -> np.ndarray:
    """(count, per) elements of one accessor's layout, strided as its buffer view says."""
    dtype = np.dtype(COMPONENTS[component])
    if view is None:
        return np.zeros((count, per), dtype=dtype)
    data = _view(document, buffers, view)
    stride = document["bufferViews"][view].get("byteStride") or dtype.itemsize * per
    rows = np.frombuffer(data, dtype=np.uint8)
    need = offset + (count - 1) * stride + dtype.itemsize * per if count else 0
    if need > len(rows):
        raise MeshError("an accessor reads past its buffer view")
    out = np.lib.stride_tricks.as_strided(rows[offset:], (count, dtype.itemsize * per), (stride, 1))
    return np.ascontiguousarray(out).view(dtype).reshape(count, per)


def dense_accessor(document: dict, buffers: list[bytes], index: int) -> np.ndarray:
    """Accessor ``index`` as a dense (count, elements) array, its sparse elements substituted."""
    a = document["accessors"][index]
    per = ELEMENTS[a["type"]]
    base = _read(document, buffers, a.get("bufferView"), a.get("byteOffset", 0), a["count"],
                 a["componentType"], per).copy()
    sparse = a.get("sparse")
    if sparse:
        n = sparse["count"]
        at = _read(document, buffers, sparse["indices"]["bufferView"],
                   sparse["indices"].get("byteOffset", 0), n, sparse["indices"]["componentType"],
                   1).ravel().astype(np.int64)
        values = _read(document, buffers, sparse["values"]["bufferView"],
                       sparse["values"].get("byteOffset", 0), n, a["componentType"], per)
        if (at >= len(base)).any():
            raise MeshError("a sparse accessor's index points past its accessor")
        base[at] = values
    return base


def applied_glb(path: Path, file_type: str, document: dict) -> bytes:
    """The document as one GLB with sparse accessors dense and default morph weights applied (module
    notes)."""
    try:
        buffers = buffer_bytes(path, file_type, document)
        doc = json.loads(json.dumps(document))
        blob = bytearray()
        starts = []
        for data in buffers:  # the original buffers, one after the other, 4-byte aligned
            starts.append(len(blob))
            blob += data + b"\0" * (-len(data) % 4)
        for view in doc.get("bufferViews") or []:
            view["byteOffset"] = view.get("byteOffset", 0) + starts[view["buffer"]]
            view["buffer"] = 0

        def store(array: np.ndarray, accessor: dict) -> None:
            data = np.ascontiguousarray(array).tobytes()
            doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob),
                                       "byteLength": len(data)})
            blob.extend(data + b"\0" * (-len(data) % 4))
            accessor.pop("sparse", None)
            accessor.update(bufferView=len(doc["bufferViews"]) - 1, byteOffset=0)

        for k, a in enumerate(doc.get("accessors") or []):
            if "sparse" in a:
                store(dense_accessor(document, buffers, k), a)
        for mesh in doc.get("meshes") or []:
            weights = np.asarray(mesh.pop("weights", None) or [], dtype=np.float64)
            for primitive in mesh.get("primitives") or []:
                targets = primitive.pop("targets", None) or []
                if not weights.any() or "POSITION" not in primitive["attributes"]:
                    continue
                base = dense_accessor(document, buffers,
                                      primitive["attributes"]["POSITION"]).astype(np.float64)
                for w, target in zip(weights, targets):
                    if w and "POSITION" in target:
                        base += w * dense_accessor(document, buffers,
                                                   target["POSITION"]).astype(np.float64)
                moved = dict(doc["accessors"][primitive["attributes"]["POSITION"]],
                             componentType=5126, min=base.min(axis=0).tolist(),
                             max=base.max(axis=0).tolist())
                moved.pop("normalized", None)
                doc["accessors"].append(moved)
                store(base.astype(np.float32), moved)
                primitive["attributes"]["POSITION"] = len(doc["accessors"]) - 1
        doc["buffers"] = [{"byteLength": len(blob)}]
    except (KeyError, IndexError, TypeError, ValueError, OSError) as exc:
        raise MeshError(f"{path}: its sparse accessors or morph targets cannot be read "
                        f"({type(exc).__name__}: "
                        f"{str(exc)[:60]}); the file is corrupt, re-export it") from None
    except MeshError as exc:
        raise MeshError(f"{path}: {exc}; the file is corrupt, re-export it") from None
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(blob),
                                                                        b"BIN\0") + bytes(blob)
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body
