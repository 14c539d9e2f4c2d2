"""The price of a match on a real level: tripods against pinches, the default against the plain
search.

    python benchmarks/bench_price.py             # 3 rounds, 1,000 poses per object
    python benchmarks/bench_price.py --rounds 1 --count 300

The level: fourteen YCB scans of household objects (nobody here made them; ``benchmarks/assets.py``)
standing on a counter 80 mm apart, as a y-up glTF in metres, one node each. The props: two more YCB
scans, the mustard bottle and the mug, each standing on its own table (``--support auto``).

Per round, side by side, ``pinchmatch match --jobs 1`` as from the command line: the pinch match
with the defaults (felt ranking, refinement, the targeted step), the plain search (``--refine off
--rank nominal``) and the tripod match with the defaults (``--grasp tripod``), in an order that
turns each round. It prints each run's seconds per object (the run's wall time over the level's
objects) in every round, the median, and the ratios of the medians, the targets beside them: tripods
at most 2x the pinch match, the default at most 1.8x the plain search. Last, the hollow mug's 1,000
feasible tripods and 1,000 pinches, sampled in this process, best of the rounds (target: tripods
under 3 s).
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).parent))
from assets import DEFAULT_ASSETS, ycb_objects  # noqa: E402
from bench_converge import timed_match  # noqa: E402

OBJECTS = ["002_master_chef_can", "003_cracker_box", "004_sugar_box", "005_tomato_soup_can",
           "007_tuna_fish_can", "008_pudding_box", "010_potted_meat_can", "011_banana", "013_apple",
           "017_orange", "021_bleach_cleanser", "040_large_marker", "043_phillips_screwdriver",
           "048_hammer"]
PROPS = ["006_mustard_bottle", "025_mug"]
COUNTER_Y_MM, SPACING_MM = 900.0, 80.0
RUNS = {"pinch, default": [], "pinch, plain": ["--refine", "off", "--rank", "nominal"],
        "tripod, default": ["--grasp", "tripod"]}


def build_level(folder: Path, assets: Path) -> tuple[Path, list[Path]]:
    """level.glb (the objects on a counter, y up, metres) and the props' STL files (mm, z up)."""
    paths = ycb_objects(folder / "scans", OBJECTS + PROPS, assets=assets)
    scene = trimesh.Scene()
    columns = math.ceil(len(OBJECTS) / 2)
    for i, path in enumerate(paths[:len(OBJECTS)]):
        mesh = trimesh.load(path, force="mesh")
        # z up -> y up
        mesh.apply_transform(trimesh.transformations.rotation_matrix(-math.pi / 2, [1, 0, 0]))
        x, z = (i % columns - columns / 2) * 1.5 * SPACING_MM, (i // columns) * 1.5 * SPACING_MM
        centre = mesh.bounds.mean(axis=0)
        mesh.apply_translation([x - centre[0], COUNTER_Y_MM - mesh.bounds[0, 1], z - centre[2]])
        mesh.apply_scale(0.001)
        scene.add_geometry(mesh, node_name=path.stem, geom_name=f"{path.stem}_mesh")
    scene.export(folder / "level.glb")
    return folder / "level.glb", paths[len(OBJECTS):]


def sampling_seconds(folder: Path, assets: Path, rounds: int) -> dict:
    """Best seconds of 1,000 feasible tripods and of 1,000 pinches on the YCB mug, after loading."""
    from pinchmatch import PinchSettings, analyze_object
    from pinchmatch.grasp.analysis import find_pinches

    [path] = ycb_objects(folder / "mug", ["025_mug"], assets=assets)
    # the compiled loops loaded (or compiled) before any clock
    warm = analyze_object(path, units="mm")
    for grasp in ("pinch", "tripod"):
        find_pinches(warm, settings=PinchSettings(count=20, seed=1, grasp=grasp))
    best = {}
    for grasp in ("tripod", "pinch"):
        settings = PinchSettings(count=1000, seed=0, grasp=grasp)
        times = []
        for _ in range(rounds):
            obj = analyze_object(path, units="mm")
            # built before the clock starts: loading, not sampling
            obj.context.tree, obj.context.rays
            t0 = time.perf_counter()
            found, _ = find_pinches(obj, settings=settings)
            times.append(time.perf_counter() - t0)
            assert len(found.points) == 1000, (grasp, len(found.points))
        best[grasp] = min(times)
    return best


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--count", type=int, default=1000, help="poses per object (default 1,000)")
    parser.add_argument("--assets", type=Path, default=DEFAULT_ASSETS)
    args = parser.parse_args(argv)
    print(f"{platform.processor() or platform.machine()}, {platform.python_version()}; "
          f"{len(OBJECTS)} YCB objects, "
          f"props {', '.join(PROPS)}; {args.count} poses; --jobs 1")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        level, props = build_level(folder, args.assets)
        base = ["--tangible", *map(str, props), "--virtual", str(level), "--split", "nodes",
                "--count", str(args.count), "--jobs", "1", "--seed", "0"]
        seconds: dict[str, list[float]] = {name: [] for name in RUNS}
        costs: dict[str, float] = {}
        names = list(RUNS)
        for r in range(args.rounds):
            for name in names[r % len(names):] + names[:r % len(names)]:
                matches, wall = (timed_match(base + RUNS[name],
                                             folder / f"out_{r}_{len(seconds[name])}"))
                seconds[name].append(wall / len(OBJECTS))
                costs[name] = float(np.mean([m["cost"] for m in matches.values()
                                             if m.get("cost") is not None]))
                print(f"  round {r + 1}: {name}: {wall:.1f} s", file=sys.stderr, flush=True)
        median = {name: float(np.median(v)) for name, v in seconds.items()}
        print("\n| run | " + " | ".join(f"round {r + 1} (s/object)" for r in range(args.rounds))
              + " | median (s/object) | mean ranked cost |")
        print("|---|" + "---:|" * (args.rounds + 2))
        for name in RUNS:
            print(f"| {name} | " + " | ".join(f"{s:.2f}" for s in seconds[name])
                  + f" | {median[name]:.2f} | "
                  f"{costs[name]:.3f} |")
        tripod = median["tripod, default"] / median["pinch, default"]
        default = median["pinch, default"] / median["pinch, plain"]
        print(f"\ntripods against pinches: {tripod:.2f}x (target at most 2x)")
        print(f"the default against the plain search: {default:.2f}x (target at most 1.8x)")
        sampled = sampling_seconds(folder, args.assets, args.rounds)
        print(f"the YCB mug's 1,000 tripods: {sampled['tripod']:.2f} s (target under 3 s); 1,000 "
              "pinches: "
              f"{sampled['pinch']:.2f} s")
        print(json.dumps({"seconds_per_object": seconds, "tripod_ratio": round(tripod, 3),
                          "default_ratio": round(default, 3), "sampling_s": sampled}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
