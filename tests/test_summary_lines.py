"""What a run says: the summary fits an 80-column terminal, says which objects are redirected and
why a reference has no cost, names a manifest's key in its objects' errors, and progress names
objects as the result does."""

import json

import pytest
import trimesh

from conftest import assert_one_line, run_cli
from levels import can_and_box_level, can_prop_manifest
from pinchmatch.cli.console import _narrowed
from pinchmatch.mesh.manifest import ObjectSpec
from pinchmatch.runner.tasks import ObjectTask

@pytest.fixture(scope="module")
def level(tmp_path_factory):
    root = tmp_path_factory.mktemp("level")
    can_and_box_level(root / "kitchen.glb", "a_long_named_can_on_the_counter", (0.12, 0.9, 0.05))
    (root / "props.toml").write_text(can_prop_manifest())
    return root


def test_a_fixed_run_fits_80_columns_says_each_mode_and_why_references_are_null(
    level, tmp_path, capsys,
                                                                               monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    code, out, err = run_cli(capsys, "match", "--tangible", level / "props.toml", "--virtual",
                             level / "kitchen.glb", "--split", "nodes", "--placement", "fixed",
                             "--count", 80, "--jobs", 1, "--no-view", "--no-cache", "-o",
                             tmp_path / "out")
    assert code == 0, err
    doc = json.loads((tmp_path / "out" / "matches.json").read_text())
    modes = {m["virtual"]: m["redirection"]["mode"] for m in doc["matches"]}
    lines = out.splitlines()
    header = next(i for i, line in enumerate(lines) if line.split()[:3]
                  == ["virtual", "tangible", "mode"])
    order = [m["virtual"] for m in doc["matches"]]
    for k, (name, mode) in enumerate(sorted(modes.items(), key=lambda x: order.index(x[0]))):
        row = lines[header + 2 + k].split()  # one line per match: no cell folded onto a second line
        assert row[:3] == [name, "can_prop", mode], lines[header:header + 4]
    assert all(len(line) <= 80 for line in lines)
    said = " ".join(out.split())
    assert "left out to fit 80 columns" in said
    assert "ref_cost is null for every object" in said and "level's node" in said


def test_narrowing_leaves_out_optional_columns_in_order_until_it_fits():
    rows = [("virtual", "cost", "offset_mm", "ref_cost"), ("mug", "0.5", "+0.10", "null")]
    assert _narrowed(rows, ("offset_mm", "ref_cost"), 80) == (rows, [])
    narrow, dropped = _narrowed(rows, ("offset_mm", "ref_cost"), 21)  # 7 + 4 + 8 and two spaces
    assert (dropped == ["offset_mm"] and narrow
            == [("virtual", "cost", "ref_cost"), ("mug", "0.5", "null")])
    assert _narrowed(rows, ("offset_mm", "ref_cost"), 5)[1] == ["offset_mm", "ref_cost"]


def test_a_manifest_objects_units_error_names_the_manifest_key(tmp_path, capsys):
    # metres, read as mm
    trimesh.creation.box(extents=(0.04, 0.03, 0.06)).export(tmp_path / "small.stl")
    (tmp_path / "props.toml").write_text('[[object]]\nfile = "small.stl"\nname = "block"\n')
    trimesh.creation.icosphere(radius=25.0).export(tmp_path / "ball.stl")
    code, _, err = run_cli(capsys, "match", "--tangible", tmp_path / "props.toml", "--virtual",
                           tmp_path / "ball.stl", "--count", 50, "-o", tmp_path / "out")
    assert code == 2
    line = assert_one_line(err, 'units = "m" in its entry of', "props.toml")
    assert "--units" not in line


def test_progress_names_an_object_as_the_result_does(tmp_path):
    assert ObjectTask("tangible", "props/can.stl",
                      spec=ObjectSpec("props/can.stl", name="can_prop")).name == "can_prop"
    assert ObjectTask("virtual", "kitchen.glb",
                      spec=ObjectSpec("kitchen.glb", node="mug")).name == "mug"
    assert ObjectTask("virtual", "a/mug.stl").name == "mug.stl"
