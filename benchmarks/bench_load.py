"""Benchmark of loading and repairing a large mesh: time, peak memory, the stages shown.

    python benchmarks/bench_load.py                    # a 5.2-million-face sphere (250 MiB STL)
    python benchmarks/bench_load.py --against ../base  # the same in another checkout, side by side
    python benchmarks/bench_load.py --subdivisions 8   # 1.3 million faces

The mesh is trimesh's icosphere subdivided 9 times (5,242,880 faces), written once as a binary STL
(every triangle with its own corners, as scanners and CAD write them). Each load runs in a fresh
process, so that its peak resident memory (VmHWM) is its own: ``load_mesh`` reads, merges the
vertices, removes degenerate and duplicate faces and loose slivers, finds the bodies and turns
inverted ones right side out, as every object's analysis starts.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ONE = """
import json, sys, time
try:
    from pinchmatch.mesh.load import load_mesh
except ImportError:  # a checkout from before the pipeline's packages
    from pinchmatch.load import load_mesh
t0 = time.perf_counter()
stages = []
loaded = load_mesh(sys.argv[1],
                   progress=lambda s: stages.append((round(time.perf_counter() - t0, 2), s)))
seconds = time.perf_counter() - t0
hwm = next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM"))
print(json.dumps({"seconds": seconds, "peak_mib": hwm / 1024, "faces": len(loaded.mesh.faces),
                  "watertight": loaded.watertight, "stages": stages}))
"""


def load_in(checkout: str | None, path: Path) -> dict:
    import json

    env = dict(os.environ)
    if checkout is not None:
        env["PYTHONPATH"] = str(Path(checkout) / "src")
    out = subprocess.run([sys.executable, "-c", ONE, str(path)], env=env, capture_output=True,
                         text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subdivisions", type=int, default=9,
                        help="icosphere subdivisions (default 9: 5.2M faces)")
    parser.add_argument("--against", metavar="DIR",
                        help="also load in the checkout DIR, side by side")
    parser.add_argument("--mesh", metavar="FILE", help="load this file instead of the sphere")
    args = parser.parse_args()
    if args.mesh:
        path = Path(args.mesh)
    else:
        import trimesh

        path = Path(tempfile.gettempdir()) / f"pinchmatch-bench-ico{args.subdivisions}.stl"
        if not path.is_file():
            trimesh.creation.icosphere(subdivisions=args.subdivisions, radius=40.0).export(path)
    load_in(None, path)  # compiles the kernels once, on the first run ever
    rows = [("this tree", load_in(None, path))]
    if args.against:
        rows.append((args.against, load_in(args.against, path)))
    print(f"# {path.name}: {path.stat().st_size / 2**20:.0f} MiB; {os.cpu_count()} cores")
    print(f"{'checkout':>20} {'faces':>9} {'seconds':>8} {'peak_MiB':>9} {'watertight':>10}")
    for name, r in rows:
        print(f"{name:>20} {r['faces']:>9} {r['seconds']:>8.1f} {r['peak_mib']:>9.0f} "
              f"{str(r['watertight']):>10}")
    for name, r in rows:
        print(f"stages shown, {name}: " + "; ".join(f"{t:.1f} s {s}" for t, s in r["stages"]))
    if len(rows) == 2:
        print(f"ratio: {rows[1][1]['seconds'] / rows[0][1]['seconds']:.1f}x faster, peak memory "
              f"{rows[1][1]['peak_mib'] / rows[0][1]['peak_mib']:.1f}x lower")


if __name__ == "__main__":
    main()
