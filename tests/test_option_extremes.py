"""Every numeric option of every command at its extremes: a run that works, or one line and exit 2.

The options are read from the command line's own parser, so an option added later is swept too.
"""

from __future__ import annotations

import argparse

import pytest

from pinchmatch.cli.main import main
from pinchmatch.cli.parser import build_parser
from pinchmatch.mesh.shapes import box

#: values past every bound an option could have
EXTREMES = ("nan", "inf", "-inf", "1e308", "-1e308", "0", "-1", "1e-320")
#: options whose values start other work than a small run (folders, budgets, servers): their own
#: tests
SKIP = {"--jobs", "-j", "--budget-s", "--serve", "--port"}


def numeric_options(command: str) -> list[str]:
    parser = build_parser()
    sub = next(a for a in parser._actions
               if isinstance(a, argparse._SubParsersAction)).choices[command]
    return sorted(a.option_strings[-1] for a in sub._actions
                  if a.option_strings and a.type in (int, float) and not set(a.option_strings)
                  & SKIP)


def test_the_sweep_sees_the_options():
    options = numeric_options("match")
    for name in ("--count", "--seed", "--landing-mm", "--distinct-mm", "--top-k",
                 "--friction-cone-deg", "--fingertip-radius-mm", "--max-width-mm"):
        assert name in options


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    folder = tmp_path_factory.mktemp("extremes")
    box((40.0, 30.0, 20.0), subdivide_mm=4.0).mesh.export(folder / "prop.stl")
    box((36.0, 30.0, 24.0), subdivide_mm=4.0).mesh.export(folder / "thing.stl")
    box((50.0, 26.0, 22.0), subdivide_mm=4.0).mesh.export(folder / "other.stl")
    return folder


def _argv(command, meshes, out, option, value):
    """A small run of ``command`` with ``option`` set to ``value``."""
    small = [] if option == "--count" else ["--count", "40"]
    if command == "poses":
        return (["poses", str(meshes / "thing.stl"), "-o", str(out / "poses.json"), "-q", *small,
                 f"{option}={value}"])
    common = ["--virtual", str(meshes / "thing.stl"), "-o", str(out), "-q", "--no-cache",
              "--no-view", "--jobs", "1", *small, f"{option}={value}"]
    if command == "select":
        k = [] if option == "-k" else ["-k", "1"]
        return (["select", "--tangible", str(meshes / "prop.stl"), str(meshes / "other.stl"), *k,
                 *common])
    return ["match", "--tangible", str(meshes / "prop.stl"), "--no-figures", *common]


@pytest.mark.parametrize("command, option",
                         [(c, o) for c in ("match", "select", "poses") for o in numeric_options(c)])
def test_numeric_options_at_their_extremes(meshes, tmp_path, capsys, command, option):
    for k, value in enumerate(EXTREMES):
        out = tmp_path / f"out{k}"
        if command == "poses":
            out.mkdir()
        code = main(_argv(command, meshes, out, option, value))
        err = capsys.readouterr().err.strip()
        assert code in (0, 2, 3), (option, value, code, err)
        assert "Traceback" not in err, (option, value, err)
        if code == 2:
            assert (len(err.splitlines()) == 1
                    and option.lstrip("-").split("-")[0] in err), (option, value, err)
            written = list(out.iterdir()) if command == "poses" else [out] if out.exists() else []
            assert not written, (option, value)
