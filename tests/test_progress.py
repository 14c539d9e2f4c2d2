"""Progress where stderr is no terminal: a pipe or a log gets plain lines now and then, a short run
none."""

from __future__ import annotations

import importlib
import re

from conftest import run_cli
from levels import standing_can, tabletop_level

PROP = ('[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, height_mm = '
        '66 }\n')


def _level(folder):
    tabletop_level(folder / "kitchen.glb", [("can_a", standing_can(), (0.1, 0.0, 0.0)),
                                           ("can_b", standing_can(0.02, 0.09), (-0.12, 0.0, 0.05))])
    (folder / "props.toml").write_text(PROP)


def _run(capsys, folder, *extra):
    return run_cli(capsys, "match", "--tangible", folder / "props.toml", "--virtual",
                   folder / "kitchen.glb", "--split", "nodes", "--count", 60, "-o", folder / "out",
                   "--no-view", "--jobs", 1, *extra)


def test_a_piped_run_prints_plain_progress_lines(tmp_path, capsys, monkeypatch):
    console = importlib.import_module("pinchmatch.cli.console")

    _level(tmp_path)
    monkeypatch.setattr(console, "PROGRESS_LINE_S", 0.0)
    code, out, err = _run(capsys, tmp_path)
    assert code == 0, err
    lines = [ln for ln in err.splitlines() if re.search(r": \d+/\d+.*, \d+ s$", ln)]
    assert lines, err
    counts = [tuple(map(int, re.search(r"(\d+)/(\d+)", ln).groups())) for ln in lines]
    assert all(0 <= done <= total for done, total in counts)
    assert "\\r" not in err and "\\x1b" not in err  # no bar redrawn in place, no colour codes


def test_a_short_or_quiet_run_prints_none(tmp_path, capsys, monkeypatch):
    console = importlib.import_module("pinchmatch.cli.console")

    _level(tmp_path)
    code, out, err = _run(capsys, tmp_path)  # done before the first line is due
    assert code == 0 and not re.search(r"\d+/\d+.*, \d+ s$", err, re.M)
    monkeypatch.setattr(console, "PROGRESS_LINE_S", 0.0)
    code, out, err = _run(capsys, tmp_path, "-q")
    assert code == 0 and not re.search(r"\d+/\d+.*, \d+ s$", err, re.M)
