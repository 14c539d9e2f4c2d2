"""Game levels: one glTF/GLB scene holding many objects, each mesh node its own object.

A *node object* is one node of the scene graph that carries a mesh, in world coordinates (every
transform from the scene's root down to it applied). It is named by the node's name, which glTF
exporters keep from the editor and trimesh makes unique within the scene, so the name is stable
across runs of the same file. Its *path* is the chain of node names from the root, joined by
``/``, which an engine can follow to find the node again. An instanced mesh (one mesh under
several nodes) gives one object per node.

A glTF node whose mesh has several primitives (one per material: a jar's glass and its lid) is one
object: trimesh reads each primitive into a child node of its own, named after the node with a
random suffix that changes on every read, so :func:`merged_primitives` joins them back into the node
itself, in the file's order of primitives.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

import numpy as np
import trimesh


@dataclass(frozen=True)
class LevelNode:
    """A mesh node of a scene: its name, its path from the root and how many triangles it holds."""

    name: str
    path: str
    faces: int


def merged_primitives(scene: trimesh.Scene) -> trimesh.Scene:
    """``scene`` (read from a glTF file by trimesh) with each node's primitives joined into the node
    itself (module notes): the children trimesh made for them (``<node>_<6 hex digits>``, holding a
    mesh, under a node that holds none) become one mesh of the node, in the order the file lists
    them. Changed in place."""
    graph = scene.graph
    parents = graph.transforms.parents
    holding = set(graph.nodes_geometry)
    # trimesh reads the primitives in the file's order
    order = {name: k for k, name in enumerate(scene.geometry)}
    groups: dict[str, list[str]] = {}
    for node in holding:
        parent = parents.get(node)
        if parent is not None and parent not in holding and re.fullmatch(re.escape(str(parent))
                                                                         + r"_[0-9a-f]{6}",
                                                                          str(node)):
            groups.setdefault(parent, []).append(node)
    for parent in sorted(groups):
        kids = sorted(groups[parent], key=lambda n: order.get(graph[n][1], len(order)))
        meshes = []
        for kid in kids:
            local, geometry = graph.get(frame_to=kid, frame_from=parent)
            mesh = scene.geometry.get(geometry)
            if isinstance(mesh, trimesh.Trimesh):
                meshes.append(mesh.copy().apply_transform(local))
        if not meshes:
            continue
        name = f"{parent}::primitives"
        scene.geometry[name] = trimesh.util.concatenate(meshes) if len(meshes) > 1 else meshes[0]
        matrix, _ = graph.get(frame_to=parent, frame_from=parents[parent])
        for kid in kids:
            graph.transforms.remove_node(kid)
        graph.update(frame_from=parents[parent], frame_to=parent, matrix=matrix, geometry=name)
    return scene


#: the roles of the nodes pinchmatch adds to a level (``level.glb``'s props, their meshes, the
#: carousel's objects)
ADDED_ROLES = ("prop", "prop_mesh", "carousel")


def placed_by_pinchmatch(scene: trimesh.Scene, node: str) -> bool:
    """Whether ``node`` is, or lies below, a node pinchmatch added to the level (a ``level.glb``
    read back: ``extras.pinchmatch.role`` one of ``ADDED_ROLES``): a prop or a carousel copy, not
    one of the level's objects."""
    parents, edges = scene.graph.transforms.parents, scene.graph.transforms.edge_data
    while node in parents:
        parent = parents[node]
        extras = (edges.get((parent, node)) or {}).get("metadata")
        mark = extras.get("pinchmatch") if isinstance(extras, dict) else None
        if isinstance(mark, dict) and mark.get("role") in ADDED_ROLES:
            return True
        node = parent
    return False


def _path(scene: trimesh.Scene, node: str) -> str:
    parents = scene.graph.transforms.parents
    chain = [node]
    while chain[-1] in parents and parents[chain[-1]] != scene.graph.base_frame:
        chain.append(parents[chain[-1]])
    return "/".join(reversed(chain))


def level_nodes(scene: trimesh.Scene) -> list[LevelNode]:
    """Every node of ``scene`` that carries triangles, in the order of their paths; not a node its
    transforms scale to nothing in some direction (an object hidden by a zero scale: no solid to
    pinch is seen), nor one pinchmatch placed there (:func:`placed_by_pinchmatch`)."""
    out = []
    for node in scene.graph.nodes_geometry:
        transform, geometry = scene.graph[node]
        mesh = scene.geometry.get(geometry)
        singular = np.linalg.svd(np.asarray(transform, dtype=np.float64)[:3, :3], compute_uv=False)
        if singular[0] == 0.0 or singular[-1] <= 1e-9 * singular[0] or placed_by_pinchmatch(scene,
                                                                                            node):
            continue
        if isinstance(mesh, trimesh.Trimesh) and len(mesh.faces):
            out.append(LevelNode(str(node), _path(scene, node), int(len(mesh.faces))))
    return sorted(out, key=lambda n: (n.path, n.name))


#: the level read last, by its file's identity and state: a level of many nodes is read once per
#: process, not once per node (each node's object reads only its own triangles out of it)
_LAST_LEVEL: dict = {}


def remembered_scene(path, read, *, split: bool) -> trimesh.Scene:
    """The scene of the level file ``path``, read by ``read()`` unless it is the level read last
    (with the same ``split`` checks) and the file has not changed since (same inode, size and
    modification time). Nothing is kept but that one level."""
    info = os.stat(path)
    key = (os.path.realpath(path), info.st_ino, info.st_size, info.st_mtime_ns, split)
    if key not in _LAST_LEVEL:
        scene = read()
        _LAST_LEVEL.clear()
        _LAST_LEVEL[key] = scene
    return _LAST_LEVEL[key]


def node_mesh(scene: trimesh.Scene, node: str) -> trimesh.Trimesh | None:
    """The triangles of ``node`` in world coordinates, or None when the scene has no such mesh
    node."""
    if node not in scene.graph.nodes_geometry:
        return None
    transform, geometry = scene.graph[node]
    mesh = scene.geometry.get(geometry)
    if not isinstance(mesh, trimesh.Trimesh):
        return None
    vertices = np.asarray(mesh.vertices, dtype=np.float64) @ transform[:3, :3].T + transform[:3, 3]
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if np.linalg.det(transform[:3, :3]) < 0:  # a mirroring transform turns the winding inside out
        faces = faces[:, ::-1]
    return trimesh.Trimesh(vertices=vertices, faces=faces, process=False)


def scene_node_digests(scene: trimesh.Scene) -> dict[str, str]:
    """{node: SHA-256 of its triangles in world coordinates} for every mesh node of ``scene``: what
    a node is, whatever else the level holds or where in the file it sits (a cache key per node)."""
    import hashlib

    out = {}
    for node in level_nodes(scene):
        mesh = node_mesh(scene, node.name)
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(mesh.vertices, dtype="<f8").tobytes())
        h.update(np.ascontiguousarray(mesh.faces, dtype="<i8").tobytes())
        out[node.name] = h.hexdigest()
    return out
