"""Benchmark of `pinchmatch design` on real third-party meshes: one designed prop against a 15-prop
shelf.

    python benchmarks/bench_design.py                 # budget 120 s
    python benchmarks/bench_design.py --budget-s 300
    python benchmarks/bench_design.py --picture docs/images/designed_prop.png
    python benchmarks/bench_design.py --no-supports    # also a prop printable without supports

The scene and the shelf are `bench_select.py`'s: twenty objects (robosuite's seven household
objects, pybullet_data's duck, teddy and Lego brick, ten ``random_urdfs`` objects) and fifteen more
``random_urdfs`` objects as the shelf. Prints, on the scene: the designed single prop, the best
single shelf prop and the best two-prop subset of the shelf (exhaustive, from `pinchmatch select`):
mean cost, noticeable objects, wall time; whether the search kept to its budget, how many candidates
it judged and gave up early, and at which candidate it last improved. `design` is given the shelf
(``--tangible``): its search starts from stacks fitted to the shelf's best prop.
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
from assets import DEFAULT_ASSETS, random_objects
from bench_reach import real_meshes
from bench_select import SCENE_REAL


def _run(argv: list[str]) -> float:
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "pinchmatch", *argv, "-q"], capture_output=True,
                          text=True)
    if proc.returncode not in (0, 3):
        raise SystemExit(f"pinchmatch {argv[0]} failed ({proc.returncode}): {proc.stderr.strip()}")
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--budget-s", type=float, default=120.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--picture", metavar="PNG",
                        help="also draw the designed prop with the scene's pinches on it")
    parser.add_argument("--no-supports", action="store_true",
                        help="also design a prop printable without supports")
    args = parser.parse_args()
    root = Path(tempfile.mkdtemp(prefix="pinchmatch-bench-design-"))
    (root / "scene").mkdir(parents=True)
    scene = [p for name, p in real_meshes(DEFAULT_ASSETS, root / "scene")
             if name.startswith(SCENE_REAL)]
    scene += random_objects(root / "scene", range(10), faces=6000)
    shelf = random_objects(root / "shelf", range(950, 965), faces=6000)
    common = ["--virtual", *map(str, scene), "--cache", str(root / "cache")]
    rows = []
    select_s = _run(["select", "--tangible", *map(str, shelf), *common, "-k", "2", "--max-k", "2",
                     "-o", str(root / "select")])
    sel = json.loads((root / "select" / "selection.json").read_text())
    for c in sel["coverage"]:
        rows.append((f"best {c['k']} of the shelf", ", ".join(c["props"]), c["mean_cost"],
                     c["noticeable_count"], f"{select_s:.0f} (select, both K)"))
    design_s = _run(["design", *common, "--tangible", *map(str, shelf), "--budget-s",
                     str(args.budget_s), "--seed", str(args.seed), "-o", str(root / "design")])
    doc = json.loads((root / "design" / "design.json").read_text())
    prop = doc["props"][0]
    parts = " / ".join(f"{p['kind']} {p['width_mm']:g}" for p in prop["parts"])
    rows.append(("designed, 1 prop", parts, doc["mean_cost"], doc["noticeable_count"],
                 f"{design_s:.0f}"))
    if args.no_supports:
        flat_s = _run(["design", *common, "--budget-s", str(args.budget_s), "--seed",
                       str(args.seed), "--no-supports", "-o", str(root / "design-no-supports")])
        flat = json.loads((root / "design-no-supports" / "design.json").read_text())
        flat_parts = " / ".join(f"{p['kind']} {p['width_mm']:g}" for p in flat["props"][0]["parts"])
        rows.append(("designed, no supports",
                     f"{flat_parts} (overhang {flat['props'][0]['overhang_area_mm2']} mm2)",
                     flat["mean_cost"], flat["noticeable_count"], f"{flat_s:.0f}"))
    print(f"# a scene of {len(scene)} objects; a shelf of {len(shelf)} props; design --budget-s "
          f"{args.budget_s:g}")
    print(f"{'set':>22} {'mean_cost':>10} {'noticeable':>10} {'seconds':>18}  props")
    for name, props, mean, loud, secs in rows:
        print(f"{name:>22} {mean:>10} {loud:>10} {secs:>18}  {props}")
    search = doc["search"]
    last = search["history"][-1]["evaluations"] if search["history"] else 0
    within = search["seconds"] <= args.budget_s + search["first_evaluation_s"]
    print(f"design: {search['evaluations']} candidates judged in {search['seconds']} s (budget "
          f"{args.budget_s:g} s, {'within' if within else 'OVER'}), "
          f"{search['pruned']} given up early; the last improvement at candidate {last} of "
          f"{search['evaluations']}; "
          f"{design_s:.1f} s wall in all (the shelf's match and the final match included); against "
          "the shelf's "
          f"best: {doc['shelf_comparison']['designed_minus_shelf_mean_cost']:+.4f} mean cost; "
          "overhang "
          f"{prop['overhang_area_mm2']} mm2, height {prop['height_mm']} mm, widest "
          f"{prop['widest_mm']} mm")
    print(f"files: {root}")
    if args.picture:
        picture(root / "design", Path(args.picture))


def picture(design_folder: Path, png: Path) -> None:
    """The designed prop with each scene object's pinch on it (contacts joined by the pinch
    line)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    import trimesh
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    doc = json.loads((design_folder / "design.json").read_text())
    matches = json.loads((design_folder / "matches.json").read_text())["matches"]
    mesh = trimesh.load(design_folder / doc["props"][0]["file"], force="mesh")
    fig = plt.figure(figsize=(7, 7))
    ax = fig.add_subplot(projection="3d")
    shade = 0.35 + 0.5 * np.clip(mesh.face_normals @ np.array([0.4, -0.5, 0.75]), 0, 1)
    colours = np.c_[shade, shade, shade * 1.05, np.full_like(shade, 0.55)].clip(0, 1)
    ax.add_collection3d(Poly3DCollection(mesh.triangles, facecolors=colours, edgecolor="none"))
    colors = plt.cm.tab20(np.linspace(0, 1, max(len(matches), 1)))
    for m, c in zip(matches, colors):
        if m.get("tangible_pose") is None:
            continue
        p1, p2 = np.array(m["tangible_pose"]["p1_mm"]), np.array(m["tangible_pose"]["p2_mm"])
        ax.plot(*np.c_[p1, p2], color=c, lw=1.5)
        ax.scatter(*np.c_[p1, p2], color=c, s=25, depthshade=False,
                   label=f"{Path(m['virtual']).stem} ({m['cost']:.2g})")
    lo, hi = mesh.bounds
    span = (hi - lo).max() / 2
    mid = (hi + lo) / 2
    ax.set(xlim=(mid[0] - span, mid[0] + span), ylim=(mid[1] - span, mid[1] + span),
           zlim=(lo[2], lo[2] + 2 * span), xlabel="x (mm)", ylabel="y (mm)", zlabel="z (mm)")
    ax.legend(fontsize=6, loc="upper left", ncol=2, title="object (cost)", title_fontsize=7)
    ax.set_title(f"designed prop: mean cost {doc['mean_cost']}, {doc['noticeable_count']} "
                 "noticeable", fontsize=9)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


if __name__ == "__main__":
    main()

