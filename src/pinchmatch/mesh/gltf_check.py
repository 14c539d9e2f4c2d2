"""A glTF or GLB document checked before trimesh reads it: its node hierarchy and its buffers.

trimesh builds a level's scene graph from the document's ``nodes`` without checking that they form a
forest: a cycle of children makes it (and any walk up the hierarchy) loop for ever, and its world
transforms cost more than linear time in the depth (a chain 1,000 nodes deep takes minutes). So the
document is read first, and refused in one line when a node names a child that does not exist, when
a node has two parents or the children form a cycle, or when the level is larger than
:data:`MAX_NODES` nodes or deeper than :data:`MAX_DEPTH` (real levels are a few dozen deep). The
walk is iterative and linear in the number of nodes. External buffers and images (of a ``.gltf`` or
a ``.glb``) are looked for as the specification says, their URIs percent-decoded, and only beside
the file. A document the checks cannot read (over 64 MiB, not UTF-8, not JSON) is refused, never
handed on.
"""

from __future__ import annotations

import json
import struct
import urllib.parse
from pathlib import Path

import trimesh

from ..errors import MeshError

#: the most nodes a level may hold
MAX_NODES = 100_000
#: the deepest chain of nodes a level may hold (root at depth 1)
MAX_DEPTH = 256
#: a GLB's JSON chunk larger than this is not read ahead of trimesh (its own reader bounds it)
MAX_JSON_BYTES = 64 * 2**20


def gltf_document(path: Path, file_type: str) -> dict:
    """The JSON document of a .gltf, or of a .glb's first chunk. What cannot be read as one (too
    large, not UTF-8, not JSON, a GLB without its JSON chunk) is refused in one line: a document the
    checks cannot read is never handed to the reader unchecked."""
    def refuse(problem: str):
        return MeshError(f"{path}: {problem}; it is not a glTF document pinchmatch can check: "
                         "re-export it from the editor (glTF 2.0)")

    try:
        if file_type == "gltf":
            if path.stat().st_size > MAX_JSON_BYTES:
                raise refuse(f"its JSON is over {MAX_JSON_BYTES // 2**20} MiB")
            raw = path.read_bytes()
        else:
            with open(path, "rb") as fh:
                header = fh.read(20)
                if len(header) < 20 or header[:4] != b"glTF":
                    raise refuse("no GLB header (the file does not start with 'glTF')")
                length, kind = struct.unpack("<I4s", header[12:20])
                if kind != b"JSON":
                    raise refuse("its first chunk is not the JSON chunk")
                if length > MAX_JSON_BYTES:
                    raise refuse(f"its JSON chunk is over {MAX_JSON_BYTES // 2**20} MiB")
                raw = fh.read(length)
                if len(raw) < length:
                    raise refuse("its JSON chunk is cut short (the file is truncated)")
        document = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise refuse(f"its JSON is not UTF-8 (byte {exc.start})") from None
    except RecursionError:
        raise refuse("its JSON is nested too deeply") from None
    except ValueError as exc:
        raise refuse(f"its JSON is not valid ({str(exc)[:60]})") from None
    except OSError as exc:
        raise MeshError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if not isinstance(document, dict):
        raise refuse("its JSON is not an object")
    return document


def external_files(path: Path, document: dict,
                   kinds=("buffers", "images")) -> list[tuple[str, Path]]:
    """(uri, file) of every external buffer and image (``kinds``) the document names, URIs
    percent-decoded as the specification says and taken beside the file (a GLB's external buffers
    the same as a .gltf's)."""
    out = []
    for kind in kinds:
        entries = document.get(kind, [])
        for entry in entries if isinstance(entries, list) else []:
            uri = entry.get("uri") if isinstance(entry, dict) else None
            if isinstance(uri, str) and not uri.startswith("data:"):
                out.append((uri, path.parent / urllib.parse.unquote(uri)))
    return out


def check_hierarchy(path: Path, document: dict) -> None:
    """Refuse a node hierarchy that is not a forest of bounded size and depth (module notes)."""
    nodes = document.get("nodes", [])
    if not isinstance(nodes, list):
        raise MeshError(f"{path}: 'nodes' is not a list; the file is corrupt, re-export it")
    n = len(nodes)
    if n > MAX_NODES:
        raise MeshError(f"{path}: the level holds {n} nodes, more than {MAX_NODES}; split it into "
                        "smaller levels")
    parent = [-1] * n
    children: list[list[int]] = []
    for i, node in enumerate(nodes):
        kids = node.get("children", []) if isinstance(node, dict) else []
        if not isinstance(kids, list) or not all(isinstance(k, int) and not isinstance(k, bool)
                                                 for k in kids):
            raise MeshError(f"{path}: node {i}'s children are not a list of node indices; "
                            "re-export the level")
        for k in kids:
            if not 0 <= k < n:
                raise MeshError(f"{path}: node {i} names child node {k}, and the level has nodes 0 "
                                f"to {n - 1}; the file is corrupt, re-export it")
            if parent[k] != -1 or k == i:
                raise MeshError(f"{path}: node {k} is a child of two nodes "
                                f"({parent[k] if k != i else i} and {i}) or "
                                "of itself, so the nodes do not form a tree; re-export the level")
            parent[k] = i
        children.append(kids)
    depth = [0] * n
    stack = [i for i in range(n) if parent[i] == -1]
    for root in stack:
        depth[root] = 1
    reached = 0
    while stack:
        i = stack.pop()
        reached += 1
        if depth[i] > MAX_DEPTH:
            raise MeshError(f"{path}: the level's nodes nest more than {MAX_DEPTH} deep (node "
                            f"{i}); flatten the hierarchy when exporting it")
        for k in children[i]:
            depth[k] = depth[i] + 1
            stack.append(k)
    if reached < n:
        loop = next(i for i in range(n) if depth[i] == 0)
        raise MeshError(f"{path}: the nodes' children form a cycle (through node {loop}), so the "
                        "level is not a tree; re-export it")


