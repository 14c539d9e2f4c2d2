"""Benchmark of `pinchmatch select` on real third-party meshes: a shelf of 15 props, a scene of 20
objects.

    python benchmarks/bench_select.py              # cold and warm runs, K = 2, coverage up to 6
    python benchmarks/bench_select.py --objective noticeable

The scene: robosuite's seven household objects (bottle, bread, can, cereal, handles, lemon, milk),
pybullet_data's duck, teddy and Lego brick, and ten of its ``random_urdfs`` objects (000-009); the
shelf: fifteen more ``random_urdfs`` objects (950-964), procedural rocks and blobs of 60-130 mm. All
are read from the wheels on PyPI (``benchmarks/assets.py``; nothing is installed), the random
objects midpoint-subdivided to about 6,000 faces. Prints each run's wall time, the coverage curve
(exact for every K here: C(15, K) is at most 5,005 subsets) and the chosen props' per-object table.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from assets import DEFAULT_ASSETS, random_objects  # noqa: E402
from bench_reach import real_meshes  # noqa: E402

SCENE_REAL = ("robosuite", "pybullet duck", "pybullet teddy", "pybullet lego")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objective", choices=("mean", "noticeable", "max"), default="mean")
    parser.add_argument("-k", type=int, default=2)
    parser.add_argument("--max-k", type=int, default=6)
    args = parser.parse_args()
    root = Path(tempfile.mkdtemp(prefix="pinchmatch-bench-select-"))
    (root / "scene").mkdir(parents=True)
    scene = [p for name, p in real_meshes(DEFAULT_ASSETS, root / "scene")
             if name.startswith(SCENE_REAL)]
    scene += random_objects(root / "scene", range(10), faces=6000)
    shelf = random_objects(root / "shelf", range(950, 965), faces=6000)
    print(f"# pinchmatch select: a shelf of {len(shelf)} props, a scene of {len(scene)} objects; "
          f"-k {args.k} --objective {args.objective} --max-k {args.max_k}")
    argv = [sys.executable, "-m", "pinchmatch", "select", "--tangible", *map(str, shelf),
            "--virtual", *map(str, scene), "-k", str(args.k), "--objective", args.objective,
            "--max-k", str(args.max_k), "--cache", str(root / "cache")]
    for run in ("cold", "warm"):
        out = root / f"out-{run}"
        t0 = time.perf_counter()
        proc = subprocess.run(argv + ["-o", str(out), "-q"], capture_output=True, text=True)
        seconds = time.perf_counter() - t0
        if proc.returncode not in (0, 3):
            raise SystemExit(f"select failed ({proc.returncode}): {proc.stderr.strip()}")
        print(f"{run}: {seconds:.1f} s (exit {proc.returncode})")
    doc = json.loads((root / "out-warm" / "selection.json").read_text())
    print(f"\n{'K':>2} {'objective':>10} {'mean_cost':>10} {'worst':>9} {'noticeable':>10} "
          f"{'exact':>5}  props")
    for c in doc["coverage"]:
        print(f"{c['k']:>2} {c['value']:>10} {c['mean_cost']:>10} {c['worst_cost']:>9} "
              f"{c['noticeable_count']:>10} "
              f"{str(c['exact']):>5}  {', '.join(c['props'])}")
    print(f"\nchosen: {', '.join(doc['selection']['props'])}; suggestion: {doc['suggestion']}")
    print(f"\n{'virtual':>28} {'tangible':>16} {'cost':>9} {'noticeable':>10} "
          f"{'best addition':>16}")
    for o in doc["objects"]:
        print(f"{o['virtual']:>28} {str(o['tangible']):>16} {str(o['cost']):>9} "
              f"{str(o['noticeable']):>10} "
              f"{str(o['best_addition']):>16}")
    if doc["unservable"]:
        print(f"no shelf prop serves: {', '.join(doc['unservable'])}")


if __name__ == "__main__":
    main()
