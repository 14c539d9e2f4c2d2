"""glTF scenes of matches: the tangible, the registered virtual object, a green cone and a finger
per fingertip.

glTF conventions: metres and +Y up. pinchmatch works in mm in each file's
frame, so every scene applies C = Q / 1000, where Q is the smallest rotation
taking the tangible's up direction (``--up``, default z for STL/OBJ/PLY,
y for glTF) onto +Y. C is baked into the vertices. The virtual object's
node carries the registration as a rigid matrix,
Q·R·Qᵀ with translation Q·t/1000, applied to its own vertices Q·v/1000. So
the node matrix is what an engine reads, and the mm transform stays in the
extras.

Node names: ``tangible``, ``virtual``, ``cone_p1``, ``cone_p2`` (a tripod's: ``cone_p1`` the
thumb's, ``cone_p2`` the index's, ``cone_p3`` the middle finger's), and
``finger_p1``, ``finger_p2`` (``finger_p3``): semi-transparent capsules of the hand model
(:mod:`hand`), each along its finger's axis (the tangible pose's approach
leaned away from the other finger by the splay), so a user sees where the
hand comes from. Match data sits in node and scene extras as flat keys
prefixed ``pinchmatch:``; the approach of both poses is among them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh
from trimesh.visual.material import PBRMaterial

from ..grasp.hand import Hand, finger_directions
from ..grasp.pinches import closing_directions
from ..grasp.spread import other_order
from ..match.noticed import contact_offset_mm
from ..mesh.frames import rotations_between
from ..files import write_atomic
from .documents import scene_stems

#: the fingertip cones: tip on the contact, axis along the pinch line, outside the object
CONE_HEIGHT_MM, CONE_RADIUS_MM = 20.0, 5.0
GREEN = [0.15, 0.75, 0.25, 1.0]
FINGER_COLOR = [0.95, 0.75, 0.6, 0.35]
TANGIBLE_COLOR = [0.6, 0.6, 0.6, 1.0]
VIRTUAL_COLOR = [0.25, 0.45, 1.0, 0.45]


def gltf_rotation(up: np.ndarray) -> np.ndarray:
    """Q: the smallest rotation taking ``up`` onto glTF's +Y."""
    return rotations_between(np.asarray(up, float)[None], np.array([[0.0, 1.0, 0.0]]))[0]


def _material(color, *, blend: bool = False) -> PBRMaterial:
    return PBRMaterial(baseColorFactor=color, metallicFactor=0.0, roughnessFactor=0.8,
                       alphaMode="BLEND" if blend else "OPAQUE", doubleSided=blend)


def _styled(mesh: trimesh.Trimesh, vertices: np.ndarray, color, *,
            blend: bool = False) -> trimesh.Trimesh:
    out = trimesh.Trimesh(vertices, mesh.faces.copy(), process=False)
    out.visual = trimesh.visual.TextureVisuals(material=_material(color, blend=blend))
    return out


def _placed(mesh: trimesh.Trimesh, origin_mm: np.ndarray, direction: np.ndarray) -> trimesh.Trimesh:
    """``mesh``, built along +z from the origin, turned onto the unit ``direction`` and moved to
    ``origin_mm``."""
    T = np.eye(4)
    T[:3, :3] = rotations_between(np.array([[0.0, 0.0, 1.0]]),
                                  np.asarray(direction, float)[None])[0]
    T[:3, 3] = origin_mm
    mesh.apply_transform(T)
    return mesh


def fingertip_cone(contact_mm: np.ndarray, toward_mm: np.ndarray) -> trimesh.Trimesh:
    """A cone (mm) with its tip on ``contact_mm``, pointing along ``toward_mm`` (unit)."""
    cone = trimesh.creation.cone(radius=CONE_RADIUS_MM, height=CONE_HEIGHT_MM, sections=24)
    cone.apply_translation([0.0, 0.0, -CONE_HEIGHT_MM])  # tip at the origin, body along -z
    return _placed(cone, contact_mm, toward_mm)


def finger_capsule(start_mm: np.ndarray, direction: np.ndarray, length_mm: float,
                   radius_mm: float) -> trimesh.Trimesh:
    """A capsule (mm) whose axis runs from ``start_mm`` along the unit ``direction`` for
    ``length_mm``."""
    capsule = trimesh.creation.capsule(height=length_mm, radius=radius_mm, count=[16, 16])
    capsule.apply_translation([0.0, 0.0, length_mm / 2.0])  # axis from the origin along +z
    return _placed(capsule, start_mm, direction)


def _flat(prefix_values: dict) -> dict:
    out = {}
    for key, value in prefix_values.items():
        if isinstance(value, np.ndarray):
            value = value.tolist()
        out[f"pinchmatch:{key}"] = value
    return out


