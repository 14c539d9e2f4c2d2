"""``pinchmatch view`` on a matches document the page cannot draw: one line naming the field, exit
2; on a result too large for a browser: a warning with the way out."""

import json
import shutil

import pytest
import trimesh

from conftest import assert_one_line, run_cli
from levels import can_and_box_level, can_prop_manifest

@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """A fixed-placement result of pinches and a registered one of tripods."""
    from pinchmatch.cli.main import main

    root = tmp_path_factory.mktemp("results")
    can_and_box_level(root / "kitchen.glb")
    (root / "props.toml").write_text(can_prop_manifest())
    assert main(["match", "--tangible", str(root / "props.toml"), "--virtual",
                 str(root / "kitchen.glb"), "--split", "nodes", "--placement", "fixed", "--count",
                 "80", "--jobs", "1", "-q", "--no-cache", "-o", str(root / "fixed")]) == 0
    trimesh.creation.cylinder(radius=20.0, height=50.0, sections=32).export(root / "can.stl")
    assert main(["match", "--tangible", str(root / "can.stl"), "--virtual", str(root / "can.stl"),
                 "--grasp", "tripod", "--count", "60", "--jobs", "1", "-q", "--no-cache", "-o",
                 str(root / "tripod")]) == 0
    return root


def _changed(results, tmp_path, which, change):
    out = tmp_path / which
    shutil.copytree(results / which, out)
    doc = json.loads((out / "matches.json").read_text())
    change(doc)
    (out / "matches.json").write_text(json.dumps(doc))
    return out


def _set(path, value):
    def change(doc):
        target = doc
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value
    return change


@pytest.mark.parametrize("which, path, value, words", [
    ("tripod", ("matches", 0, "tangible_pose", "contacts_mm"), [], ["contacts_mm", "cannot draw"]),
    ("tripod", ("matches", 0, "virtual_pose", "contacts_mm"), [[0, 0, 0], [1, 1, 1]],
     ["contacts_mm"]),
    ("fixed", ("matches", 0, "redirection", "angle_deg"), None, ["redirection", "angle_deg"]),
    ("fixed", ("matches", 0, "redirection"), [], ["redirection"]),
    ("fixed", ("tangibles", 0, "pose"), "on the table", ["prop's pose"]),
    ("fixed", ("tangibles", 0, "pose", "position_mm"), [0, 900], ["position_mm"]),
    ("fixed", ("matches", 0, "transform_virtual_to_tangible"), [[1, 0, 0], [0, 1, 0]],
     ["transform_virtual_to_tangible"]),
    ("fixed", ("matches", 0, "redirection", "hand_start_mm"), None, ["hand_start_mm"]),
])
def test_a_document_the_page_cannot_draw_is_one_line(
    results, tmp_path, capsys, which, path, value, words):
    out = _changed(results, tmp_path, which, _set(path, value))
    before = (out / "index.html").read_bytes()
    code, _, err = run_cli(capsys, "view", out)
    assert code == 2, err
    assert_one_line(err, "matches.json", *words)
    assert (out / "index.html").read_bytes() == before  # the page it had stays


def test_a_page_larger_than_a_browser_opens_comfortably_is_said(
    results, tmp_path, capsys, monkeypatch, caplog):
    from pinchmatch.export import view

    monkeypatch.setattr(view, "PAGE_NOTE_BYTES", 1000)
    out = tmp_path / "fixed"
    shutil.copytree(results / "fixed", out)
    code, _, err = run_cli(capsys, "view", out)
    assert code == 0
    said = " ".join(caplog.text.split())
    assert "index.html is" in said and "MB" in said and "scenes" in said, said
