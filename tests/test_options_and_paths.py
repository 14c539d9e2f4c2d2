"""Options, paths and API arguments that used to be taken wrongly: each is taken as meant, or
refused in one line naming the fix."""

import json
import os

import numpy as np
import pytest
import trimesh

from conftest import assert_one_line, run_cli
from levels import standing_can, tabletop_level
from pinchmatch import PinchSettings, analyze_object, candidate_poses, match_scene
from pinchmatch.errors import ConfigError
from pinchmatch.mesh.manifest import object_specs


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp("files")
    trimesh.creation.box(extents=(40.0, 30.0, 60.0)).export(root / "box.stl")
    trimesh.creation.cylinder(radius=20.0, height=50.0, sections=32).export(root / "can.stl")
    box = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    box.apply_translation([0.0, 0.025, 0.0])
    tabletop_level(root / "kitchen.glb",
                   [("can", standing_can(), (0.0, 0.9, 0.0)), ("box", box, (0.1, 0.9, 0.0))])
    return root


def test_nodes_without_split_is_one_line(files, capsys, tmp_path):
    for option in ("--nodes", "--skip-nodes"):
        code, _, err = run_cli(capsys, "match", "--tangible", files / "box.stl", "--virtual",
                               files / "kitchen.glb", option, "can", "--count", 60, "-o",
                               tmp_path / "out")
        assert code == 2
        assert_one_line(err, "--split nodes", "kitchen.glb")
    assert not (tmp_path / "out").exists()


def test_negative_coordinates_are_values_not_options(files, capsys, tmp_path):
    (tmp_path / "props.toml").write_text('[[object]]\nname = "can_prop"\nshape = { kind = '
                                         '"cylinder", diameter_mm = '
                                         '54, height_mm = 66 }\npose = { position_mm = [0.0, '
                                         '900.0, 0.0], '
                                         'quaternion_xyzw = [-0.7071068, 0.0, 0.0, 0.7071068] }\n')
    code, _, err = run_cli(capsys, "match", "--tangible", tmp_path / "props.toml", "--virtual",
                           files / "kitchen.glb", "--split", "nodes", "--placement", "fixed",
                           "--hand-start", "-100,1050,300", "--user-at", "-100,1050,300", "--count",
                           60, "--jobs", 1, "--no-view", "-q", "--no-cache", "-o", tmp_path / "out")
    assert code == 0, err
    doc = json.loads((tmp_path / "out" / "matches.json").read_text())
    assert doc["settings"]["hand_start_mm"] == [-100.0, 1050.0, 300.0]
    assert doc["matches"][0]["redirection"]["hand_start_mm"] == [-100.0, 1050.0, 300.0]


def test_a_hand_start_inside_a_level_object_is_one_line(files, capsys, tmp_path):
    (tmp_path / "props.toml").write_text('[[object]]\nname = "can_prop"\nshape = { kind = '
                                         '"cylinder", diameter_mm = '
                                         '54, height_mm = 66 }\npose = { position_mm = [300.0, '
                                         '900.0, 0.0], '
                                         'quaternion_xyzw = [-0.7071068, 0.0, 0.0, 0.7071068] }\n')
    code, _, err = run_cli(capsys, "match", "--tangible", tmp_path / "props.toml", "--virtual",
                           files / "kitchen.glb", "--split", "nodes", "--placement", "fixed",
                           "--hand-start", "100,925,0", "--count", 60, "-o", tmp_path / "out")
    assert code == 2
    assert_one_line(err, "inside the level's object box", "--hand-start")


@pytest.mark.parametrize("kind", ["manifest", "poses"])
def test_a_byte_order_mark_is_read_as_utf8(files, capsys, tmp_path, kind):
    if kind == "manifest":
        (tmp_path / "props.toml").write_bytes(b"\xef\xbb\xbf"
                                              + '[[object]]\nfile = '
                                                f'"{files / "box.stl"}"\n'.encode())
        specs = object_specs([tmp_path / "props.toml"], option="--tangible")
        assert [s.display_name for s in specs] == ["box.stl"]
    else:
        (tmp_path / "poses.json").write_bytes(b"\xef\xbb\xbf" + json.dumps(
            {"poses": [{"p1_mm": [20.0, 0.0, 0.0], "p2_mm": [-20.0, 0.0, 0.0]}]}).encode())
        code, _, err = run_cli(capsys, "poses", files / "box.stl", "--poses",
                               tmp_path / "poses.json", "-q", "-o", tmp_path / "out.json")
        assert code == 0, err


