"""A level node whose mesh has several primitives (one per material) is one object, named by its
node."""

import json

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from conftest import run_cli
from levels import glb_of
from pinchmatch.mesh.load import load_mesh, read_level


def _jar_and_lid():
    """A jar (metres, y up) and its lid, two primitives of one mesh."""
    jar = trimesh.creation.cylinder(radius=0.035, height=0.09, sections=32)
    jar.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    jar.apply_translation([0, 0.045, 0])
    lid = trimesh.creation.cylinder(radius=0.037, height=0.015, sections=32)
    lid.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    lid.apply_translation([0, 0.0975, 0])
    return jar, lid


def _level(path, turn_deg=35.0):
    jar, lid = _jar_and_lid()
    box = trimesh.creation.box(extents=(0.05, 0.03, 0.08))
    box.apply_translation([0, 0.015, 0])
    q = Rotation.from_euler("y", turn_deg, degrees=True).as_quat().tolist()
    nodes = [{"name": "Kitchen", "children": [1, 2], "translation": [1.3, 0.2, -0.7],
              "rotation": q},
             {"name": "jar", "mesh": 0, "translation": [0.1, 0.76, 0.05]},
             {"name": "box", "mesh": 1, "translation": [-0.15, 0.76, 0.0]}]
    path.write_bytes(glb_of([[jar, lid], [box]], nodes))
    R = Rotation.from_quat(q).as_matrix()
    world = np.eye(4)
    world[:3, :3], world[:3, 3] = R, R @ [0.1, 0.76, 0.05] + [1.3, 0.2, -0.7]
    return trimesh.util.concatenate([jar, lid]).apply_transform(world)


def test_a_node_of_two_primitives_is_one_object_under_its_own_name_on_every_read(tmp_path):
    expected = _level(tmp_path / "kitchen.glb")
    assert [n.name for n in read_level(tmp_path / "kitchen.glb")] == ["box", "jar"]
    assert [n.path for n in read_level(tmp_path / "kitchen.glb")] == ["Kitchen/box", "Kitchen/jar"]
    digests = set()
    for _ in range(3):
        # a fresh read each time: the same name, the same triangles in the same order
        loaded = load_mesh(tmp_path / "kitchen.glb", node="jar", units="m")
        assert len(loaded.mesh.faces) == len(expected.faces)  # the jar's and the lid's
        np.testing.assert_allclose(loaded.mesh.bounds, expected.bounds * 1000.0, atol=1e-3)
        assert abs(loaded.mesh.area - expected.area * 1e6) < 1e-3 * expected.area * 1e6
        digests.add(loaded.mesh.vertices.tobytes())
    assert len(digests) == 1


def test_a_level_with_a_jar_and_its_lid_is_matched_by_name_with_and_without_a_glob(
    tmp_path, capsys):
    _level(tmp_path / "kitchen.glb")
    prop = trimesh.creation.cylinder(radius=32.0, height=100.0, sections=48)
    prop.export(tmp_path / "prop.stl")
    docs = []
    for k, extra in enumerate(([], ["--nodes", "jar*"])):
        code, out, err = run_cli(capsys, "match", "--tangible", tmp_path / "prop.stl", "--virtual",
                                 tmp_path / "kitchen.glb", "--split", "nodes", *extra, "--count",
                                 120, "--no-view", "--no-figures", "--jobs", 1, "--no-cache", "-o",
                                 tmp_path / f"out{k}")
        assert code == 0, err
        docs.append(json.loads((tmp_path / f"out{k}" / "matches.json").read_text()))
    assert {m["virtual"] for m in docs[0]["matches"]} == {"jar", "box"}
    assert {m["virtual"] for m in docs[1]["matches"]} == {"jar"}
    jar = [m for m in docs[0]["matches"] if m["virtual"] == "jar"][0]
    again = [m for m in docs[1]["matches"] if m["virtual"] == "jar"][0]
    assert jar["cost"] == again["cost"] and jar["virtual_pose"] == again["virtual_pose"]
