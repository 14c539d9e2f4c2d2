import numpy as np
import pytest
from scipy.spatial.transform import Rotation


def random_rigid(seed):
    """A seeded random rotation (3, 3) and translation (3,) in mm."""
    rng = np.random.default_rng(seed)
    return Rotation.random(random_state=rng).as_matrix(), rng.uniform(-200, 200, 3)


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


@pytest.fixture(scope="session")
def demo_out(tmp_path_factory):
    """The folder a quiet ``pinchmatch demo`` wrote: study, matches, scenes, figures and the page."""
    from pinchmatch.cli.commands import main

    out = tmp_path_factory.mktemp("demo") / "out"
    assert main(["demo", "-o", str(out), "-q"]) == 0
    return out


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    """Every test gets its own feature cache; none writes to the user's."""
    monkeypatch.setenv("PINCHMATCH_CACHE_DIR", str(tmp_path / "cache"))
