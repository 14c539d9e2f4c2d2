"""level.glb keeps the level whole: levels written as three exporters write them round-trip through
``--placement fixed`` with every node, extra, camera, light and scene, valid glTF, and every target
on its node's surface in the level's own units and frame."""

from __future__ import annotations

import json
import os
import struct
import subprocess

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from pinchmatch.cli.main import main
from levels import glb_of
from test_level_glb import NODE, VALIDATE, _document

#: the prop: a can (mm, its file's +Z up) standing where the level's own can stands, turned about
#: the level's up
PROP = ('[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, height_mm = '
        '66 }\n')


def _on_top(mesh, up):
    """``mesh`` (built z-up) turned to stand along ``up`` ("y" or "z") on the plane through the
    origin."""
    mesh = mesh.copy()
    if up == "y":
        mesh.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    axis = 1 if up == "y" else 2
    mesh.apply_translation(-mesh.bounds[0, axis] * np.eye(3)[axis])
    return mesh


def _parts(scale):
    """A counter, a can, a jar with its lid (two primitives), a box (z-up, in the level's units)."""
    counter = trimesh.creation.box(extents=(1.4, 0.7, 0.04))
    counter.apply_translation([0, 0, -0.04])
    can = trimesh.creation.cylinder(radius=0.027, height=0.066, sections=48)
    jar = trimesh.creation.cylinder(radius=0.03, height=0.08, sections=32)
    lid = trimesh.creation.cylinder(radius=0.032, height=0.012, sections=32)
    lid.apply_translation([0, 0, 0.046])
    box = trimesh.creation.box(extents=(0.05, 0.08, 0.03))
    return [m.apply_scale(scale) for m in (counter, can, jar, lid, box)]


def blender_level(path):
    """As Blender's exporter writes a kitchen: metres, y up, named nodes under a collection's empty,
    the jar's glass and lid two primitives of one mesh, a camera and a light (KHR_lights_punctual),
    custom properties as node extras and the document's extras; the table top at y = 0.76, the level
    turned 25 degrees."""
    counter, can, jar, lid, box = _parts(1.0)
    up = "y"
    turn = Rotation.from_euler("y", 25, degrees=True).as_quat().tolist()
    nodes = [{"name": "Kitchen", "children": [1, 2, 3, 4, 5, 6], "rotation": turn,
              "translation": [0.4, 0.0, -0.3]},
             {"name": "Counter", "mesh": 0, "translation": [0, 0.72, 0],
              "extras": {"material_set": "oak"}},
             {"name": "Can", "mesh": 1, "translation": [0.1, 0.76, 0.05], "extras": {"prop_id": 7}},
             {"name": "Jar", "mesh": 2, "translation": [-0.15, 0.76, 0.1]},
             {"name": "Box", "mesh": 3, "translation": [0.25, 0.76, -0.1], "extras": [1, 2]},
             {"name": "Camera", "camera": 0, "translation": [0, 1.6, 2.0]},
             {"name": "Light", "extensions": {"KHR_lights_punctual": {"light": 0}},
              "translation": [0, 2.5, 0]}]
    path.write_bytes(glb_of([[_on_top(counter, up)], [_on_top(can, up)],
                             [_on_top(jar, up), _on_top(lid, up).apply_translation([0, 0.0, 0])],
                             [_on_top(box, up)]],
                            nodes,
                            cameras=[{"type": "perspective",
                                      "perspective": {"yfov": 0.8, "znear": 0.05}}],
                                      extensionsUsed=["KHR_lights_punctual"],
                            extensions={"KHR_lights_punctual": {"lights": [{
                                "type": "point", "intensity": 20.0}]}},
                            extras={"author": "a level designer", "version": 3}))
    R = Rotation.from_euler("y", 25, degrees=True)
    can_at = R.apply([0.1, 0.76, 0.05]) + [0.4, 0.0, -0.3]
    pose = {"position_mm": (can_at * 1000.0).tolist(),
            "quaternion_xyzw": (R * Rotation.from_euler("x", -90, degrees=True)).as_quat().tolist()}
    return {"units": None, "up": None, "pose": pose, "objects": {"Can", "Jar", "Box"}}