def test_a_pipe_or_a_device_is_named_as_such_and_never_read(files, capsys, tmp_path):
    os.mkfifo(tmp_path / "pipe.stl")  # reading it would wait for a writer forever
    for path in (tmp_path / "pipe.stl", "/dev/zero"):
        code, _, err = run_cli(capsys, "match", "--tangible", path, "--virtual", files / "box.stl",
                               "--count", 60, "-o", tmp_path / "out")
        assert code == 2
        assert_one_line(err, str(path), "not a regular file")


def test_an_empty_path_is_refused_not_taken_for_the_current_folder(
    files, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(files)  # a folder full of meshes
    code, _, err = run_cli(capsys, "match", "--tangible", files / "box.stl", "--virtual", "",
                           "--count", 60, "-o", tmp_path / "out")
    assert code == 2
    assert_one_line(err, "--virtual", "empty path")


def test_a_level_node_that_cannot_be_pinched_is_told_to_be_left_out_not_held(capsys, tmp_path):
    # a thin board flat on the floor: no finger beside it
    table = trimesh.creation.box(extents=(0.9, 0.006, 0.6))
    table.apply_translation([0, 0.003, 0])
    tabletop_level(tmp_path / "room.glb",
                   [("board", table, (0.0, 0.0, 0.0)), ("can", standing_can(), (2.0, 0.0, 0.0))])
    trimesh.creation.box(extents=(40.0, 30.0, 60.0)).export(tmp_path / "box.stl")
    code, out, err = run_cli(capsys, "match", "--tangible", tmp_path / "box.stl", "--virtual",
                             tmp_path / "room.glb", "--split", "nodes", "--count", 60, "--jobs", 1,
                             "--no-view", "-q", "--no-cache", "-o", tmp_path / "out")
    said = " ".join(err.split())
    assert ("node board" in said and "--skip-nodes 'board'" in said
            and "--support none" not in said), said


def test_the_api_takes_one_path_as_one_path_and_refuses_bad_vectors_and_mixed_grasps(files):
    assert [s.display_name for s in object_specs(str(files / "box.stl"),
                                                 option="--tangible")] == ["box.stl"]
    assert [s.display_name for s in object_specs(files / "box.stl",
                                                 option="--tangible")] == ["box.stl"]
    for bad in ([np.nan, 0.0, 0.0], [1.0, 2.0], ["a", "b", "c"], [1.0, np.inf, 0.0]):
        with pytest.raises(ConfigError, match="three finite numbers"):
            analyze_object(files / "box.stl", com_mm=bad)
        with pytest.raises(ConfigError, match="three finite numbers"):
            analyze_object(files / "box.stl", axis=bad)
    settings = PinchSettings(count=40)
    pinch = candidate_poses(analyze_object(files / "box.stl"), settings=settings)
    tripod = candidate_poses(analyze_object(files / "can.stl"),
                             settings=PinchSettings(count=40, grasp="tripod"))
    with pytest.raises(ConfigError, match="one grasp"):
        match_scene([pinch], [tripod])


def test_a_tripod_document_says_tripod_and_no_approach_where_the_contacts_meet(
    files, capsys, tmp_path):
    code, out, err = run_cli(capsys, "features", files / "box.stl", "--p1", "20,0,0", "--p2",
                             "20,0.5,0", "--p3", "20,1,0", "-q", "-o", tmp_path / "f.json")
    assert code == 0, err
    doc = json.loads((tmp_path / "f.json").read_text())
    assert doc["settings"]["grasp"] == "tripod"
    assert doc["pose"]["approach"] == [None, None, None] and "reach" in doc["pose"]["broken_rules"]
    assert doc["pose"]["feasible"] is False
