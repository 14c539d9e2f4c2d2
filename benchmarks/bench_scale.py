"""Benchmark of ``pinchmatch match`` on an asset library: start-up, --jobs, the cache, growth.

    python benchmarks/bench_scale.py                  # all three parts (25 minutes on 2 cores)
    python benchmarks/bench_scale.py --quick          # fewer objects (about 4 minutes)
    python benchmarks/bench_scale.py --only startup   # start-up of the command line and two workers
    python benchmarks/bench_scale.py --only real      # 5 real props x 40 real objects, the outputs
    python benchmarks/bench_scale.py --only growth    # generated objects: growth in objects, poses

**start-up**: ``pinchmatch --help`` and a bad option against ``python -c pass`` (median of 7), and
two local workers started with one task each.

**real**: 5 props and 40 virtual objects from pybullet_data's random_urdfs (third-party meshes,
subdivided to about 16k faces; see ``assets.py``), matched as users run it, with default options and
its default outputs (matches.json, scenes, the page; PNG figures only with ``--figures``, and a
checkout from before that writes them by default): cold with ``--jobs 1`` and with the default jobs
(empty caches), then warm from the cache with both. Prints the ratios jobs 2 / jobs 1 and warm /
cold, and each core's busy share over the middle 80 % of each run (/proc/stat).

**growth**: generated objects (seeded ellipsoids, cylinders and tori of random sizes, 20,000 faces,
randomly rotated; five tangibles: the stacked study prop, an ellipsoid, a cylinder, a torus and a
subdivided box), ``--no-view --no-figures`` (the scenes are written): cold with --jobs 1 and 2,
warm, warm with --format jsonl; cold with 25, 50, 100 (and 200) objects; cold with 500, 1000 and
2000 poses per object on 50 objects. The growth plot goes to ``--plot`` (default
benchmarks/scale.png).

Per run: wall time, time per virtual object, the peak resident memory of the main process and of the
largest worker (sampled /proc VmHWM), and each core's busy share.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

FACES = 20_000


def make_objects(folder: Path, n_virtual: int, seed: int = 7) -> tuple[list[Path], list[Path]]:
    from pinchmatch.mesh.shapes import box, cylinder, ellipsoid, stacked_prop, torus

    rng = np.random.default_rng(seed)
    (folder / "t").mkdir(parents=True, exist_ok=True)
    (folder / "v").mkdir(parents=True, exist_ok=True)
    tangibles = {
        "prop.stl": stacked_prop(sections=512),
        "egg.stl": ellipsoid((45.0, 30.0, 22.0), faces=FACES).mesh,
        "rod.stl": cylinder(15.0, 90.0, triangulation="random", faces=FACES, seed=1).mesh,
        "ring.stl": torus(35.0, 10.0, triangulation="random", faces=FACES, seed=2).mesh,
        "brick.stl": box((70.0, 40.0, 25.0), subdivide_mm=1.6).mesh,
    }
    for name, mesh in tangibles.items():
        mesh.export(folder / "t" / name)
    for k in range(n_virtual):
        kind = k % 3
        if kind == 0:
            mesh = ellipsoid(rng.uniform(12, 50, 3), triangulation="random", faces=FACES,
                             seed=k).mesh
        elif kind == 1:
            mesh = cylinder(rng.uniform(8, 30), rng.uniform(30, 120), triangulation="random",
                            faces=FACES, seed=k).mesh
        else:
            minor = rng.uniform(6, 14)
            mesh = torus(minor + rng.uniform(10, 30), minor, triangulation="random", faces=FACES,
                         seed=k).mesh
        mesh.apply_transform(np.block([[Rotation.random(random_state=rng).as_matrix(),
                                        np.zeros((3, 1))],
                                       [np.zeros((1, 3)), np.ones((1, 1))]]))
        mesh.export(folder / "v" / f"obj{k:04d}.stl")
    return sorted((folder / "t").glob("*.stl")), sorted((folder / "v").glob("*.stl"))


def _hwm_mib(pid: int) -> float:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


def _children(pid: int) -> list[int]:
    out = []
    try:
        for task in Path(f"/proc/{pid}/task").iterdir():
            out += [int(c) for c in (task / "children").read_text().split()]
    except OSError:
        pass
    return out + [g for c in out for g in _children(c)]


def _cpu_busy() -> np.ndarray:
    """(cores, 2) busy and total jiffies of each core so far (/proc/stat)."""
    rows = [line.split() for line in Path("/proc/stat").read_text().splitlines()
            if line.startswith("cpu") and line[3].isdigit()]
    ticks = np.array([[int(v) for v in r[1:9]] for r in rows], dtype=np.int64)
    idle = ticks[:, 3] + ticks[:, 4]
    return np.stack([ticks.sum(axis=1) - idle, ticks.sum(axis=1)], axis=1)


def run(tangibles, virtuals, *, poses: int | None, jobs: int | None, cache: Path, out: Path,
        fmt: str = "json", outputs: bool = False) -> dict:
    """One ``pinchmatch match`` as a user runs it; ``outputs``: the default outputs (the page, and
    the figures where a checkout writes them by default), else the scenes only. ``poses`` and
    ``jobs`` None: the defaults."""
    argv = [sys.executable, "-m", "pinchmatch", "match", "--tangible", *map(str, tangibles),
            "--virtual", *map(str, virtuals), "--cache", str(cache), "-o", str(out), "-q"]
    argv += ["--count", str(poses)] if poses else []
    argv += ["--jobs", str(jobs)] if jobs else []
    argv += [] if outputs else ["--format", fmt, "--no-view", "--no-figures"]
    peak = {"main": 0.0, "worker": 0.0}
    busy = []
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, stderr=subprocess.PIPE, text=True)

    def sample():
        while proc.poll() is None:
            peak["main"] = max(peak["main"], _hwm_mib(proc.pid))
            for c in _children(proc.pid):
                peak["worker"] = max(peak["worker"], _hwm_mib(c))
            busy.append(_cpu_busy())
            time.sleep(0.05)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    _, err = proc.communicate()
    seconds = time.perf_counter() - t0
    sampler.join()
    if proc.returncode != 0:
        raise SystemExit(f"pinchmatch failed ({proc.returncode}): {err.strip()}")
    entries = len(list(cache.glob("*.npz")))
    # both cores' busy share over the middle 80 % of the run (start-up and the final writing left
    # out)
    lo, hi = len(busy) // 10, max(len(busy) - len(busy) // 10 - 1, len(busy) // 10 + 1)
    d = busy[min(hi, len(busy) - 1)] - busy[lo] if len(busy) > 1 else np.ones((1, 2))
    per_core = d[:, 0] / np.maximum(d[:, 1], 1)
    return {"seconds": seconds, "main_mib": peak["main"], "worker_mib": peak["worker"],
            "cache_entries": entries, "busy": per_core}


def _median_seconds(argv: list[str], runs: int = 7) -> float:
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


WORKER_START = """
import sys, time
def main():
    from pinchmatch.runner.forkserver import start_worker_server
    # what the command line does right after parsing, before it loads the pipeline
    start_worker_server()
    import pinchmatch.runner.tasks  # the run's own load
    from pinchmatch.runner.executors import executor
    t0 = time.perf_counter()
    with executor(2) as ex:
        list(ex.map(abs, [1, 2]))
        print(time.perf_counter() - t0)
