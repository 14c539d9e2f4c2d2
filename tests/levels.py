"""A generated game level: a glTF 2.0 binary written by hand (not by trimesh), so that what the
loader makes of it can be checked against matrices composed here.

Two meshes (a crate and a jar, in metres), each instanced under many nodes; nodes nested three
deep with translations, rotations (quaternions) and scales; one node mirrored.
"""

from __future__ import annotations

import json
import math
import struct

import numpy as np
import trimesh


def _quaternion(axis, angle_deg):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    h = math.radians(angle_deg) / 2.0
    return [*(axis * math.sin(h)), math.cos(h)]  # glTF order: x, y, z, w


def _trs(node: dict) -> np.ndarray:
    """The local matrix of a glTF node from its translation, rotation and scale."""
    T = np.eye(4)
    T[:3, 3] = node.get("translation", [0, 0, 0])
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    R = np.eye(4)
    R[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    S = np.diag([*node.get("scale", [1, 1, 1]), 1.0])
    return T @ R @ S


def _meshes():
    crate = trimesh.creation.box(extents=(0.06, 0.04, 0.05))
    jar = trimesh.creation.cylinder(radius=0.02, height=0.07, sections=24)
    return [("crate", crate), ("jar", jar)]


def game_level(crates: int = 12, jars: int = 9) -> tuple[bytes, dict]:
    """(GLB bytes, expected) for a level of ``crates + jars`` mesh nodes; ``expected`` maps each
    mesh node's name to (its path from the root, its world vertices in metres, its mesh index)."""
    meshes = _meshes()
    blob, views, accessors, gltf_meshes = b"", [], [], []
    for name, mesh in meshes:
        v = np.asarray(mesh.vertices, np.float32)
        f = np.asarray(mesh.faces, np.uint32).ravel()
        for data, target, kind, count, extra in ((v, 34962, "VEC3", len(v),
                                                  {"min": v.min(0).tolist(),
                                                   "max": v.max(0).tolist()}),
                                                 (f, 34963, "SCALAR", len(f), {})):
            views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": data.nbytes,
                          "target": target})
            accessors.append({"bufferView": len(views) - 1, "componentType": 5126 if kind == "VEC3"
                              else 5125,
                              "count": count, "type": kind, **extra})
            blob += data.tobytes()
        gltf_meshes.append({"name": name,
                            "primitives": [{"attributes": {"POSITION": len(accessors) - 2},
                                                          "indices": len(accessors) - 1}]})
    nodes = [{"name": "Level", "children": [1, 2], "translation": [1.0, 0.0, -2.0]},
             {"name": "Storeroom", "children": [], "rotation": _quaternion([0, 1, 0], 30.0),
              "translation": [0.5, 0, 0]},
             {"name": "Shelf", "children": [], "translation": [0, 0.8, 0],
              "rotation": _quaternion([1, 0, 0], 10.0)}]
    for k in range(crates):
        nodes[1]["children"].append(len(nodes))
        node = {"name": f"Crate.{k:03d}", "mesh": 0,
                "translation": [0.1 * (k % 4), 0.0, 0.12 * (k // 4)],
                "rotation": _quaternion([0, 1, 0], 15.0 * k)}
        if k == 5:
            node["scale"] = [-1.0, 1.0, 1.0]  # mirrored in the editor
        if k == 7:
            node["scale"] = [1.5, 1.5, 1.5]
        nodes.append(node)
    for k in range(jars):
        nodes[2]["children"].append(len(nodes))
        nodes.append({"name": f"Jar_{k}", "mesh": 1, "translation": [0.07 * k, 0.0, 0.0]})
    document = {"asset": {"version": "2.0", "generator": "pinchmatch tests"}, "scene": 0,
                "scenes": [{"nodes": [0]}], "nodes": nodes, "meshes": gltf_meshes,
                "accessors": accessors, "bufferViews": views,
                "buffers": [{"byteLength": len(blob)}]}
    expected = {}

    def walk(i, parent_matrix, parent_path):
        node = nodes[i]
        M = parent_matrix @ _trs(node)
        path = f"{parent_path}/{node['name']}" if parent_path else node["name"]
        if "mesh" in node:
            v = np.asarray(meshes[node["mesh"]][1].vertices, np.float32).astype(float)
            expected[node["name"]] = (path, v @ M[:3, :3].T + M[:3, 3], node["mesh"])
        for c in node.get("children", []):
            walk(c, M, path)

    walk(0, np.eye(4), "")
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    glb = struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + 8 + len(blob))
    glb += struct.pack("<I4s", len(text), b"JSON") + text + struct.pack(
        "<I4s", len(blob), b"BIN\0") + blob
    return glb, expected


#: a prop's pose that stands a file's +Z up in a glTF world (+Y up): a quarter turn about X
Z_UP_IN_Y_UP = [-math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)]


