"""Benchmark of the matching search (``pinchmatch match``): exact search over all pose pairs.

    python benchmarks/bench_match.py            # 1k, 5k and 10k poses per object (about a minute)
    python benchmarks/bench_match.py --quick    # 1k and 3k

Poses are sampled on two real objects (the example prop as the tangible, an
ellipsoid as the virtual object). For each size it times the whole search
(``match_scene``: blockwise separable costs with both finger orders, the
pool, exact evaluation and registration of the pooled pairs, three distinct
alternatives), first call and the median of three more, and the peak of
memory allocated during the search (tracemalloc, which sees numpy's
buffers). ``exact`` checks, at the smallest size, that the best cost equals
a brute-force evaluation of every pair. The target is 10,000 x 10,000 poses
in <= 1 s on the project's 2-core machine.

What bounds it: two matrix products per block of 2,048 tangible poses
(BLAS, both cores), then three passes over each block (finger order,
clamp, threshold); the exact part is a few thousand pairs.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

from pinchmatch.grasp.analysis import analyze_object
from pinchmatch.cli.commands import example_mesh_path
from pinchmatch.match.cost import PAPER_CRITERIA
from pinchmatch.match.scene import match_scene
from pinchmatch.match.search import MatchSettings, cost_model, evaluate_pairs
from pinchmatch.match.candidates import candidate_poses
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.mesh.shapes import ellipsoid


def timed_search(T, V, settings) -> tuple[float, float, float, float]:
    model = cost_model(settings, [T, V])
    t0 = time.perf_counter()
    scene = match_scene([T], [V], settings=settings, model=model)
    first_s = time.perf_counter() - t0
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        match_scene([T], [V], settings=settings, model=model)
        times.append(time.perf_counter() - t0)
    tracemalloc.start()
    match_scene([T], [V], settings=settings, model=model)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return first_s, statistics.median(times), peak / 2**20, scene.matches[0].best.cost


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1k and 3k poses only")
    args = parser.parse_args()
    sizes = [1000, 3000] if args.quick else [1000, 5000, 10000]
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"python {platform.python_version()}, numpy {np.__version__}")
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "ellipsoid.stl"
        ellipsoid((40.0, 25.0, 18.0), faces=20000).mesh.export(path)
        count = max(sizes)
        T = candidate_poses(analyze_object(example_mesh_path()),
                            settings=PinchSettings(count=count))
        V = candidate_poses(analyze_object(path), settings=PinchSettings(count=count, seed=1))
    print(f"sampled {len(T)} + {len(V)} poses in {time.perf_counter() - t0:.1f} s (not part of the "
          "search)\n")

    header = ["poses_t", "poses_v", "pairs_M", "criteria", "first_s", "median_s", "pairs_M_per_s",
              "peak_MiB", "exact"]
    rows = []
    # the search over the given poses alone: refinement would add poses the brute force does not see
    search_only = dict(refine=False, landing_mm=0.0)
    settings_list = [("default", MatchSettings(**search_only)),
                     ("paper+range", MatchSettings(weights=dict.fromkeys(PAPER_CRITERIA, 1.0),
                                                   criteria=PAPER_CRITERIA, normalize="range",
                                                   **search_only))]
    for n in sizes:
        t, v = T.subset(np.arange(min(n, len(T)))), V.subset(np.arange(min(n, len(V))))
        for label, settings in settings_list:
            first_s, median_s, peak, best = timed_search(t, v, settings)
            exact = "-"
            if n == sizes[0]:
                it = np.repeat(np.arange(len(t)), len(v))
                iv = np.tile(np.arange(len(v)), len(t))
                brute = evaluate_pairs(t, v, it, iv, model=cost_model(settings, [t, v])).cost.min()
                exact = ("yes" if abs(brute - best) <= 1e-9 * max(1.0, brute)
                         else f"NO ({brute:.6g} vs {best:.6g})")
            pairs = len(t) * len(v) / 1e6
            rows.append([len(t), len(v), f"{pairs:.1f}", label, f"{first_s:.3f}", f"{median_s:.3f}",
                         f"{pairs / median_s:.0f}", f"{peak:.0f}", exact])
            print("  ".join(str(x) for x in rows[-1]), file=sys.stderr)
    widths = [max(len(str(r[i])) for r in rows + [header]) for i in range(len(header))]
    print("  ".join(h.rjust(w) for h, w in zip(header, widths)))
    for r in rows:
        print("  ".join(str(x).rjust(w) for x, w in zip(r, widths)))


if __name__ == "__main__":
    main()