if __name__ == "__main__":
    main()
"""


def startup() -> None:
    """Start-up of the command line and of the workers, against the interpreter's own."""
    bare = _median_seconds([sys.executable, "-c", "pass"])
    help_s = _median_seconds([sys.executable, "-m", "pinchmatch", "--help"])
    bad_s = _median_seconds([sys.executable, "-m", "pinchmatch", "match", "--bogus"])
    with tempfile.TemporaryDirectory() as tmp:
        script = Path(tmp) / "workers.py"
        script.write_text(WORKER_START)
        worker_s = float(np.median([float(subprocess.run(
            [sys.executable, str(script)], capture_output=True,
                                                         text=True, check=True).stdout)
                                                         for _ in range(3)]))
    print(f"start-up, median of 7: python -c pass {bare:.3f} s; pinchmatch --help {help_s:.3f} s "
          f"({help_s / bare:.1f}x); a bad option {bad_s:.3f} s ({bad_s / bare:.1f}x)")
    print(f"local workers, median of 3: two started, one task each, {worker_s:.2f} s after the run "
          "has loaded")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="16 virtual objects, 8 for the poses rows")
    parser.add_argument("--only", choices=("startup", "real", "growth"),
                        help="one part only: start-up, the real assets (all outputs), growth "
                             "(generated objects)")
    parser.add_argument("--plot", default=str(Path(__file__).with_name("scale.png")),
                        help="where the growth plot goes")
    args = parser.parse_args()
    if args.only in (None, "startup"):
        startup()
    if args.only in (None, "real"):
        real_runs(Path(tempfile.mkdtemp(prefix="pinchmatch-bench-")), quick=args.quick)
    if args.only in (None, "growth"):
        growth(args.quick, args.plot)


