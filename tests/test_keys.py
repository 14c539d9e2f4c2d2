"""Keys derived from what they key: every ObjectSpec field is in its shape key or excluded by name,
and a changed pose, a re-triangulated node or another setting in the same process never reuses what
was made for the old one (warm runs equal cold ones)."""

import dataclasses
import json
import subprocess
import sys

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from levels import glb_of, standing_can
from pinchmatch.cli.main import main
from pinchmatch.mesh.object_spec import NOT_SHAPE, ObjectSpec, spec_from_dict, spec_to_dict

#: the fields that do not shape an object's candidates, and why (a new field must be added here or
#: to the key)
EXCLUDED = {"path": "the file is keyed by its bytes", "name": "a label",
            "mass_g": "enters the cost, not the poses",
            "split": "a level is split before its nodes are keyed",
            "node_path": "the node is keyed by its name", "manifest": "where it was listed",
            "nodes": "chooses nodes, each keyed on its own",
            "skip_nodes": "chooses nodes, each keyed on its own",
            "scan_noise_mm": "a record of the scan",
            "scan_residual_mm": "enters the cost (the features' spread), not the poses",
            "scale_verified": "a note in the summary"}


def test_every_field_of_a_spec_is_keyed_or_excluded_by_name():
    names = {f.name for f in dataclasses.fields(ObjectSpec)}
    assert set(NOT_SHAPE) == set(EXCLUDED)
    key = ObjectSpec("a.stl").shape_key()
    assert set(key) == names - set(NOT_SHAPE)
    assert set(key) | set(NOT_SHAPE) == names


def test_every_field_of_a_spec_goes_through_its_record_and_back():
    """A spec with every field away from its default, through JSON: the same spec (a field added
    must be given a value here)."""
    from pinchmatch.mesh.regions import ContactRegions, Region

    values = {"path": "a.glb", "name": "cup", "units": "m", "up": "-x", "com_mm": (1.0, 2.0, 3.5),
              "axis": (0.0, 1.0, 0.0), "mass_g": 120.0,
              "regions": ContactRegions((Region.sphere((0.0, 0.0, 5.0), 2.0),),
                                        (Region.box((-1.0, -1.0, 0.0), (1.0, 1.0, 9.0)),)),
              "split": "nodes", "node": "cup_1", "node_path": "Kitchen/cup_1",
              "manifest": "props.toml", "pose": ((10.0, 900.0, -5.0), (0.0, 0.6, 0.0, 0.8)),
              "support": 12.5, "rests_on_mm": 900.0, "level_up": "z", "nodes": ("cup*",),
              "skip_nodes": ("wall*", "floor"), "scan_noise_mm": 0.5, "scan_residual_mm": 0.1,
              "scale_verified": False}
    assert set(values) == {f.name for f in dataclasses.fields(ObjectSpec)}
    spec = ObjectSpec(**values)
    again = spec_from_dict(json.loads(json.dumps(spec_to_dict(spec))))
    assert again == spec and spec_to_dict(again) == spec_to_dict(spec)


def test_the_key_turns_with_a_standing_props_pose_not_with_where_it_stands():
    turn = Rotation.from_euler("y", 30, degrees=True).as_quat().tolist()
    other = Rotation.from_euler("y", 75, degrees=True).as_quat().tolist()
    base = ObjectSpec("can.stl", support="auto", pose=((0.0, 900.0, 0.0), tuple(turn)))
    assert base.shape_key() != dataclasses.replace(base,
                                                   pose=(
                                                       (0.0, 900.0, 0.0), tuple(other))).shape_key()
    assert base.shape_key() == dataclasses.replace(base,
                                                   pose=(
                                                       (500.0, 900.0, -40.0),
                                                       tuple(turn))).shape_key()
    assert base.shape_key() == dataclasses.replace(base, name="x", mass_g=300.0,
                                                   manifest="m.toml").shape_key()
    held = dataclasses.replace(base, support="none")  # a held prop's pose shapes nothing
    assert held.shape_key() == dataclasses.replace(held,
                                                   pose=(
                                                       (0.0, 900.0, 0.0), tuple(other))).shape_key()


def _match(out, *argv, cache=None):
    code = main([*map(str, argv), "--count", "60", "--jobs", "1", "-q", "--no-view", "--no-figures",
                 "-o", str(out), *(["--cache", str(cache)] if cache else ["--no-cache"])])
    assert code == 0
    doc = json.loads((out / "matches.json").read_text())
    return [(m["virtual"], m["tangible"], m["cost"], m["tangible_pose"],
             m["virtual_pose"]) for m in doc["matches"]]


