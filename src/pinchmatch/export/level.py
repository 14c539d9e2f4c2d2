"""``OUT/level.glb``: a level as an engine loads it, with each prop at its pose and each node's
match.

Under ``--placement fixed`` the objects stay where a level puts them; an engine (Unity, Unreal, a
WebXR page) needs the level itself, the props where they stand, and per node what to do: redirect
the hand to the prop, or bring the object onto the prop (the carousel). This writes the level's own
file back with:

- every node and mesh of the level as the file holds them (its units, y up: the file's frame);
- one node per prop, ``pinchmatch_prop_<name>``, at its manifest ``pose`` (turned and moved into the
  level), with its mesh in its own frame below it: an engine moves that node with the tracked prop;
- below a prop's node, for each object the carousel brings onto it, a node ``carousel_<node>``
  holding the object's own mesh, whose transform shows it registered on the prop, resting on the
  table where the prop stands (:mod:`pinchmatch.match.rest`): parented to the tracked prop, it is in
  place;
- below each redirected node, and below the carousel node of each object the carousel brings (where
  it is pinched: on the prop, not where the level puts it), the grasp in the node's own frame, named
  as the OpenXR hand joints: ``thumb_tip``, ``index_tip`` (and ``middle_tip`` for a tripod) at the
  centres of the fingertip pads (each contact plus the fingertip radius along its normal),
  ``pinch_center`` between the contacts, and ``wrist`` along the hand's approach, ``WRIST_MM`` from
  the pinch's centre;
- the masses and centres of mass an engine's physics needs, on the prop and object nodes, under
  OMI_physics_body's ``motion`` (``type``, ``mass`` in kg where known, ``centerOfMass`` in the
  node's frame);
- in each matched node's ``extras.pinchmatch``: its ``mode`` (``redirect`` or ``carousel``), the
  prop, the cost, both costs and the reason, the redirection's angle and gain, the rest gap and, in
  the level's frame in metres, the virtual and physical pinch targets, the contacts and the hand's
  start; a prop node's and a carousel node's ``extras.pinchmatch`` say what they are; the scene's
  gives the schema, the units and the settings.

The level's own document is kept as its file holds it, and added to, never re-exported: every node
(its name or none, its TRS or matrix, its extras and extensions), every scene, camera, light,
material, texture and animation, the document's extras. Its buffers become the GLB's one binary
buffer, with the files of a .gltf's external buffers and images embedded. A level.glb fed back in
loses the nodes and meshes pinchmatch added to it last time (those at the end of its lists, marked
``extras.pinchmatch.role``) before the new ones are added. A node's extras that are not an object
are kept under ``extras.value``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..match.redirect import world_pose
from ..mesh.frames import UNITS_MM
from .documents import record_contacts
from .gltf_document import GltfLevel

SCHEMA_LEVEL = "pinchmatch.level/2"
#: the name of a prop's node in the level, of its mesh's node, and of a carousel object's node below
#: it
PROP_NODE = "pinchmatch_prop_{}"
PROP_MESH_NODE = "pinchmatch_prop_{}_mesh"
CAROUSEL_NODE = "carousel_{}"
#: the OpenXR hand joints at a grasp's fingertips, thumb first (XR_HAND_JOINT_*_TIP_EXT)
FINGERTIP_JOINTS = ("thumb_tip", "index_tip", "middle_tip")
#: how far the wrist is from the pinch's centre along the hand's approach (mm): the length of a hand
#: from the pads of a thumb-index pinch to the wrist crease, about 60 % of an adult hand's 190 mm (a
#: documented choice)
WRIST_MM = 110.0
OMI = "OMI_physics_body"


def node_extras(entry: dict, prop_spec) -> dict:
    """A matched node's ``extras.pinchmatch``, from its entry of matches.json and its prop's
    spec."""
    r = entry.get("redirection") or {}
    R, p = world_pose(prop_spec)
    t = entry["tangible_pose"]
    physical = np.array(record_contacts(t), dtype=np.float64) @ R.T + p
    v = entry["virtual_pose"]
    out = {"mode": r.get("mode"), "prop": entry["tangible"], "cost": entry["cost"],
           "redirect_cost": r.get("redirect_cost"), "carousel_cost": r.get("carousel_cost"),
           "reason": r.get("reason"), "angle_deg": r.get("angle_deg"), "gain": r.get("gain"),
           "rest_gap_mm": entry.get("rest_gap_mm"),
           "virtual_contacts_m": _metres(record_contacts(v)),
           "physical_contacts_m": _metres(physical)}
    for key in ("virtual_target_mm", "physical_target_mm", "hand_start_mm"):
        if r.get(key) is not None:
            out[key.replace("_mm", "_m")] = _metres(r[key])
    if r.get("mode") == "carousel":
        out["carousel_node"] = CAROUSEL_NODE.format(entry["virtual_node"])
    return out


def _metres(points_mm) -> list:
    return [round(float(c) / 1000.0, 6) for c in np.asarray(points_mm,
                                                            dtype=np.float64).reshape(-1)]


def _matrix(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = R, t
    return M


def grasp_joints(entry: dict, node_world: np.ndarray, mm_per_unit: float,
                 fingertip_radius_mm: float) -> dict:
    """{joint name: (3,) its place in the node's own frame (the file's units)} for a matched node
    whose world matrix (the file's units) is ``node_world``: the fingertip pads, the pinch's centre
    and the wrist."""
    v = entry["virtual_pose"]
    contacts = np.array(record_contacts(v), dtype=np.float64)
    normals = np.array(v["normals"] if "normals" in v else [v["n1"], v["n2"]], dtype=np.float64)
    pads = contacts + fingertip_radius_mm * normals
    T = np.array(entry["transform_virtual_to_tangible"], dtype=np.float64)
    # into the seen frame
    approach = T[:3, :3].T @ np.array(entry["tangible_pose"]["approach"], dtype=np.float64)
    centre = contacts.mean(axis=0)
    places = dict(zip(FINGERTIP_JOINTS, pads))
    places["pinch_center"] = centre
    if np.isfinite(approach).all():
        places["wrist"] = centre + WRIST_MM * approach
    to_local = np.linalg.inv(node_world)
    return {name: to_local[:3, :3] @ (q / mm_per_unit) + to_local[:3, 3]
            for name, q in places.items()}


def _motion(mass_g, com_local) -> dict:
    motion = {"type": "dynamic", "centerOfMass": [round(float(c), 6) for c in com_local]}
    if mass_g is not None:
        motion["mass"] = round(float(mass_g) / 1000.0, 6)
    return {OMI: {"motion": motion}}


def level_glb(level_path, props: list, entries: dict, settings: dict, *,
              virtuals: dict | None = None, units: str | None = None) -> bytes:
    """The level file at ``level_path`` (read in ``units``, glTF's metres where None) with ``props``
    ([(spec, mesh in mm in its file frame, centre of mass in mm, mass in g or None)]) at their
    poses, ``entries`` ({node name: (its matches.json entry, its prop's spec)}) in the nodes'
    extras, their carousel nodes and grasp joints; ``virtuals`` ({node name: its object entry of
    matches.json}) gives their masses and centres of mass; ``settings``: the run's (the fingertip
    radius, and the scene's extras)."""
    k = UNITS_MM[units or "m"]
    level = GltfLevel.read(Path(level_path))
    prop_nodes = {}
    for spec, mesh, com_mm, mass_g in props:
        R, p = world_pose(spec)
        name = spec.display_name
        mesh_index = level.add_mesh(np.asarray(mesh.vertices) / k, np.asarray(mesh.faces),
                                    PROP_MESH_NODE.format(name))
        child = level.add_node({"name": PROP_MESH_NODE.format(name), "mesh": mesh_index,
                                "extras": {"pinchmatch": {"role": "prop_mesh", "name": name}}})
        node = level.add_node({"name": PROP_NODE.format(name), "children": [child],
                               **_trs(R, p / k),
                               "extras": {"pinchmatch": {"role": "prop", "name": name,
                                                         "mesh_node": PROP_MESH_NODE.format(name)}},
                               "extensions": _motion(mass_g, np.asarray(com_mm, dtype=np.float64)
                                                     / k)})
        level.add_root(node)
        prop_nodes[name] = node
    radius = float(settings.get("fingertip_radius_mm", 8.0))
    for name, (entry, spec) in entries.items():
        entry = dict(entry, virtual_node=name)
        i = level.index[name]
        world = level.world[i]
        level.set_extras(i, node_extras(entry, spec))
        virtual = (virtuals or {}).get(name) or {}
        com, motion = virtual.get("com_mm"), None
        regular = abs(np.linalg.det(world[:3, :3])) > 1e-12
        if com is not None and regular:
            inverse = np.linalg.inv(world)
            motion = _motion(virtual.get("mass_g"), inverse[:3, :3] @ (np.asarray(com) / k)
                             + inverse[:3, 3])
            level.add_extensions(i, motion)
        # where the hand goes: the node itself, or the node the carousel brings onto the prop
        owners = [i]
        if (entry.get("redirection") or {}).get("mode") == "carousel":
            T = np.array(entry["transform_virtual_to_tangible"], dtype=np.float64)
            # the node's mesh, registered, in the prop's frame
            local = _matrix(T[:3, :3], T[:3, 3] / k) @ world
            carousel = level.add_node({"name": CAROUSEL_NODE.format(name),
                                       "mesh": level.nodes[i]["mesh"],
                                       "matrix": [float(c) for c in local.T.reshape(-1)],
                                       "extras": {"pinchmatch": {
                                           "role": "carousel", "node": name,
                                           "prop": entry["tangible"],
                                           "rest_gap_mm": entry.get("rest_gap_mm")}},
                                       **({"extensions": motion} if motion else {})})
            level.nodes[prop_nodes[entry["tangible"]]]["children"].append(carousel)
            owners = [carousel]  # the object is pinched on the prop, not where the level puts it
        if not regular:
            continue  # a node scaled to nothing: no frame to place its joints in
        joints = grasp_joints(entry, world, k, radius)  # the node's frame: the carousel node's too
        for owner in owners:
            for joint, place in joints.items():
                child = level.add_node({"name": joint, "translation": [float(c) for c in place],
                                        "extras": {"pinchmatch": {"role": "joint"}}})
                level.nodes[owner].setdefault("children", []).append(child)
    up = next((getattr(spec, "level_up", None) for spec, *_ in props
               if getattr(spec, "level_up", None)), None)
    level.set_scene_extras({"schema": SCHEMA_LEVEL, "units": units or "m", "up": _signed(up or "y"),
                            "settings": settings})
    return level.glb()


def _signed(label: str) -> str:
    return label if label.startswith("-") else f"+{label}"


def _trs(R: np.ndarray, t: np.ndarray) -> dict:
    from scipy.spatial.transform import Rotation

    return {"translation": [float(c) for c in t],
            "rotation": [float(c) for c in Rotation.from_matrix(R).as_quat()]}