def engine_level(path):
    """As a game engine's exporter writes one: metres, y up, unnamed mesh nodes placed by matrices,
    a hidden object scaled to nothing, and two scenes (the second the default)."""
    counter, can, jar, lid, box = _parts(1.0)
    up = "y"

    def matrix(t, deg=0.0):
        M = np.eye(4)
        M[:3, :3] = Rotation.from_euler("y", deg, degrees=True).as_matrix()
        M[:3, 3] = t
        return [float(c) for c in M.T.reshape(-1)]

    nodes = [{"name": "Root", "children": [1, 2, 3, 4]},
             {"mesh": 0, "matrix": matrix([1.0, 0.86, 2.0])},
             {"mesh": 1, "matrix": matrix([1.05, 0.9, 2.1], 40.0)},
             {"mesh": 2, "matrix": matrix([0.9, 0.9, 1.9], -30.0)},
             {"name": "Hidden", "mesh": 3, "translation": [1.2, 0.9, 2.0],
              "scale": [0.0, 0.0, 0.0]},
             {"name": "Other scene's box", "mesh": 3, "translation": [5.0, 0.0, 0.0]}]
    path.write_bytes(glb_of([[_on_top(counter, up)], [_on_top(can, up)],
                             [_on_top(jar, up), _on_top(lid, up)], [_on_top(box, up)]], nodes,
                             scenes=[{"name": "Lobby", "nodes": [5]},
                                                                 {"name": "Kitchen", "nodes": [0]}],
                                                                 scene=1))
    pose = {"position_mm": [1050.0, 900.0, 2100.0],
            "quaternion_xyzw": (Rotation.from_euler("y", 40, degrees=True) *
                                Rotation.from_euler("x", -90, degrees=True)).as_quat().tolist()}
    return {"units": None, "up": None, "pose": pose, "objects": {"2", "3"}}


def cad_level(path):
    """As a CAD package writes one: centimetres, z up, the table top at z = 90 cm."""
    counter, can, jar, lid, box = _parts(100.0)
    nodes = [{"name": "counter", "mesh": 0, "translation": [50.0, 25.0, 86.0]},
             {"name": "can", "mesh": 1, "translation": [52.0, 25.0, 90.0]},
             {"name": "jar", "mesh": 2, "translation": [40.0, 30.0, 90.0]},
             {"name": "box", "mesh": 3, "translation": [60.0, 18.0, 90.0]}]
    path.write_bytes(glb_of([[_on_top(counter, "z")], [_on_top(can, "z")],
                             [_on_top(jar, "z"), _on_top(lid, "z")], [_on_top(box, "z")]], nodes))
    pose = {"position_mm": [520.0, 250.0, 900.0], "quaternion_xyzw": [0.0, 0.0, 0.0, 1.0]}
    return {"units": "cm", "up": "z", "pose": pose, "objects": {"can", "jar", "box"}}


def _world(doc):
    from test_level_glb import _world as world

    return (world(doc) if doc.get("scene", 0) == 0
            else world({**doc, "scenes": [doc["scenes"][doc["scene"]]]}))


@pytest.fixture(scope="module", params=["blender", "engine", "cad"])
def round_trip(request, tmp_path_factory):
    folder = tmp_path_factory.mktemp(request.param)
    level = {"blender": blender_level, "engine": engine_level,
             "cad": cad_level}[request.param](folder / "level.glb")
    pose = level["pose"]
    (folder / "props.toml").write_text(PROP + f"pose = {{ position_mm = {pose['position_mm']}, "
                                              f"quaternion_xyzw = {pose['quaternion_xyzw']} }}\n")
    extra = [f for k in ("units", "up") if level[k] for f in (f"--{k}", level[k])]
    code = main([str(a) for a in ("match", "--tangible", folder / "props.toml", "--virtual",
                                  folder / "level.glb", "--split", "nodes", "--placement", "fixed",
                                  "--count", 150, "--no-view", "--no-figures", "-q", "--jobs", 1,
                                  "--no-cache", "-o", folder / "out", *extra)])
    err = request.param
    assert code == 0, err
    return request.param, folder, level


