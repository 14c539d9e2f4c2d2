"""A level's glTF document, kept as its file holds it and added to: what ``level.glb`` is written
from.

Re-exporting a level through a mesh library loses what it has no field for (cameras, lights, the
nodes' and the document's extras, extra scenes, unnamed nodes' lack of a name, a node's TRS as
written), so :class:`GltfLevel` keeps the document and only appends: meshes (their arrays in the one
binary buffer), nodes, roots of the default scene, extras and extensions. Its buffers become one
binary buffer, 4-byte aligned, each buffer view moved by its buffer's start; the files of a .gltf's
external buffers and images are embedded (an image as a buffer view with its MIME type). Data URIs
are decoded into the buffer too.

A level's nodes are named as the matching names them (:mod:`pinchmatch.mesh.level`, which reads
through trimesh): a node's ``name``, else its index, made unique in the order of the nodes as
trimesh makes them.

Nodes and meshes that pinchmatch added to a level before (``extras.pinchmatch.role``: a level.glb
fed back in) are dropped first, when they are at the end of their lists, as pinchmatch writes them;
else they are kept and the level's own are matched as written.
"""

from __future__ import annotations

import json
import mimetypes
import struct
import urllib.parse
from pathlib import Path

import numpy as np
from trimesh.util import unique_name

from ..errors import MeshError
from ..mesh.gltf_apply import buffer_bytes, uri_bytes
from ..mesh.gltf_check import gltf_document

#: what pinchmatch marks its own nodes and meshes with, in their extras
ROLES = ("prop", "prop_mesh", "carousel", "joint")


def _local(node: dict) -> np.ndarray:
    """A node's matrix (column vectors) from its ``matrix``, else its translation, rotation and
    scale."""
    from scipy.spatial.transform import Rotation

    if "matrix" in node:
        return np.array(node["matrix"], dtype=np.float64).reshape(4, 4).T
    M = np.eye(4)
    M[:3, :3] = Rotation.from_quat(node.get("rotation", [0.0, 0.0, 0.0, 1.0])).as_matrix() * \
        np.asarray(node.get("scale", [1.0, 1.0, 1.0]), dtype=np.float64)
    M[:3, 3] = node.get("translation", [0.0, 0.0, 0.0])
    return M


def _ours(item) -> bool:
    extras = item.get("extras") if isinstance(item, dict) else None
    return isinstance(extras, dict) and isinstance(extras.get("pinchmatch"), dict) and \
        extras["pinchmatch"].get("role") in ROLES