def check_unique_names(path: Path, document: dict) -> None:
    """Refuse a level to be split whose mesh nodes share a name: each becomes an object named by its
    node, and trimesh would make up ``name_1`` for the second, a name the file does not have."""
    nodes = document.get("nodes", [])
    names = [n.get("name") for n in nodes if isinstance(n, dict)
             and "mesh" in n] if isinstance(nodes, list) else []
    seen, twice = set(), []
    for name in names:
        if isinstance(name, str) and name in seen and name not in twice:
            twice.append(name)
        seen.add(name)
    if twice:
        raise MeshError(f"{path}: several mesh nodes are named {', '.join(map(repr, twice[:3]))}; "
                        "each node becomes an "
                        "object named by its node, so give them distinct names in the editor and "
                        "export again")


def check_buffers(path: Path, document: dict) -> None:
    """Refuse an external buffer or image that lies outside the file's folder, and name a buffer the
    file needs and lacks (the reader would only say 'not found'); for a .gltf and a .glb alike."""
    folder = path.parent.resolve()
    for uri, file in external_files(path, document):
        if not file.resolve().is_relative_to(folder):
            raise MeshError(f"{path}: its file {uri!r} lies outside the file's folder ({folder}); "
                            "a glTF names its "
                            "files beside it: copy the file there, or export a .glb that holds it")
    for uri, file in external_files(path, document, kinds=("buffers",)):
        if not file.is_file():
            raise MeshError(f"{path}: its buffer file {uri!r} is missing (looked for {file}); copy "
                            "it next to the file, or export a .glb, which holds its buffers")


#: extensions a file may require that change nothing pinchmatch reads (materials, textures, lights)
HARMLESS_EXTENSIONS = ("KHR_materials_", "KHR_texture_", "KHR_lights_punctual", "EXT_texture_webp",
                       "KHR_materials_variants")
#: what the reader does not apply, and how to export instead
UNSUPPORTED = {
    "KHR_draco_mesh_compression": "Draco-compressed meshes",
    "EXT_meshopt_compression": "meshopt-compressed buffers",
    "KHR_meshopt_compression": "meshopt-compressed buffers",
    "EXT_mesh_gpu_instancing": "GPU instancing (one mesh drawn at many places)",
    "KHR_mesh_quantization": "quantized vertex positions",
}


def check_features(path: Path, document: dict) -> None:
    """Refuse, naming it, what the reader would not apply and so read as other geometry: a required
    extension it does not know or cannot apply (Draco, meshopt, quantization), GPU instancing on a
    node, per-node morph weights, and skinned nodes (whose transform the specification says to
    ignore). Sparse accessors and meshes' default morph weights are applied (:mod:`gltf_apply`)."""
    def refuse(what: str):
        raise MeshError(f"{path}: uses {what}, which pinchmatch does not apply (the geometry would "
                        "be read wrong); "
                        "export it again without it (apply modifiers, skins and morphs; no "
                        "compression)")

    required = document.get("extensionsRequired", [])
    for name in required if isinstance(required, list) else []:
        if isinstance(name, str) and not name.startswith(HARMLESS_EXTENSIONS):
            refuse(f"the required extension {name}"
                   + (f" ({UNSUPPORTED[name]})" if name in UNSUPPORTED else ""))
    nodes = document.get("nodes", [])
    for k, node in enumerate(nodes if isinstance(nodes, list) else []):
        if isinstance(node, dict) and "EXT_mesh_gpu_instancing" in (node.get("extensions") or {}):
            refuse(f"GPU instancing (EXT_mesh_gpu_instancing) on node {node.get('name', k)!r}")
        if isinstance(node, dict) and "skin" in node and "mesh" in node:
            refuse(f"a skinned mesh on node {node.get('name', k)!r}")
        if isinstance(node, dict) and node.get("weights"):
            refuse(f"morph weights of its own on node {node.get('name', k)!r} (a mesh's default "
                   "weights are applied)")
    for kind in ("accessors", "meshes"):  # what gltf_apply reads
        entries = document.get(kind, [])
        if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
            raise MeshError(f"{path}: its {kind} are not a list of objects; the file is corrupt, "
                            "re-export it")


def check_gltf(path: Path, file_type: str, *, split: bool = False) -> dict:
    """Check a glTF or GLB document before it is read (hierarchy, what the reader does not apply,
    external files, and for a level to be split, its mesh nodes' names); return the document."""
    document = gltf_document(path, file_type)
    check_hierarchy(path, document)
    check_features(path, document)
    if split:
        check_unique_names(path, document)
    check_buffers(path, document)
    return document


class PercentDecoding(trimesh.resolvers.FilePathResolver):
    """trimesh's resolver of a .gltf's files, with the URIs percent-decoded as the specification
    says (``a%20b.bin`` is the file ``a b.bin``)."""

    def get(self, name: str):
        return super().get(urllib.parse.unquote(name))