def test_every_node_scene_camera_light_and_extra_of_the_level_is_kept(round_trip):
    _, folder, level = round_trip
    source = _document(folder / "level.glb")
    written = _document(folder / "out" / "level.glb")
    n = len(source["nodes"])
    for before, after in zip(source["nodes"], written["nodes"][:n]):
        mine = dict(after)
        extras = mine.pop("extras", None)
        mine.pop("extensions", None) if "extensions" not in before else None
        for key in ("children",):  # joints are added below matched nodes
            if key in mine:
                mine[key] = [c for c in mine[key] if c < n]
                if not mine[key]:
                    del mine[key]
        assert {k: v for k, v in mine.items() if k != "extensions"} == \
            {k: v for k, v in before.items() if k not in ("extensions", "extras")}
        for key, value in (before.get("extensions") or {}).items():
            assert after["extensions"][key] == value
        if "extras" in before:
            own = before["extras"]
            assert (extras == own) if "pinchmatch" not in extras else \
                (extras.get("value") == own if not isinstance(own, dict)
                 else {**extras, "pinchmatch": None} ==
                 {**own, "pinchmatch": None})
    for key in ("cameras", "extras", "extensions"):
        if key in source:
            assert written[key] == source[key]
    assert [s.get("name") for s in written["scenes"]] == [s.get("name") for s in source["scenes"]]
    assert written.get("scene", 0) == source.get("scene", 0)
    assert set(source.get("extensionsUsed", [])) <= set(written.get("extensionsUsed", []))
    # the matched objects carry their match, and nothing else gained one
    matched = {(node.get("name") or str(i)) for i, node in enumerate(written["nodes"][:n])
               if isinstance(node.get("extras"), dict) and "pinchmatch" in node["extras"]}
    assert matched == level["objects"], matched


def test_the_levels_scene_says_its_units_and_up(round_trip):
    """The scene the level shows records the units and the signed up axis the objects were placed
    in: the CAD level's centimetres and +z, the others' metres and +y."""
    name, folder, level = round_trip
    written = _document(folder / "out" / "level.glb")
    record = written["scenes"][written.get("scene", 0)]["extras"]["pinchmatch"]
    assert (record["units"], record["up"]) == ((level["units"] or "m"), "+" + (level["up"] or "y"))


def test_the_validator_reports_no_error(round_trip):
    if NODE is None or not (VALIDATE.parent / "node_modules" / "gltf-validator").is_dir():
        if os.environ.get("CI"):
            pytest.fail("node or the glTF validator missing; .ci/run installs both")
        pytest.skip("node or tests/js's gltf-validator is not installed (npm ci --prefix tests/js)")
    _, folder, _ = round_trip
    proc = subprocess.run([NODE, str(VALIDATE), str(folder / "out" / "level.glb")],
                          capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout.splitlines()[0])
    assert report["errors"] == 0, report


def test_every_target_lies_on_its_node_in_the_levels_own_units(round_trip):
    """The virtual contacts (extras, metres) on their node's surface, in the level's units and
    frame, within 0.01 mm; the fingertip joints below each node (or carousel node) the pads: contact
    + 8 mm x normal."""
    name, folder, level = round_trip
    doc = _document(folder / "out" / "level.glb")
    k = {"cm": 10.0, None: 1000.0}[level["units"]]
    world = _world(doc)
    matches = {m["virtual"]: m
               for m in json.loads((folder / "out" / "matches.json").read_text())["matches"]}
    checked = 0
    for i, node in enumerate(doc["nodes"]):
        extras = node.get("extras")
        if (not (isinstance(extras, dict) and "pinchmatch" in extras
                 and "virtual_contacts_m" in extras["pinchmatch"])):
            continue
        label = node.get("name") or str(i)
        surface = trimesh.Trimesh(*_node_triangles(doc, folder / "level.glb", i, world[i]),
                                  process=False)
        # level's units
        contacts = np.reshape(extras["pinchmatch"]["virtual_contacts_m"], (-1, 3)) * 1000.0 / k
        _, distance, _ = trimesh.proximity.closest_point(surface, contacts)
        assert distance.max() * k < 0.01, (name, label, distance)
        m = matches[label]
        owner = [c for c in doc["nodes"]
                 if (c.get("extras") or {}).get("pinchmatch", {}).get("node") == label] \
            if m["redirection"]["mode"] == "carousel" else [node]
        assert owner, label
        radius = 8.0 / k
        for place in owner:
            j = doc["nodes"].index(place)
            joints = {doc["nodes"][c]["name"]: world[c][:3, 3] for c in place.get("children", [])}
            pads = np.reshape(extras["pinchmatch"]["virtual_contacts_m"], (-1, 3)) * 1000.0 / k
            if place is not node:
                # the carousel's: the pads as registered on the prop, in the level
                T = np.array(m["transform_virtual_to_tangible"])
                pads = (world[j] @ np.linalg.inv(world[i])
                        @ np.c_[pads, np.ones(len(pads))].T).T[:, :3]
            thumb = joints["thumb_tip"]
            assert (min(np.linalg.norm(thumb - p) for p in pads)
                    == pytest.approx(radius, abs=1e-4 * radius)), label
        checked += 1
    assert checked == len(level["objects"])


