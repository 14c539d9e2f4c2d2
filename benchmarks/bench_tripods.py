"""Tripod grasps on real scans: sampling speed, the exact search's price per pair, and pinch against
tripod.

    python benchmarks/bench_tripods.py            # all three tables
    python benchmarks/bench_tripods.py --quick    # 300 poses per object in the scene, not 1,000
    python benchmarks/bench_tripods.py --only sampling|search|scene

1. **Sampling:** 1,000 feasible tripods on YCB scans of 16,384 triangles (target: under 3 s on a
   2-core machine), beside 1,000 pinches on the same scan, seconds after loading.
2. **The exact search per pair:** the separable pass over every (tangible pose, virtual pose) pair
   (:func:`pinchmatch.match.cost.pair_cost_blocks`), 2,000 x 2,000 poses, tripods beside pinches, ns
   per pair (best of 7).
3. **Pinch against tripod on one scene:** 8 YCB objects matched against 4 YCB props (Rubik's cube,
   mug, mustard bottle, baseball) with each grasp, the default match; per object the best prop and
   its ranked cost, which grasp feels closer, and where a tripod is impossible.
"""

from __future__ import annotations

import argparse
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

# benchmarks/assets.py: the packages, downloaded once
from assets import DEFAULT_ASSETS, ycb_objects
from pinchmatch import (Config, MatchSettings, PinchSettings, analyze_object, candidate_poses,
                        match_scene)
from pinchmatch.errors import NoFeasiblePinchError
from pinchmatch.grasp.analysis import find_pinches
from pinchmatch.match.cost import CostModel, pair_cost_blocks

SPEED_SCANS = ["013_apple", "005_tomato_soup_can", "025_mug", "011_banana", "037_scissors",
               "048_hammer"]
PROPS = ["077_rubiks_cube", "025_mug", "006_mustard_bottle", "055_baseball"]
OBJECTS = ["013_apple", "011_banana", "037_scissors", "033_spatula", "040_large_marker",
           "048_hammer", "029_plate", "024_bowl"]


def table(rows, head) -> str:
    cols = [head] + [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cols) for i in range(len(head))]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in cols)


def sampling(folder: Path, assets: Path) -> None:
    rows = []
    paths = ycb_objects(folder, SPEED_SCANS, assets=assets)
    # the compiled spread loop is loaded (or compiled) before any clock
    warm = analyze_object(paths[0], units="mm")
    for grasp in ("pinch", "tripod"):
        find_pinches(warm, settings=PinchSettings(count=20, seed=1, grasp=grasp))
    for path in paths:
        obj = analyze_object(path, units="mm")
        obj.context.tree, obj.context.rays  # built before the clock starts: loading, not sampling
        seconds = {}
        for grasp in ("pinch", "tripod"):
            t0 = time.perf_counter()
            grasps, _ = find_pinches(obj, settings=PinchSettings(count=1000, seed=0, grasp=grasp))
            seconds[grasp] = (time.perf_counter() - t0, len(grasps))
        rows.append([path.stem, len(obj.loaded.mesh.faces), seconds["pinch"][1],
                     f"{seconds['pinch'][0]:.2f}", seconds["tripod"][1],
                     f"{seconds['tripod'][0]:.2f}",
                     f"{seconds['tripod'][0] / seconds['pinch'][0]:.2f}"])
    print(table(rows, ["scan", "faces", "pinches", "pinch s", "tripods", "tripod s", "x pinch"]))


def search_speed(folder: Path, assets: Path, n: int = 2000) -> None:
    path = ycb_objects(folder, ["025_mug"], assets=assets)[0]
    obj = analyze_object(path, units="mm")
    model = CostModel()
    rows = []
    for grasp in ("pinch", "tripod"):
        table_ = candidate_poses(obj, settings=PinchSettings(count=n, seed=0, grasp=grasp)).table
        best = np.inf
        for _ in range(7):
            t0 = time.perf_counter()
            for _, block, _ in pair_cost_blocks(table_, table_, model):
                block.min()
            best = min(best, time.perf_counter() - t0)
        rows.append([grasp, len(table_), table_.shape[1], f"{best:.3f}",
                     f"{1e9 * best / len(table_) ** 2:.1f}"])
    print(table(rows, ["grasp", "poses", "contacts", "seconds", "ns/pair"]))


def pinch_against_tripod(folder: Path, assets: Path, count: int) -> None:
    paths = {p.stem: p for p in ycb_objects(folder, sorted(set(PROPS + OBJECTS)), assets=assets)}
    results = {}
    for grasp in ("pinch", "tripod"):
        settings = PinchSettings(count=count, seed=0, grasp=grasp)
        props = [candidate_poses(analyze_object(paths[p], units="mm"), settings=settings)
                 for p in PROPS]
        config = Config(settings, MatchSettings(top_k=1))
        for name in OBJECTS:
            t0 = time.perf_counter()
            try:
                virtual = candidate_poses(analyze_object(paths[name], units="mm"),
                                          settings=settings)
            except NoFeasiblePinchError as exc:
                results[(name, grasp)] = (None, None,
                                          str(exc).split("; ")[0].split(": ", 1)[-1][:60], 0.0)
                continue
            best = match_scene(props, [virtual], config=config).matches[0].best
            results[(name, grasp)] = (best.tangible_name.split(".")[0], best.cost, None,
                                      time.perf_counter() - t0)
    rows = []
    for name in OBJECTS:
        p, t = results[(name, "pinch")], results[(name, "tripod")]
        closer = "-" if t[1] is None or p[1] is None else ("tripod" if t[1] < p[1] else "pinch")
        rows.append([name, p[0] or "-", "-" if p[1] is None else f"{p[1]:.3f}", t[0] or "-",
                     "-" if t[1] is None else f"{t[1]:.3f}", closer, t[2] or ""])
    print(table(rows,
                ["object", "pinch prop", "pinch JND", "tripod prop", "tripod JND", "closer",
                 "tripod impossible"]))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="300 poses per object in the scene table")
    parser.add_argument("--assets", type=Path, default=DEFAULT_ASSETS)
    parser.add_argument("--only", choices=("sampling", "search", "scene"),
                        help="one of the three tables")
    args = parser.parse_args(argv)
    print(f"# {platform.machine()}, {platform.python_version()}, {time.strftime('%Y-%m-%d')}")
    with tempfile.TemporaryDirectory() as tmp:
        if args.only in (None, "sampling"):
            print("\n## sampling, 1,000 asked (seconds after loading)")
            sampling(Path(tmp) / "speed", args.assets)
        if args.only in (None, "search"):
            print("\n## the exact search's separable pass, every pair of 2,000 x 2,000 poses (best "
                  "of 7)")
            search_speed(Path(tmp) / "search", args.assets)
        if args.only in (None, "scene"):
            print("\n## pinch against tripod: 8 YCB objects on 4 YCB props, the default match "
                  "(ranked: expected cost)")
            pinch_against_tripod(Path(tmp) / "scene", args.assets, 300 if args.quick else 1000)
    return 0


if __name__ == "__main__":
    sys.exit(main())