def _table(rows) -> None:
    print(f"{'run':>22} {'objects':>7} {'poses':>5} {'jobs':>4} {'seconds':>8} {'s/object':>8} "
          f"{'main_MiB':>8} {'worker_MiB':>10} {'busy_%':>9}")
    for r in rows:
        busy = "/".join(f"{100 * b:.0f}" for b in r["busy"])
        print(f"{r['run']:>22} {r['objects']:>7} {r['poses'] or 'dflt':>5} "
              f"{r['jobs'] or 'dflt':>4} "
              f"{r['seconds']:>8.1f} {r['seconds'] / r['objects']:>8.3f} {r['main_mib']:>8.0f} "
              f"{r['worker_mib']:>10.0f} {busy:>9}")


def real_runs(root: Path, quick: bool) -> None:
    """5 real props x 40 real virtual objects of about 16k faces, default options, default
    outputs."""
    from assets import face_counts, random_objects

    n = 10 if quick else 40
    t0 = time.perf_counter()
    virtuals = random_objects(root / "v", range(n))
    tangibles = random_objects(root / "t", range(995, 1000))
    faces = face_counts(virtuals + tangibles)
    print(f"\n# {len(tangibles)} props x {len(virtuals)} virtual objects: pybullet_data "
          "random_urdfs, "
          f"{faces.min()}-{faces.max()} faces (mean {faces.mean():.0f}), written in "
          f"{time.perf_counter() - t0:.0f} s; "
          "pinchmatch match with default options and default outputs (matches.json, scenes, page)")
    rows = []
    for name, jobs, cache in (("cold --jobs 1", 1, "c1"), ("cold default jobs", None, "c2"),
                              ("warm --jobs 1", 1, "c2"), ("warm default jobs", None, "c2")):
        r = run(tangibles, virtuals, poses=None, jobs=jobs, cache=root / cache,
                out=root / "out" / cache, outputs=True)
        rows.append({"run": name, "objects": n, "poses": None, "jobs": jobs, **r})
        print(f"  {name}: {r['seconds']:.1f} s", file=sys.stderr, flush=True)
    _table(rows)
    cold1, cold2, warm1, warm2 = (r["seconds"] for r in rows)
    print(f"ratio jobs 2 / jobs 1, cold: {cold1 / cold2:.2f}x faster; both cores busy "
          f"{'/'.join(f'{100 * b:.0f}' for b in rows[1]['busy'])} % (middle 80 % of the default "
          "run)")
    print(f"ratio warm / cold, default outputs: {cold1 / warm1:.1f}x with --jobs 1, "
          f"{cold2 / warm2:.1f}x by default")


