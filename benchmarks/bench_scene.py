"""One prop for a whole level: real objects on a table around one prop, matched with the hand
redirected.

    python benchmarks/bench_scene.py            # 9 real objects, 1,000 poses each
    python benchmarks/bench_scene.py --quick    # 300 poses

The level: robosuite's seven household objects and pybullet_data's duck and Lego brick (nobody here
made them; read from the wheels on PyPI, ``benchmarks/assets.py``), stood up on a table (glTF,
metres, y up) on a spiral around one prop, from 45 mm to 400 mm from its axis. The prop: a can 54 mm
across and 66 mm tall, known by its sizes (a manifest ``shape``), standing at the level's origin
(``pose``).

Both placements run side by side, as ``pinchmatch match`` runs from the command line: ``--placement
fixed`` (the objects stay; the hand is redirected, or the carousel serves) and ``--placement
registered``. Per object it prints the distance from the prop, the mode, the redirection angle as
reported and as recomputed here from the reported targets and hand start, the reach gain, the
redirected and the carousel's cost, the fixed and the registered cost, how far the chosen tangible
pinch moved between the two (mm, the larger contact displacement) and the rest gap of each object
shown on the prop (mm over the prop's table; - sunk into it); then how many sink or hover, then the
redirects that cost more than their carousel plus the margin (none, by the rule), the gains, the
split, the largest disagreement of the angles and the wall times side by side. Last, a level of 100
objects (the real ones again and again on a grid): the size of its page and the time Chromium takes
to open it and show its first entry.
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).parent))
from assets import DEFAULT_ASSETS  # noqa: E402
from bench_converge import timed_match  # noqa: E402
from bench_reach import real_meshes  # noqa: E402

#: the objects of the level and their distances from the prop's axis (mm), on a spiral
LEVEL = ("robosuite", "pybullet duck", "pybullet lego")
DISTANCES_MM = (45.0, 60.0, 75.0, 95.0, 120.0, 160.0, 220.0, 300.0, 400.0)
PROP = ('[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, height_mm = '
        '66 }\n'
        'pose = { position_mm = [0, 0, 0], quaternion_xyzw = [-0.7071068, 0, 0, 0.7071068] }\n')


def build_level(folder: Path) -> list[tuple[str, float]]:
    """kitchen.glb in ``folder``: each real object turned from its file's +Z up to +Y, standing on
    the table at its distance; returns (node name, distance mm)."""
    meshes = [(name, path) for name, path in real_meshes(DEFAULT_ASSETS, folder)
              if name.startswith(LEVEL)]
    scene, placed = trimesh.Scene(), []
    for k, ((name, path), distance) in enumerate(zip(meshes, DISTANCES_MM)):
        mesh = trimesh.load(path, force="mesh")
        # z up -> y up
        mesh.apply_transform(trimesh.transformations.rotation_matrix(-math.pi / 2, [1, 0, 0]))
        mesh.apply_scale(0.001)  # the level in metres
        centre = mesh.bounds.mean(axis=0)
        # on the table, centred
        mesh.apply_translation([-centre[0], -mesh.bounds[0, 1], -centre[2]])
        angle = 2.4 * k  # the spiral: each object a little further round
        T = np.eye(4)
        T[:3, 3] = [distance / 1000 * math.cos(angle), 0.0, distance / 1000 * math.sin(angle)]
        node = name.replace(" ", "_")
        scene.add_geometry(mesh, node_name=node, geom_name=f"{node}_mesh", transform=T)
        placed.append((node, distance))
    scene.export(folder / "kitchen.glb")
    (folder / "props.toml").write_text(PROP)
    return placed


#: the page's measure: this many objects in a level (the real ones, again and again, on a grid)
PAGE_OBJECTS = 100


def build_big_level(folder: Path, n: int = PAGE_OBJECTS) -> None:
    """kitchen.glb in ``folder``: ``n`` nodes, the real objects in turn on a grid 250 mm apart (the
    prop at the origin), each standing on the table."""
    meshes = [(name, path) for name, path in real_meshes(DEFAULT_ASSETS, folder)
              if name.startswith(LEVEL)]
    loaded = []
    for name, path in meshes:
        mesh = trimesh.load(path, force="mesh")
        mesh.apply_transform(trimesh.transformations.rotation_matrix(-math.pi / 2, [1, 0, 0]))
        mesh.apply_scale(0.001)
        centre = mesh.bounds.mean(axis=0)
        mesh.apply_translation([-centre[0], -mesh.bounds[0, 1], -centre[2]])
        loaded.append((name.replace(" ", "_"), mesh))
    scene, side = trimesh.Scene(), math.ceil(math.sqrt(n + 1))
    cells = [(i, j) for i in range(side) for j in range(side)
             if (i, j) != (side // 2, side // 2)][:n]
    for k, (i, j) in enumerate(cells):
        name, mesh = loaded[k % len(loaded)]
        T = np.eye(4)
        T[:3, 3] = [0.25 * (i - side // 2), 0.0, 0.25 * (j - side // 2)]
        scene.add_geometry(mesh, node_name=f"{name}_{k:03d}", geom_name=f"{name}_{k:03d}_mesh",
                           transform=T)
    scene.export(folder / "kitchen.glb")
    (folder / "props.toml").write_text(PROP)


def page_load(index: Path) -> tuple[float, float]:
    """(MB, s): the page's size, and the time from opening it in Chromium (playwright) until its
    first entry is shown; (size, nan) without playwright or Chromium."""
    size = index.stat().st_size / 1e6
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        return size, float("nan")
    chromium = Path("/usr/bin/chromium")
    if not chromium.exists():
        return size, float("nan")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(chromium),
                                    args=["--no-sandbox", "--use-gl=swiftshader"])
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        t0 = time.perf_counter()
        page.goto(index.as_uri())
        page.wait_for_selector("body[data-shown='0']", timeout=120_000)
        seconds = time.perf_counter() - t0
        browser.close()
    return size, seconds


def run(folder: Path, placement: str, count: int) -> tuple[dict, float]:
    return timed_match(["--tangible", str(folder / "props.toml"), "--virtual",
                        str(folder / "kitchen.glb"), "--split", "nodes", "--placement", placement,
                        "--count", str(count)],
                       folder / f"out_{placement}")


def angle_deg(start, a, b) -> float:
    u, v = np.subtract(a, start), np.subtract(b, start)
    return math.degrees(math.atan2(np.linalg.norm(np.cross(u, v)), float(u @ v)))


def pinch_moved_mm(a: dict, b: dict) -> float:
    p = np.array([a["tangible_pose"]["p1_mm"], a["tangible_pose"]["p2_mm"]])
    q = np.array([b["tangible_pose"]["p1_mm"], b["tangible_pose"]["p2_mm"]])
    return float(min(np.linalg.norm(p - q, axis=1).max(),
                     np.linalg.norm(p - q[::-1], axis=1).max()))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="300 poses per object instead of 1,000")
    args = parser.parse_args(argv)
    count = 300 if args.quick else 1000
    with tempfile.TemporaryDirectory(prefix="pinchmatch-bench-scene-") as tmp:
        folder = Path(tmp)
        placed = build_level(folder)
        fixed, t_fixed = run(folder, "fixed", count)
        registered, t_registered = run(folder, "registered", count)
        big = folder / "big"
        big.mkdir()
        build_big_level(big)
        argv = [sys.executable, "-m", "pinchmatch", "match", "--tangible", str(big / "props.toml"),
                "--virtual", str(big / "kitchen.glb"), "--split", "nodes", "--placement", "fixed",
                "--count", "200", "--no-cache", "--no-figures", "-q", "-o", str(big / "out")]
        subprocess.run(argv, check=False, capture_output=True)
        page_mb, page_s = page_load(big / "out" / "index.html")
    head = ("object", "from prop mm", "mode", "angle deg", "recomputed", "gain", "redirect cost",
            "carousel cost", "fixed cost", "registered cost", "pinch moved mm",
            "rest gap mm fixed/registered")
    rows, worst = [head], 0.0
    for node, distance in placed:
        m, r = fixed[node], registered[node]
        red = m["redirection"]
        again = angle_deg(red["hand_start_mm"], red["physical_target_mm"], red["virtual_target_mm"])
        worst = max(worst, abs(again - red["angle_deg"]))
        def cost(value):
            return "-" if value is None else f"{value:.3g}"

        rows.append((node, f"{distance:.0f}", red["mode"], f"{red['angle_deg']:.2f}",
                     f"{again:.2f}", f"{red['gain']:.3f}", cost(red.get("redirect_cost")),
                     cost(red.get("carousel_cost")), f"{m['cost']:.3g}", f"{r['cost']:.3g}",
                     f"{pinch_moved_mm(m, r):.1f}",
                     "/".join("-" if x.get("rest_gap_mm") is None else f"{x['rest_gap_mm']:+.1f}"
                              for x in (m, r))))
    widths = [max(len(str(row[i])) for row in rows) for i in range(len(head))]
    print(f"# {len(placed)} real objects around one prop, {count} poses each")
    for row in rows:
        print("  ".join(str(c).rjust(w) for c, w in zip(row, widths)))
    modes = [fixed[node]["redirection"]["mode"] for node, _ in placed]
    beyond = sum(fixed[node]["redirection"].get("redirect_cost") is None for node, _ in placed)
    over = [node for node, _ in placed if fixed[node]["redirection"]["mode"] == "redirect"
            and fixed[node]["redirection"]["redirect_cost"]
            > fixed[node]["redirection"]["carousel_cost"] + 0.5]
    gains = [fixed[node]["redirection"]["gain"] for node, _ in placed
             if fixed[node]["redirection"]["mode"] == "redirect"]
    print(f"\nredirects costing more than their carousel plus the margin: {len(over)}; redirect "
          "gains "
          + (f"{min(gains):.3f} to {max(gains):.3f}" if gains else "none")
          + f"; carousel beyond the budget {beyond}")
    print(f"redirect {modes.count('redirect')}, carousel {modes.count('carousel')}; largest "
          "difference between "
          f"reported and recomputed angle {worst:.4f} deg; wall time fixed {t_fixed:.1f} s, "
          "registered "
          f"{t_registered:.1f} s ({t_fixed / t_registered:.2f}x)")
    for name, doc in (("fixed (the carousel)", fixed), ("registered", registered)):
        gaps = np.array([doc[node]["rest_gap_mm"] for node, _ in placed
                         if doc[node].get("rest_gap_mm") is not None])
        print(f"{name}: {len(gaps)} objects shown on the prop; sunk more than 2 mm into its table "
              f"{int((gaps < -2.0).sum())}, more than 10 mm above it {int((gaps > 10.0).sum())}, "
              "not within 2 mm "
              f"{int((np.abs(gaps) > 2.0).sum())} (rest_gap_mm as reported; bench_level.py "
              "re-measures it)")
    print(f"the page of a level of {PAGE_OBJECTS} objects (200 poses each): {page_mb:.1f} MB, "
          "first entry shown "
          f"{page_s:.2f} s after opening it (Chromium, headless)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