def virtual_contacts_mm(virtual, choice) -> np.ndarray:
    """(F, 3) the virtual pose's contacts in the virtual object's frame, ordered to meet the
    tangible's (p1, p2; a tripod's thumb, index, middle)."""
    p = virtual.pinches.points[choice.v_pose]
    return p[other_order(len(p))] if choice.swapped else p



def virtual_approach(virtual, choice) -> np.ndarray:
    """(3,) the virtual pose's approach in the virtual object's frame."""
    return virtual.pinches.approach[choice.v_pose]


def match_scene_glb(tangible, virtual, choice, *, extras: dict | None = None,
                    hand: Hand = Hand()) -> bytes:
    """One match as GLB bytes: tangible, registered virtual object (semi-transparent), a cone per
    fingertip."""
    Q = gltf_rotation(tangible.obj.loaded.up)
    to_gltf = lambda points_mm: (np.asarray(points_mm) @ Q.T) / 1000.0  # noqa: E731

    scene = trimesh.Scene()
    t_mesh = tangible.obj.loaded.mesh
    scene.add_geometry(_styled(t_mesh, to_gltf(t_mesh.vertices), TANGIBLE_COLOR),
                       node_name="tangible", geom_name="tangible",
                       metadata=_flat({"role": "tangible", "object": tangible.name}))

    X = choice.transform
    node = np.eye(4)
    node[:3, :3] = Q @ X[:3, :3] @ Q.T
    node[:3, 3] = Q @ X[:3, 3] / 1000.0
    v_mesh = virtual.obj.loaded.mesh
    info = {
        "role": "virtual", "object": virtual.name, "tangible": tangible.name,
        "cost": float(choice.cost), "flipped": bool(choice.flipped),
        "finger_order_swapped": bool(choice.swapped),
        "transform_virtual_to_tangible_mm": X.reshape(-1),
        "contact_offset_mm": contact_offset_mm(tangible, virtual, choice),
        # where the fingers go on the virtual object, in its own file frame (mm), in the tangible's
        # finger order
        "virtual_contacts_mm": virtual_contacts_mm(virtual, choice).reshape(-1),
        "virtual_approach": virtual_approach(virtual, choice),
    }
    scene.add_geometry(_styled(v_mesh, to_gltf(v_mesh.vertices), VIRTUAL_COLOR, blend=True),
                       node_name="virtual", geom_name="virtual", transform=node,
                       metadata=_flat(info | (extras or {})))

    p = tangible.pinches.points[choice.t_pose]
    for k, (contact, toward) in enumerate(zip(p, closing_directions(p)), start=1):
        cone = fingertip_cone(contact, toward)
        scene.add_geometry(_styled(cone, to_gltf(cone.vertices), GREEN), node_name=f"cone_p{k}",
                           geom_name=f"cone_p{k}",
                           metadata=_flat({"role": "fingertip", "finger": f"p{k}",
                                           "contact_mm": contact}))
    approach = tangible.pinches.approach[choice.t_pose]
    if np.isfinite(approach).all():
        normals = tangible.pinches.normals[choice.t_pose]
        along = finger_directions(p[None], approach[None], hand)[0]  # the V of the fingers
        for k in range(len(p)):
            start = p[k] + hand.fingertip_radius_mm * normals[k]
            capsule = finger_capsule(start, along[k], hand.finger_length_mm, hand.finger_radius_mm)
            scene.add_geometry(_styled(capsule, to_gltf(capsule.vertices), FINGER_COLOR,
                                       blend=True),
                               node_name=f"finger_p{k + 1}", geom_name=f"finger_p{k + 1}",
                               metadata=_flat({"role": "finger", "finger": f"p{k + 1}",
                                               "approach": approach, "direction": along[k],
                                               "finger_splay_deg": hand.finger_splay_deg,
                                               "finger_radius_mm": hand.finger_radius_mm,
                                               "finger_length_mm": hand.finger_length_mm}))
    C = np.eye(4)
    C[:3, :3] = Q / 1000.0
    scene.metadata.update(_flat({"schema": "pinchmatch.scene/1", "units": "m", "up": "+y",
                                 "source_up": tangible.obj.loaded.up_label,
                                 "file_mm_to_gltf_m": C.reshape(-1)}))
    return scene.export(file_type="glb")


def write_scenes(scene, folder, *, progress=None, hand: Hand = Hand()) -> list:
    """Write ``folder/<virtual name>.glb`` for every matched virtual object; return the paths.

    ``progress``, if given, is called with each path once it is written.
    """
    folder = Path(folder)
    stems = scene_stems([v.name for v in scene.virtuals])
    paths = []
    for vm in scene.matches:
        if vm.best is None:
            continue
        path = folder / f"{stems[vm.virtual]}.glb"
        tangibles, V = scene.objects(vm)
        T = tangibles[vm.best.tangible]
        write_atomic(path, match_scene_glb(T, V, vm.best, hand=hand))
        paths.append(path)
        if progress is not None:
            progress(path)
    return paths
