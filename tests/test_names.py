"""Objects, levels and nodes of one name: every result tells them apart, none overwrites another."""

import json

import numpy as np
import pytest
import trimesh

from conftest import assert_one_line, run_cli
from levels import standing_can, tabletop_level
from pinchmatch.mesh.manifest import object_specs

PROP = ('[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, height_mm = '
        '66 }\n'
        "pose = { position_mm = [500.0, 900.0, -250.0], quaternion_xyzw = [-0.7071068, 0.0, 0.0, "
        "0.7071068] }\n")


def _kitchen(path, shift_m):
    box = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    box.apply_translation([0.0, 0.025, 0.0])
    tabletop_level(path, [("mug", standing_can(0.03, 0.09), (0.52 + shift_m, 0.9, -0.25)),
                          ("box", box, (0.47, 0.9, -0.23 + shift_m))])


def test_files_of_one_name_in_two_folders_are_named_by_their_folders(tmp_path, capsys):
    for folder, extents in (("a", (40.0, 30.0, 60.0)), ("b", (30.0, 30.0, 70.0))):
        (tmp_path / folder).mkdir()
        trimesh.creation.box(extents=extents).export(tmp_path / folder / "prop.stl")
    trimesh.creation.icosphere(radius=25.0).export(tmp_path / "ball.stl")
    names = [s.display_name
             for s in object_specs([tmp_path / "a" / "prop.stl", tmp_path / "b" / "prop.stl",
                                                   tmp_path / "ball.stl"], option="--tangible")]
    assert names == ["a/prop.stl", "b/prop.stl", "ball.stl"]
    code, out, err = run_cli(capsys, "match", "--tangible", tmp_path / "a" / "prop.stl",
                             tmp_path / "b" / "prop.stl", "--virtual", tmp_path / "ball.stl",
                             "--count", 80, "--jobs", 1, "--no-view", "-q", "--no-cache", "-o",
                             tmp_path / "out")
    assert code == 0, err
    doc = json.loads((tmp_path / "out" / "matches.json").read_text())
    assert [t["name"] for t in doc["tangibles"]] == ["a/prop.stl", "b/prop.stl"]
    assert doc["cost_matrix"]["columns_tangible"] == ["a/prop.stl", "b/prop.stl"]


def test_a_manifest_giving_two_objects_one_name_is_one_line(tmp_path, capsys):
    trimesh.creation.box(extents=(40.0, 30.0, 60.0)).export(tmp_path / "a.stl")
    trimesh.creation.box(extents=(30.0, 30.0, 70.0)).export(tmp_path / "b.stl")
    (tmp_path / "props.toml").write_text('[[object]]\nfile = "a.stl"\nname = "prop"\n'
                                         '[[object]]\nfile = "b.stl"\nname = "prop"\n')
    code, out, err = run_cli(capsys, "match", "--tangible", tmp_path / "props.toml", "--virtual",
                             tmp_path / "a.stl", "--count", 60, "-o", tmp_path / "out")
    assert code == 2
    assert_one_line(err, "named 'prop'", "its own name")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("layout", ["two names", "one name, two folders"])
def test_two_levels_with_a_node_of_one_name_each_keep_their_own(tmp_path, capsys, layout):
    """Two levels each with a ``mug`` and a ``box``: both levels' nodes are matched under names that
    tell them apart, each level's file holds its own nodes' matches, and two levels of one file name
    in two folders write two files."""
    if layout == "two names":
        paths = [tmp_path / "kitchen_a.glb", tmp_path / "kitchen_b.glb"]
    else:
        (tmp_path / "a").mkdir()
        (tmp_path / "b").mkdir()
        paths = [tmp_path / "a" / "kitchen.glb", tmp_path / "b" / "kitchen.glb"]
    for k, path in enumerate(paths):
        _kitchen(path, 0.01 * k)
    (tmp_path / "props.toml").write_text(PROP)
    code, out, err = run_cli(capsys, "match", "--tangible", tmp_path / "props.toml", "--virtual",
                             *paths, "--split", "nodes", "--placement", "fixed", "--count", 100,
                             "--jobs", 1, "--no-view", "-q", "--no-cache", "-o", tmp_path / "out")
    assert code == 0, err
    doc = json.loads((tmp_path / "out" / "matches.json").read_text())
    names = [m["virtual"] for m in doc["matches"]]
    assert len(names) == 4 and len(set(names)) == 4, names
    files = sorted(p.name for p in (tmp_path / "out").glob("level-*.glb"))
    expected = ["level-kitchen_a.glb", "level-kitchen_b.glb"] if layout == "two names" else \
        ["level-a-kitchen.glb", "level-b-kitchen.glb"]
    assert files == expected
    from test_level_glb import _document

    for path, name in zip(paths, expected):
        level = _document(tmp_path / "out" / name)
        matched = {n["name"]: n["extras"]["pinchmatch"] for n in level["nodes"]
                   if isinstance(n.get("extras"), dict) and "pinchmatch" in n["extras"]
                   and "cost" in n["extras"]["pinchmatch"]}
        assert set(matched) == {"mug", "box"}
        # each node's contacts are its own level's: the mug in the second level is 10 mm further
        # along x
        label = f"{path.parent.name}/{path.name}" if layout != "two names" else path.name
        mine = [m for m in doc["matches"] if m["virtual"] == f"{label}/mug"]
        assert len(mine) == 1
        assert np.allclose(np.reshape(matched["mug"]["virtual_contacts_m"], (-1, 3)) * 1000.0,
                           np.reshape([mine[0]["virtual_pose"]["p1_mm"],
                                       mine[0]["virtual_pose"]["p2_mm"]], (-1, 3)),
                           atol=1e-3)
