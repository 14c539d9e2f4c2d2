import contextlib
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation


def random_rigid(seed):
    """A seeded random rotation (3, 3) and translation (3,) in mm."""
    rng = np.random.default_rng(seed)
    return Rotation.random(random_state=rng).as_matrix(), rng.uniform(-200, 200, 3)


def finger_axes(approach, u, splay_deg, fingers):
    """(n, F, 3) each finger's direction: the hand's ``approach`` (n, 3) turned by ``splay_deg``
    about approach × u, away from the other finger (the thumb, finger 0, away from u; the others
    towards it), by Rodrigues' formula (not the module's arithmetic)."""
    k = np.cross(approach, u)
    k /= np.linalg.norm(k, axis=1, keepdims=True)
    out = []
    for sign in [-1.0] + [1.0] * (fingers - 1):
        out.append(Rotation.from_rotvec(k * np.radians(sign * splay_deg)).apply(approach))
    return np.stack(out, axis=1)


def transformed(mesh, R, t):
    out = mesh.copy()
    out.vertices = mesh.vertices @ R.T + t
    return out


@pytest.fixture
def write_mesh(tmp_path):
    """Write a trimesh to tmp_path/name and return the path."""

    def _write(mesh, name):
        path = tmp_path / name
        mesh.export(path)
        return path

    return _write


@dataclass
class DemoRun:
    out: Path  # the folder it wrote: study, matches, scenes, figures, the page and the objects
    stdout: str
    stderr: str
    study: object  # the Study it computed (pinchmatch.runner.study.Study)


@pytest.fixture(scope="session")
def demo(tmp_path_factory) -> DemoRun:
    """``pinchmatch demo``, run once per test session: what it wrote and printed, and its study."""
    from pinchmatch.cli import commands
    from pinchmatch.cli.main import main

    out = tmp_path_factory.mktemp("demo") / "out"
    studies = []
    real = commands.run_study

    def keep(*args, **kwargs):
        studies.append(real(*args, **kwargs))
        return studies[-1]

    stdout, stderr = io.StringIO(), io.StringIO()
    commands.run_study = keep
    try:
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            code = main(["demo", "-o", str(out)])
    finally:
        commands.run_study = real
    assert code == 0, stderr.getvalue()
    return DemoRun(out, stdout.getvalue(), stderr.getvalue(), studies[0])


@pytest.fixture(scope="session")
def demo_out(demo) -> Path:
    """The folder ``pinchmatch demo`` wrote."""
    return demo.out


@pytest.fixture(scope="session")
def tripod_demo_out(tmp_path_factory) -> Path:
    """The folder ``pinchmatch demo --grasp tripod`` wrote: the study with tripods."""
    from pinchmatch.cli.main import main

    out = tmp_path_factory.mktemp("tripod_demo") / "out"
    stderr = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(stderr):
        code = main(["demo", "--grasp", "tripod", "-o", str(out)])
    assert code == 0, stderr.getvalue()
    return out


def run_cli(capsys, *argv):
    """``pinchmatch ARGV`` in this process: (exit code, stdout, stderr)."""
    from pinchmatch.cli.main import main

    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line(err: str, *words: str) -> str:
    """The bad-input contract: one line on stderr, no traceback, naming every word given."""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


def assert_bad_input(code: int, err: str, *words: str) -> str:
    """Exit code 2 and :func:`assert_one_line`."""
    assert code == 2, err
    return assert_one_line(err, *words)


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    """Every test gets its own feature cache; none writes to the user's."""
    monkeypatch.setenv("PINCHMATCH_CACHE_DIR", str(tmp_path / "cache"))