class GltfLevel:
    """A level's document and its one binary buffer, appended to (module notes)."""

    def __init__(self, document: dict, blob: bytearray):
        self.document, self.blob = document, blob
        self.document.setdefault("nodes", [])
        self.nodes = self.document["nodes"]
        self._drop_earlier()
        names: dict[str, int] = {}
        counts: dict = {}
        for i, node in enumerate(self.nodes):
            names[unique_name(node.get("name", str(i)), names, counts=counts)] = i
        #: {the node's name in the matching: its index}
        self.index = names
        #: {node index: its world matrix (the file's units), down from the default scene's roots}
        self.world = {}
        stack = [(r, np.eye(4)) for r in self._scene().get("nodes", [])]
        while stack:
            i, parent = stack.pop()
            if i in self.world:
                continue
            self.world[i] = parent @ _local(self.nodes[i])
            stack.extend((c, self.world[i]) for c in self.nodes[i].get("children", []))

    @classmethod
    def read(cls, path: Path) -> "GltfLevel":
        file_type = "glb" if path.suffix.lower() == ".glb" else "gltf"
        document = gltf_document(path, file_type)
        try:
            return cls(*_one_buffer(path, file_type, document))
        except (KeyError, IndexError, TypeError, ValueError, OSError) as exc:
            raise MeshError(f"{path}: its buffers cannot be read for level.glb "
                            f"({type(exc).__name__}: "
                            f"{str(exc)[:60]}); the file is corrupt, re-export it") from None

    def _scene(self) -> dict:
        scenes = self.document.setdefault("scenes", [{"nodes": []}])
        return scenes[self.document.get("scene", 0)]

    def _drop_earlier(self) -> None:
        """Drop the nodes and meshes pinchmatch added last time, where they end their lists."""
        n = len(self.nodes)
        while n and _ours(self.nodes[n - 1]):
            n -= 1
        if n < len(self.nodes):
            del self.nodes[n:]
            for node in self.nodes:
                if "children" in node:
                    node["children"] = [c for c in node["children"] if c < n]
                    if not node["children"]:
                        del node["children"]
                extras = node.get("extras")
                if isinstance(extras, dict):
                    extras.pop("pinchmatch", None)
                    if not extras:
                        del node["extras"]
            for scene in self.document.get("scenes", []):
                scene["nodes"] = [r for r in scene.get("nodes", []) if r < n]
        meshes = self.document.get("meshes", [])
        m = len(meshes)
        while m and _ours(meshes[m - 1]):
            m -= 1
        if not any(node.get("mesh", -1) >= m for node in self.nodes):
            del meshes[m:]

    def _view(self, data: bytes, target: int | None = None) -> int:
        self.blob.extend(b"\0" * (-len(self.blob) % 4))
        view = {"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        self.blob.extend(data)
        views = self.document.setdefault("bufferViews", [])
        views.append(view)
        return len(views) - 1

    def add_mesh(self, vertices: np.ndarray, faces: np.ndarray, name: str) -> int:
        """A mesh of one primitive (positions in the file's units, triangles); returns its index."""
        v = np.ascontiguousarray(vertices, dtype="<f4")
        f = np.ascontiguousarray(faces, dtype="<u4").reshape(-1)
        accessors = self.document.setdefault("accessors", [])
        accessors.append({"bufferView": self._view(v.tobytes(), 34962), "componentType": 5126,
                          "count": len(v), "type": "VEC3",
                          "min": v.min(axis=0).astype(float).tolist(),
                          "max": v.max(axis=0).astype(float).tolist()})
        accessors.append({"bufferView": self._view(f.tobytes(), 34963), "componentType": 5125,
                          "count": len(f), "type": "SCALAR"})
        meshes = self.document.setdefault("meshes", [])
        meshes.append({"name": name, "primitives": [{"attributes": {"POSITION": len(accessors) - 2},
                                                     "indices": len(accessors) - 1}],
                       "extras": {"pinchmatch": {"role": "prop_mesh"}}})
        return len(meshes) - 1

    def add_node(self, node: dict) -> int:
        self.nodes.append(node)
        return len(self.nodes) - 1

    def add_root(self, index: int) -> None:
        self._scene().setdefault("nodes", []).append(index)

    def set_extras(self, index: int, value: dict) -> None:
        """``extras.pinchmatch`` of a node, beside its own extras (kept under ``value`` if not an
        object)."""
        node = self.nodes[index]
        extras = node.get("extras", {})
        node["extras"] = {**(extras if isinstance(extras, dict) else {"value": extras}),
                          "pinchmatch": value}

    def add_extensions(self, index: int, extensions: dict) -> None:
        node = self.nodes[index]
        node["extensions"] = {**(node.get("extensions") or {}), **extensions}

    def set_scene_extras(self, value: dict) -> None:
        scene = self._scene()
        extras = scene.get("extras", {})
        scene["extras"] = {**(extras if isinstance(extras, dict) else {"value": extras}),
                           "pinchmatch": value}

    def glb(self) -> bytes:
        """The document as GLB bytes; every extension its nodes use listed as used."""
        used = {key for node in self.nodes for key in (node.get("extensions") or {})}
        if used:
            self.document["extensionsUsed"] = sorted(set(self.document.get("extensionsUsed", []))
                                                     | used)
        self.document["buffers"] = [{"byteLength": len(self.blob)}] if self.blob else []
        if not self.blob:
            self.document.pop("buffers")
        text = json.dumps(self.document, separators=(",", ":"), sort_keys=True).encode()
        text += b" " * (-len(text) % 4)  # a JSON chunk is padded with spaces to four bytes
        blob = bytes(self.blob) + b"\0" * (-len(self.blob) % 4)
        body = struct.pack("<I4s", len(text), b"JSON") + text
        if blob:
            body += struct.pack("<I4s", len(blob), b"BIN\0") + blob
        return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def _one_buffer(path: Path, file_type: str, document: dict) -> tuple[dict, bytearray]:
    """The document with its buffers (and a .gltf's image files) in one binary buffer (module
    notes)."""
    blob, starts = bytearray(), []
    for buffer, data in zip(document.get("buffers") or [], buffer_bytes(path, file_type, document)):
        blob.extend(b"\0" * (-len(blob) % 4))
        starts.append(len(blob))
        blob.extend(data[:buffer.get("byteLength", len(data))])
    for view in document.get("bufferViews") or []:
        view["byteOffset"] = view.get("byteOffset", 0) + starts[view["buffer"]]
        view["buffer"] = 0
    document.pop("buffers", None)
    for image in document.get("images") or []:
        uri = image.get("uri")
        if isinstance(uri, str) and (file_type == "gltf" or uri.startswith("data:")):
            data = uri_bytes(path, uri)
            mime = uri[5:].split(";")[0] if uri.startswith("data:") else \
                mimetypes.guess_type(urllib.parse.unquote(uri))[0] or "application/octet-stream"
            blob.extend(b"\0" * (-len(blob) % 4))
            views = document.setdefault("bufferViews", [])
            views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
            blob.extend(data)
            image.pop("uri")
            image.update(bufferView=len(views) - 1, mimeType=image.get("mimeType", mime))
    return document, blob