def tabletop_level(path, places) -> None:
    """A level (GLB, metres, y up) of named meshes (metres, y up) placed at world translations:
    ``places`` is (name, mesh, (x, y, z) m) per node; written by trimesh's scene export."""
    scene = trimesh.Scene()
    for name, mesh, xyz in places:
        T = np.eye(4)
        T[:3, 3] = xyz
        scene.add_geometry(mesh, node_name=name, geom_name=f"{name}_mesh", transform=T)
    scene.export(path)


def counter_kitchen(path) -> None:
    """A kitchen (GLB): a counter 0.9 m up, a can and a box on it beside where a prop stands (0.5,
    0.9, -0.25), and a can 0.5 m farther off, beyond the redirection's reach."""
    box = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    box.apply_translation([0.0, 0.025, 0.0])
    counter = trimesh.creation.box(extents=(1.4, 0.04, 0.7))
    counter.apply_translation([0.0, -0.02, 0.0])
    tabletop_level(path, [("counter", counter, (0.5, 0.9, -0.25)),
                          ("can_near", standing_can(), (0.52, 0.9, -0.25)),
                          ("box_near", box, (0.47, 0.9, -0.23)),
                          ("can_far", standing_can(), (0.9, 0.9, -0.5))])


def standing_can(radius_m: float = 0.027, height_m: float = 0.066) -> trimesh.Trimesh:
    """A can (metres) standing on y = 0 with its axis along +Y, as a glTF level holds it."""
    can = trimesh.creation.cylinder(radius=radius_m, height=height_m, sections=64)
    can.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    can.apply_translation([0.0, height_m / 2.0, 0.0])
    return can


def glb_of(meshes, nodes, *, scenes=None, **document) -> bytes:
    """A GLB written by hand: ``meshes`` a list of glTF meshes, each a list of its primitives
    (trimesh meshes, one material each), ``nodes`` the glTF nodes (dicts, as the file holds them),
    ``scenes`` the scenes (default: one holding every node no other node holds); ``document`` any
    other top-level fields (cameras, extras, extensionsUsed...)."""
    blob, views, accessors, gltf_meshes, materials = b"", [], [], [], []
    for primitives in meshes:
        out = []
        for mesh in primitives:
            v = np.asarray(mesh.vertices, np.float32)
            f = np.asarray(mesh.faces, np.uint32).ravel()
            for data, target, kind, count, extra in (
                    (v, 34962, "VEC3", len(v),
                     {"min": v.min(0).tolist(), "max": v.max(0).tolist()}),
                    (f, 34963, "SCALAR", len(f), {})):
                views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": data.nbytes,
                              "target": target})
                accessors.append({"bufferView": len(views) - 1, "componentType": 5126 if kind
                                  == "VEC3" else 5125,
                                  "count": count, "type": kind, **extra})
                blob += data.tobytes()
            materials.append({"name": f"material_{len(materials)}"})
            out.append({"attributes": {"POSITION": len(accessors) - 2},
                        "indices": len(accessors) - 1, "material": len(materials) - 1})
        gltf_meshes.append({"primitives": out})
    held = {c for n in nodes for c in n.get("children", [])}
    doc = {"asset": {"version": "2.0", "generator": "pinchmatch tests"}, "scene": 0,
           "scenes": scenes if scenes is not None
           else [{"nodes": [i for i in range(len(nodes)) if i not in held]}],
           "nodes": nodes, "meshes": gltf_meshes, "materials": materials, "accessors": accessors,
           "bufferViews": views, "buffers": [{"byteLength": len(blob)}], **document}
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    glb = struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + 8 + len(blob))
    return glb + struct.pack("<I4s", len(text), b"JSON") + text + struct.pack(
        "<I4s", len(blob), b"BIN\0") + blob


def can_prop_manifest(position_mm=(0.0, 900.0, 0.0), quaternion_xyzw=None,
                      name: str = "can_prop") -> str:
    """A props manifest of one can (54 x 66 mm, its file's +Z up) posed in a y-up level: standing on
    the level's table at ``position_mm`` unless ``quaternion_xyzw`` turns it otherwise."""
    q = list(Z_UP_IN_Y_UP if quaternion_xyzw is None else quaternion_xyzw)
    return (f'[[object]]\nname = "{name}"\nshape = {{ kind = "cylinder", diameter_mm = 54, '
            f'height_mm = 66 }}\n'
            f"pose = {{ position_mm = {[float(c) for c in position_mm]}, quaternion_xyzw = {q} "
            f"}}\n")


def can_and_box_level(path, can_name: str = "can", box_at=(0.1, 0.9, 0.0)) -> None:
    """A level (GLB, metres, y up) of a standing can at (0, 0.9, 0) and a 50 mm box beside it, on y
    = 0.9."""
    box = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    box.apply_translation([0.0, 0.025, 0.0])
    tabletop_level(path, [(can_name, standing_can(), (0.0, 0.9, 0.0)), ("box", box, box_at)])