def _node_triangles(doc, path, index, world):
    """The triangles of node ``index``'s mesh (all its primitives) placed by ``world``, read from
    the file's accessors here."""
    data = path.read_bytes()
    length, = struct.unpack_from("<I", data, 12)
    blob_at = 20 + length + 8
    vertices, faces = [], []
    for primitive in doc["meshes"][doc["nodes"][index]["mesh"]]["primitives"]:
        def read(a, dtype, width):
            acc = doc["accessors"][a]
            view = doc["bufferViews"][acc["bufferView"]]
            start = blob_at + view.get("byteOffset", 0) + acc.get("byteOffset", 0)
            return np.frombuffer(data, dtype=dtype, count=acc["count"] * width,
                                 offset=start).reshape(-1, width)
        v = read(primitive["attributes"]["POSITION"], "<f4", 3).astype(float)
        f = read(primitive["indices"], "<u4", 1).reshape(-1, 3)
        faces.append(f + sum(len(x) for x in vertices))
        vertices.append(v @ world[:3, :3].T + world[:3, 3])
    return np.concatenate(vertices), np.concatenate(faces)


def test_a_run_writing_lines_writes_the_same_level(round_trip, tmp_path):
    """``--format jsonl`` writes level.glb too, the same bytes as the document run's."""
    name, folder, level = round_trip
    if name != "blender":
        pytest.skip("one level is enough")
    extra = [f for k in ("units", "up") if level[k] for f in (f"--{k}", level[k])]
    code = main([str(a) for a in ("match", "--tangible", folder / "props.toml", "--virtual",
                                  folder / "level.glb", "--split", "nodes", "--placement", "fixed",
                                  "--count", 150, "--no-view", "--no-figures", "-q", "--jobs", 1,
                                  "--no-cache", "--format", "jsonl", "-o", tmp_path / "lines",
                                  *extra)])
    assert code == 0
    assert (tmp_path / "lines" / "level.glb").read_bytes() == (
        folder / "out" / "level.glb").read_bytes()


def test_a_level_glb_fed_back_in_matches_the_same_objects_and_is_written_once_more_whole(
    round_trip, tmp_path):
    """The props and carousel copies pinchmatch added are not objects of the level; writing the
    level again drops them first, so the level holds one prop node, not two."""
    name, folder, level = round_trip
    extra = [f for k in ("units", "up") if level[k] for f in (f"--{k}", level[k])]
    code = main([str(a) for a in ("match", "--tangible", folder / "props.toml", "--virtual",
                                  folder / "out" / "level.glb", "--split", "nodes", "--placement",
                                  "fixed", "--count", 150, "--no-view", "--no-figures", "-q",
                                  "--jobs", 1, "--no-cache", "-o", tmp_path / "again", *extra)])
    assert code == 0
    first = json.loads((folder / "out" / "matches.json").read_text())
    again = json.loads((tmp_path / "again" / "matches.json").read_text())
    assert {m["virtual"] for m in again["matches"]} == {
        m["virtual"] for m in first["matches"]} == level["objects"]
    before, after = (_document(folder / "out" / "level.glb"),
                     _document(tmp_path / "again" / "level.glb"))
    assert [n.get("name") for n in after["nodes"]] == [n.get("name") for n in before["nodes"]]
    assert sum(n.get("name") == "pinchmatch_prop_can_prop" for n in after["nodes"]) == 1


def test_a_bodys_motion_gives_its_mass_in_kilograms_and_its_centre_to_the_micrometre():
    """OMI_physics_body's motion: the mass in kg (grams / 1000), the centre of mass in the node's
    units rounded to 6 decimals (a micrometre in metres); no mass where none is known."""
    from pinchmatch.export.level import _motion

    com = [0.01234567891, -0.2000004999, 1.5e-7]
    motion = _motion(387.5, com)["OMI_physics_body"]["motion"]
    assert motion["type"] == "dynamic" and motion["mass"] == 0.3875
    assert motion["centerOfMass"] == [0.012346, -0.2, 0.0]
    assert "mass" not in _motion(None, com)["OMI_physics_body"]["motion"]