def _prop(folder, deg):
    turn = (Rotation.from_euler("y", deg, degrees=True)
            * Rotation.from_euler("x", -90, degrees=True)).as_quat()
    (folder / "props.toml").write_text('[[object]]\nname = "prop"\nshape = { kind = "box", size_mm '
                                       '= [40, 60, 30] }\n'
                                       f"pose = {{ position_mm = [300.0, 900.0, -200.0], "
                                       "quaternion_xyzw = "
                                       f"{turn.tolist()} }}\n")


def _flipped_diagonals(mesh):
    """``mesh`` over the same vertices, each pair of coplanar triangles (a quad) split along its
    other diagonal."""
    faces = mesh.faces.copy()
    used = set()
    for (a, b), angle in zip(mesh.face_adjacency, mesh.face_adjacency_angles):
        if angle > 1e-9 or a in used or b in used:
            continue
        shared = [v for v in faces[a] if v in faces[b]]
        lone_a = [v for v in faces[a] if v not in faces[b]][0]
        lone_b = [v for v in faces[b] if v not in faces[a]][0]
        order = list(faces[a])  # keep a's winding: lone_a, then the shared edge as a has it
        i = order.index(lone_a)
        s0, s1 = order[(i + 1) % 3], order[(i + 2) % 3]
        faces[a], faces[b] = [lone_a, s0, lone_b], [lone_a, lone_b, s1]
        used |= {a, b}
    return trimesh.Trimesh(mesh.vertices, faces, process=False)


def _level(path, triangulation=0):
    jar = standing_can(0.03, 0.08)
    if triangulation:  # the same vertices, each quad of its side split along its other diagonal
        jar = _flipped_diagonals(jar)
    box = trimesh.creation.box(extents=(0.05, 0.04, 0.06))
    box.apply_translation([0, 0.03, 0])
    path.write_bytes(glb_of([[jar], [box]],
                            [{"name": "jar", "mesh": 0, "translation": [0.3, 0.9, -0.1]},
                                             {"name": "box", "mesh": 1,
                                              "translation": [0.2, 0.9, -0.15]}]))


def test_a_turned_prop_and_a_retriangulated_node_are_made_anew(tmp_path):
    _level(tmp_path / "kitchen.glb")
    _prop(tmp_path, 30)
    run = ("match", "--tangible", tmp_path / "props.toml", "--virtual", tmp_path / "kitchen.glb",
           "--split", "nodes")
    cache = tmp_path / "cache"
    _match(tmp_path / "warm0", *run, cache=cache)
    _prop(tmp_path, 75)  # the prop turned on its table: its support turns in its frame
    assert _match(tmp_path / "warm1", *run, cache=cache) == _match(tmp_path / "cold1", *run)
    _level(tmp_path / "kitchen.glb", triangulation=1)
    from pinchmatch.mesh.load import node_digests

    assert _match(tmp_path / "warm2", *run, cache=cache) == _match(tmp_path / "cold2", *run)
    retriangulated = node_digests(tmp_path / "kitchen.glb")
    _level(tmp_path / "again.glb")
    # the same vertices, other faces
    assert node_digests(tmp_path / "again.glb")["jar"] != retriangulated["jar"]
    assert node_digests(tmp_path / "again.glb")["box"] == retriangulated["box"]


def test_two_settings_in_one_process_give_what_two_processes_give(tmp_path):
    """A second match in one process with another patch radius and landing radius: as a fresh
    process's."""
    trimesh.creation.box(extents=(40.0, 60.0, 30.0)).export(tmp_path / "box.stl")
    trimesh.creation.cylinder(radius=22.0, height=70.0, sections=48).export(tmp_path / "can.stl")
    run = ("match", "--tangible", tmp_path / "box.stl", "--virtual", tmp_path / "can.stl")
    _match(tmp_path / "first", *run, "--patch-radius-mm", "8", "--landing-mm", "5")
    second = _match(tmp_path / "second", *run, "--patch-radius-mm", "6", "--landing-mm", "3")
    fresh = tmp_path / "fresh"
    subprocess.run([sys.executable, "-m", "pinchmatch", *map(str, run), "--patch-radius-mm", "6",
                    "--landing-mm", "3", "--count", "60", "--jobs", "1", "-q", "--no-view",
                    "--no-figures", "--no-cache", "-o", str(fresh)],
                   check=True, capture_output=True)
    doc = json.loads((fresh / "matches.json").read_text())
    assert second == [(m["virtual"], m["tangible"], m["cost"], m["tangible_pose"],
                       m["virtual_pose"])
                      for m in doc["matches"]]