def growth(quick: bool, plot_path: str) -> None:
    """Generated objects: cache, --jobs, growth with objects and poses (scenes only)."""
    n = 16 if quick else 200
    steps = [4, 8, 16] if quick else [25, 50, 100, 200]
    n_poses_objects = 8 if quick else 50

    root = Path(tempfile.mkdtemp(prefix="pinchmatch-bench-"))
    t0 = time.perf_counter()
    tangibles, virtuals = make_objects(root / "objects", n)
    print(f"# {len(virtuals)} virtual objects ({FACES} faces) and {len(tangibles)} tangibles "
          "generated in "
          f"{time.perf_counter() - t0:.0f} s; {os.cpu_count()} cores, {platform.machine()}, Python "
          f"{platform.python_version()}")

    rows = []

    def row(name, objects, poses, jobs, cache, fmt="json"):
        r = run(tangibles, virtuals[:objects], poses=poses, jobs=jobs, cache=root / cache,
                out=root / "out" / name, fmt=fmt)
        rows.append({"run": name, "objects": objects, "poses": poses, "jobs": jobs, **r})
        print(f"  {name}: {r['seconds']:.1f} s", file=sys.stderr, flush=True)
        return r

    cold1 = row("cold --jobs 1", n, 1000, 1, "cache-j1")
    cold2 = row("cold --jobs 2", n, 1000, 2, "cache-j2")
    warm1 = row("warm --jobs 1", n, 1000, 1, "cache-j2")
    warm2 = row("warm --jobs 2", n, 1000, 2, "cache-j2")
    row("warm --jobs 2 jsonl", n, 1000, 2, "cache-j2", fmt="jsonl")
    growth_objects = {n: cold2["seconds"]}
    for k in steps[:-1]:
        growth_objects[k] = row(f"cold {k} objects", k, 1000, 2, f"cache-o{k}")["seconds"]
    growth_poses = {}
    for poses in (500, 1000, 2000):
        growth_poses[poses] = row(f"cold {poses} poses", n_poses_objects, poses, 2,
                                  f"cache-p{poses}")["seconds"]

    print()
    _table(rows)
    print()
    print(f"speed-up of --jobs 2 over --jobs 1, cold: {cold1['seconds'] / cold2['seconds']:.2f}x")
    print(f"warm over cold: {cold1['seconds'] / warm1['seconds']:.1f}x with --jobs 1, "
          f"{cold2['seconds'] / warm2['seconds']:.1f}x with --jobs 2, "
          f"{cold1['seconds'] / warm2['seconds']:.1f}x cold --jobs 1 over warm --jobs 2")
    ks = np.array(sorted(growth_objects))
    ts = np.array([growth_objects[k] for k in ks])
    slope, intercept = np.polyfit(ks, ts, 1)
    fit = slope * ks + intercept
    r2 = 1 - ((ts - fit) ** 2).sum() / ((ts - ts.mean()) ** 2).sum()
    print(f"time vs objects: {slope:.3f} s per object + {intercept:.1f} s, R^2 = {r2:.4f}; "
          "log-log slope "
          f"{np.polyfit(np.log(ks), np.log(ts - intercept if intercept > 0 else ts), 1)[0]:.2f}")
    ps = np.array(sorted(growth_poses))
    tp = np.array([growth_poses[p] for p in ps])
    print(f"time vs poses ({n_poses_objects} objects): "
          + ", ".join(f"{p}: {t:.1f} s" for p, t in zip(ps, tp)))
    plot(ks, ts, slope, intercept, ps, tp, n_poses_objects, plot_path)
    print(f"plot: {plot_path}")


def plot(ks, ts, slope, intercept, ps, tp, n_poses_objects, path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.0, 3.6), layout="constrained")
    FigureCanvasAgg(fig)
    a, b = fig.subplots(1, 2)
    a.plot(ks, ts, "o", color="#1f77b4", label="measured")
    a.plot(ks, slope * ks + intercept, "-", color="#999999",
           label=f"{slope:.2f} s/object + {intercept:.1f} s")
    a.set(xlabel="virtual objects (1000 poses each, 5 tangibles)",
          ylabel="wall time, cold, --jobs 2 (s)")
    a.legend(frameon=False, fontsize=8)
    b.plot(ps, tp, "o-", color="#ff7f0e")
    b.set(xlabel="poses per object", ylabel="wall time, cold, --jobs 2 (s)",
          title=f"{n_poses_objects} virtual objects", xticks=ps)
    for ax in (a, b):
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
    fig.savefig(path, dpi=100)


if __name__ == "__main__":
    main()
