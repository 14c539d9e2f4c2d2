"""``OUT/level.glb``: a level as an engine loads it, with the prop at its pose and each node's match.

Under ``--placement fixed`` the objects stay where a level puts them; an engine (Unity, Unreal, a WebXR
page) needs the level itself, the prop where it stands, and per node what to do: redirect the hand to
the prop, or bring the object onto the prop (the carousel). This writes the level's own file back with:

- every node and mesh of the level as the file holds them (metres, y up: the file's frame);
- one node per prop, ``pinchmatch_prop_<name>``, its mesh placed by its manifest ``pose`` (the prop's
  file in mm, turned and moved into the level, in metres);
- in each matched node's ``extras.pinchmatch``: its ``mode`` (``redirect`` or ``carousel``), the prop, the
  cost, both costs and the reason, the redirection's angle and gain, and, in the level's frame in metres,
  the virtual and physical pinch targets, the four contacts and the hand's start; a prop node's
  ``extras.pinchmatch`` says it is a prop; the scene's ``extras.pinchmatch`` gives the schema, the units
  and the settings.

trimesh writes the meshes, the materials and the scene graph; node extras, which trimesh's exporter has
no field for, are set in the binary's JSON chunk afterwards (the chunk re-padded as glTF 2.0 requires).
"""

from __future__ import annotations

import json
import struct

import numpy as np
import trimesh

from ..match.redirect import world_pose
from .documents import record_contacts

SCHEMA_LEVEL = "pinchmatch.level/1"
#: the name of a prop's node in the level
PROP_NODE = "pinchmatch_prop_{}"


def _metres(points_mm) -> list:
    return [round(float(c) / 1000.0, 6) for c in np.asarray(points_mm, dtype=np.float64).reshape(-1)]


def node_extras(entry: dict, prop_spec) -> dict:
    """A matched node's ``extras.pinchmatch``, from its entry of matches.json and its prop's spec."""
    r = entry.get("redirection") or {}
    R, p = world_pose(prop_spec)
    t = entry["tangible_pose"]
    physical = np.array(record_contacts(t), dtype=np.float64) @ R.T + p
    v = entry["virtual_pose"]
    out = {"mode": r.get("mode"), "prop": entry["tangible"], "cost": entry["cost"],
           "redirect_cost": r.get("redirect_cost"), "carousel_cost": r.get("carousel_cost"), "reason": r.get("reason"),
           "angle_deg": r.get("angle_deg"), "gain": r.get("gain"),
           "virtual_contacts_m": _metres(record_contacts(v)), "physical_contacts_m": _metres(physical)}
    for key in ("virtual_target_mm", "physical_target_mm", "hand_start_mm"):
        if r.get(key) is not None:
            out[key.replace("_mm", "_m")] = _metres(r[key])
    return out


def level_glb(level_path, props: list, entries: dict, settings: dict) -> bytes:
    """The level file at ``level_path`` with ``props`` ([(spec, mesh in mm in its file frame)]) placed at
    their poses and ``entries`` ({node name: (its matches.json entry, its prop's spec)}) in the nodes'
    extras; ``settings``: the run's, for the scene's extras."""
    scene = trimesh.load(str(level_path), force="scene", process=False)
    for spec, mesh in props:
        R, p = world_pose(spec)
        placed = trimesh.Trimesh(vertices=(np.asarray(mesh.vertices) @ R.T + p) / 1000.0, faces=mesh.faces,
                                 process=False)
        name = PROP_NODE.format(spec.display_name)
        placed.metadata["pinchmatch"] = {"role": "prop", "name": spec.display_name}
        scene.add_geometry(placed, node_name=name, geom_name=name)
    scene.metadata["pinchmatch"] = {"schema": SCHEMA_LEVEL, "units": "m", "up": "+y", "settings": settings}
    data = scene.export(file_type="glb")
    extras = {name: {"pinchmatch": node_extras(entry, spec)} for name, (entry, spec) in entries.items()}
    extras |= {PROP_NODE.format(spec.display_name): {"pinchmatch": {"role": "prop", "name": spec.display_name}}
               for spec, _ in props}
    return with_node_extras(data, extras)


def with_node_extras(glb: bytes, extras: dict) -> bytes:
    """GLB bytes with ``extras`` ({node name: dict}) set on the nodes of those names."""
    length, = struct.unpack_from("<I", glb, 12)
    document = json.loads(glb[20:20 + length])
    for node in document.get("nodes", []):
        if node.get("name") in extras:
            node["extras"] = extras[node["name"]]
    chunk = json.dumps(document, separators=(",", ":"), sort_keys=True).encode()
    chunk += b" " * (-len(chunk) % 4)  # a JSON chunk is padded with spaces to four bytes
    rest = glb[20 + length:]
    header = struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(chunk) + len(rest))
    return header + struct.pack("<I4s", len(chunk), b"JSON") + chunk + rest
