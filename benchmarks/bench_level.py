"""A kitchen level on a counter and one real prop standing on its own table: does any hand go under
them?

    python benchmarks/bench_level.py            # 9 real objects, 1,000 poses each
    python benchmarks/bench_level.py --quick    # 300 poses
    python benchmarks/bench_level.py --grasp tripod   # every run with tripods

The level: robosuite's household objects and pybullet_data's duck, teddy and Lego brick (nobody here
made them; read from the wheels on PyPI, ``benchmarks/assets.py``), stood up (their files' +Z to the
level's +Y, metres) on a counter whose top is at y = 900 mm, 80 mm apart around the prop's spot. The
prop: robosuite's scanned can (an STL in mm, +Z up), with a ``pose`` where the level's own can
stands.

Six runs, as ``pinchmatch match`` runs from the command line: ``--placement fixed`` and
``registered``, each with the defaults (``--support auto``: the prop stands on its table, each node
on the counter; ``--rank expected``: ranked by the cost over where guided fingers land), with
``--rank nominal`` (ranked on target, the same table) and with ``--support none --rank nominal``
(what every run did before: the objects held in the air, ranked on target). Per run it prints the
mean nominal and expected cost of the answers, the share of objects whose expected cost is at most
twice the nominal plus 0.3 JND, and the wall time; then, per placement, the default's mean expected
cost against ``--rank nominal``'s and the time ratio. For every best choice and
every alternative it checks, with planes worked out here from the prop's pose and the level's
vertices (not read from the output): each fingertip sphere and finger capsule above the prop's table
and, under ``fixed``, above the counter the virtual object stands on (within the pad's 0.3 mm), and
no finger's axis (the approach leaned by the splay) from below. It prints, per run, the pinches
checked, those that reach under a table (tangible, virtual), the mean cost and the wall time; and of
the objects shown on the prop (registered, or brought by the carousel), how many sink more than 2 mm
into the prop's table or hover more than 10 mm over it, re-measured from the reported transform and
the node's own vertices, the worst gap, the approaches from the user's far half lower than 35
degrees (the default user, worked out here from the prop's pose), and the mean expected cost less
what the gaps add (``expected felt``: what the hand feels alone). Last, per placement, the default
run over ``--seeds`` (0, 1, 2): how much each object's ranked cost varies with the seed, (max - min)
/ mean, its median and largest over the objects.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).parent))
from assets import DEFAULT_ASSETS  # noqa: E402
from bench_converge import timed_match  # noqa: E402
from bench_reach import real_meshes  # noqa: E402

COUNTER_Y_MM = 900.0
SPACING_MM = 80.0
#: the prop stands where the level's can stands
PROP_SPOT_MM = (0.0, COUNTER_Y_MM, 0.0)
OBJECTS = ("robosuite", "pybullet duck", "pybullet teddy", "pybullet lego")
#: the hand model's defaults (mm) and the pad's tolerance
FINGERTIP_MM, FINGER_MM, LENGTH_MM, PAD_MM = 8.0, 8.0, 45.0, 0.3
Z_UP_TO_Y_UP = Rotation.from_euler("x", -90, degrees=True)


def build_level(folder: Path) -> tuple[dict, np.ndarray, dict, np.ndarray]:
    """kitchen.glb and props.toml in ``folder``; returns {node: its lowest y in mm}, the prop's
    vertices (mm), {node: its vertices in the level, mm} and the prop's pose position (mm, the
    level's frame)."""
    meshes = [(name, path) for name, path in real_meshes(DEFAULT_ASSETS, folder)
              if name.startswith(OBJECTS)]
    scene, lowest, shapes = trimesh.Scene(), {}, {}
    spots = [(0.0, 0.0)] + [(SPACING_MM * math.cos(a), SPACING_MM * math.sin(a) * 1.5)
                            for a in np.linspace(0, 2 * math.pi, len(meshes), endpoint=False)[1:]]
    can = next(path for name, path in meshes if name == "robosuite can")
    # the level's can at the prop's spot
    order = sorted(meshes, key=lambda m: m[0] != "robosuite can")
    for (name, path), (x, z) in zip(order, spots):
        mesh = trimesh.load(path, force="mesh")
        # z up -> y up
        mesh.apply_transform(trimesh.transformations.rotation_matrix(-math.pi / 2, [1, 0, 0]))
        centre = mesh.bounds.mean(axis=0)
        mesh.apply_translation([x - centre[0], COUNTER_Y_MM - mesh.bounds[0, 1], z - centre[2]])
        node = name.replace(" ", "_")
        lowest[node] = float(mesh.bounds[0, 1])
        shapes[node] = np.array(mesh.vertices)
        mesh.apply_scale(0.001)  # the level in metres
        scene.add_geometry(mesh, node_name=node, geom_name=f"{node}_mesh")
    scene.export(folder / "kitchen.glb")
    prop = trimesh.load(can, force="mesh")
    # the prop's file is in mm, +Z up, its origin wherever the scan put it: posed so that it stands
    # on the counter where the level's can stands
    R = Z_UP_TO_Y_UP.as_matrix()
    standing = prop.vertices @ R.T
    centre = standing.mean(axis=0)
    position = np.array(PROP_SPOT_MM) - [centre[0], standing[:, 1].min(), centre[2]]
    (folder / "props.toml").write_text(
        f'[[object]]\nfile = "{can.name}"\nname = "can_prop"\nunits = "mm"\nup = "z"\n'
        f"pose = {{ position_mm = {position.round(4).tolist()}, quaternion_xyzw = "
        f"{Z_UP_TO_Y_UP.as_quat().tolist()} }}\n")
    return lowest, np.asarray(prop.vertices), shapes, position


#: the fingers' splay (the default of --finger-splay-deg): each leans this far from the approach
SPLAY_DEG = 15.0


def under_table(pose: dict, normal: np.ndarray, height: float) -> bool:
    """Does the grasp (a pinch, or a tripod's three contacts) put a fingertip, a finger or the hand
    below the plane normal . x = height?"""
    p = np.array(pose["contacts_mm"] if "contacts_mm" in pose else [pose["p1_mm"], pose["p2_mm"]])
    n = np.array(pose["normals"] if "normals" in pose else [pose["n1"], pose["n2"]])
    h = np.array(pose["approach"], dtype=float)
    tips = p + FINGERTIP_MM * n
    if (tips @ normal - height < FINGERTIP_MM - PAD_MM - 1e-6).any():
        return True
    if not np.isfinite(h).all():
        return False  # a given pose: no approach to check
    # each finger: the approach turned by the splay about h x u, the thumb away from the others, the
    # others towards
    u = p[1:].mean(axis=0) - p[0]
    k = np.cross(h, u / np.linalg.norm(u))
    k /= np.linalg.norm(k)
    axes = np.array([Rotation.from_rotvec(k * math.radians(SPLAY_DEG * (
        -1.0 if i == 0 else 1.0))).apply(h)
                     for i in range(len(p))])
    ends = tips + LENGTH_MM * axes
    return bool((ends @ normal - height < FINGER_MM - PAD_MM - 1e-6).any()
                or (axes @ normal < -1e-9).any())


#: a shown object reads as resting within this many mm below its prop's table; hovering is counted
#: beyond FLOAT_MM
SINK_MM, FLOAT_MM = 2.0, 10.0


def rest_gaps(doc: dict, prop_vertices: np.ndarray, shapes: dict) -> list[float]:
    """The gap (mm, negative: sunk) between each object shown on the prop (registered, or brought by
    the carousel) and the prop's table, best choices only: the node's own vertices moved by the
    reported transform, against the plane through the prop's lowest point along the level's up
    (worked out here, not read from the output)."""
    prop_up = Z_UP_TO_Y_UP.inv().apply([0.0, 1.0, 0.0])
    prop_table = float((prop_vertices @ prop_up).min())
    gaps = []
    for m in doc["matches"]:
        if m.get("tangible") is None or (m.get("redirection") or {}).get("mode") == "redirect":
            continue
        T = np.array(m["transform_virtual_to_tangible"], dtype=float)
        placed = shapes[m["virtual"]] @ T[:3, :3].T + T[:3, 3]
        gaps.append(float((placed @ prop_up).min() - prop_table))
    return gaps


#: an approach from the user's far half must come from at least this high (deg)
FAR_ELEVATION_DEG = 35.0


def far_approaches(doc: dict, prop_vertices: np.ndarray, position: np.ndarray) -> tuple[int, int]:
    """(approaches checked, those from the user's far half under ``FAR_ELEVATION_DEG``), best
    choices and alternatives: each tangible approach turned into the level by the prop's pose,
    against the default user (where the hand starts: 150 mm above the prop's footprint and 300 mm
    toward +Z), worked out here."""
    R = Z_UP_TO_Y_UP.as_matrix()
    world = prop_vertices @ R.T + position
    low, high = world.min(axis=0), world.max(axis=0)
    user = np.array([(low[0] + high[0]) / 2.0, low[1] + 150.0, (low[2] + high[2]) / 2.0 + 300.0])
    checked = far = 0
    for m in doc["matches"]:
        if m.get("tangible") is None:
            continue
        for choice in [m] + m["alternatives"]:
            pose = choice["tangible_pose"]
            h = np.array(pose["approach"], dtype=float)
            if not np.isfinite(h).all():
                continue
            p = np.array(pose["contacts_mm"] if "contacts_mm" in pose
                         else [pose["p1_mm"], pose["p2_mm"]])
            h, mid = R @ h, p.mean(axis=0) @ R.T + position
            to_user, flat = (user - mid) * [1, 0, 1], h * [1, 0, 1]
            elevation = math.degrees(math.asin(np.clip(h[1], -1.0, 1.0)))
            checked += 1
            far += bool(flat @ to_user < 0 and elevation < FAR_ELEVATION_DEG)
    return checked, far


def rest_charge(gap: float | None) -> float:
    """What a rest gap adds to the cost (JND) under the default rates: 1 per mm sunk, 1 per 10 mm
    hovering, beyond 2 mm either way; 0 where nothing rests on a table."""
    if gap is None:
        return 0.0
    return max(-gap - SINK_MM, 0.0) / 1.0 + max(gap - SINK_MM, 0.0) / 10.0


def check(doc: dict, prop_vertices: np.ndarray, lowest: dict, fixed: bool) -> tuple[int, int, int]:
    """(pinches checked, tangible ones under the prop's table, virtual ones under the counter)."""
    prop_up = Z_UP_TO_Y_UP.inv().apply([0.0, 1.0, 0.0])  # the level's up in the prop's frame
    prop_table = float((prop_vertices @ prop_up).min())
    checked = tangible = virtual = 0
    for m in doc["matches"]:
        if m.get("tangible") is None:
            continue
        mode = (m.get("redirection") or {}).get("mode")
        for choice in [m] + m["alternatives"]:
            checked += 1
            tangible += under_table(choice["tangible_pose"], prop_up, prop_table)
            if fixed and mode == "redirect":  # the virtual pinch is made where the object stands
                virtual += under_table(choice["virtual_pose"], np.array([0.0, 1.0, 0.0]),
                                       lowest[m["virtual"]])
    return checked, tangible, virtual


def seed_spread(folder: Path, placement: str, count: int, seeds: list[int],
                grasp: str = "pinch") -> str:
    """One line: over ``seeds``, how much each object's ranked cost varies with the default options,
    (max - min) / mean per object (0 where every seed costs 0), its median and largest over the
    objects."""
    if len(seeds) < 2:
        return f"{placement}: one seed, no spread"
    costs: dict[str, list] = {}
    for seed in seeds:
        matches, _ = timed_match(["--tangible", str(folder / "props.toml"), "--virtual",
                                  str(folder / "kitchen.glb"), "--split", "nodes", "--placement",
                                  placement, "--count", str(count), "--seed", str(seed), "--grasp",
                                  grasp], folder / f"out_{placement}_seed{seed}")
        for name, m in matches.items():
            costs.setdefault(name, []).append(m["cost"] if m.get("cost") is not None else np.inf)
    spread = {name: (max(c) - min(c)) / np.mean(c) if np.mean(c) > 0 else 0.0
              for name, c in costs.items()}
    worst = max(spread, key=spread.get)
    return (f"{placement}: over seeds {','.join(map(str, seeds))} the ranked cost per object "
            "varies by a median of "
            f"{100 * float(np.median(list(spread.values()))):.1f} % (largest: {worst}, "
            f"{100 * spread[worst]:.1f} %)")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="300 poses per object instead of 1,000")
    parser.add_argument("--seeds", default="0,1,2",
                        help="the default run over these seeds: how much each object's ranked cost "
                             "varies")
    parser.add_argument("--grasp", choices=("pinch", "tripod"), default="pinch",
                        help="the grasp every run looks for (tripod: thumb against index and "
                             "middle finger)")
    args = parser.parse_args(argv)
    count = 300 if args.quick else 1000
    rows = [("placement", "support", "rank", "pinches", "under the prop's table",
             "under the counter", f"far side < {FAR_ELEVATION_DEG:g} deg", "shown",
             f"sunk > {SINK_MM:g}", f"float > {FLOAT_MM:g}", "worst gap", "nominal", "expected",
             "expected felt", "exp <= 2 nom + 0.3", "wall s")]
    summary = []
    with tempfile.TemporaryDirectory(prefix="pinchmatch-bench-level-") as tmp:
        folder = Path(tmp)
        lowest, prop_vertices, shapes, position = build_level(folder)
        for placement in ("fixed", "registered"):
            seen = {}
            for support, rank in (("auto", "expected"), ("auto", "nominal"), ("none", "nominal")):
                out = folder / f"out_{placement}_{support}_{rank}"
                matches, seconds = timed_match(
                    ["--tangible", str(folder / "props.toml"), "--virtual",
                     str(folder / "kitchen.glb"), "--split", "nodes", "--placement", placement,
                     "--support", support, "--rank", rank, "--count", str(count), "--grasp",
                     args.grasp],
                    out)
                doc = json.loads((out / "matches.json").read_text())
                checked, tangible, virtual = check(doc, prop_vertices, lowest, placement == "fixed")
                gaps = np.array(rest_gaps(doc, prop_vertices, shapes) or [np.nan])
                worst = gaps[np.nanargmax(np.abs(gaps))] if np.isfinite(gaps).any() else np.nan
                landed = [m["landing"] for m in matches.values() if m.get("landing")]
                nominal = np.array([x["cost_nominal"] for x in landed])
                expected = np.array([x["cost_mean"] for x in landed])
                # what the hand feels alone: the expected cost less what a gap beyond 2 mm adds (1
                # JND per mm sunk, per 10 mm hovering: the defaults)
                charged = np.array([rest_charge(m.get("rest_gap_mm")) for m in matches.values()
                                    if m.get("landing")])
                felt = expected - charged
                near = float(np.mean(expected <= 2.0 * nominal + 0.3))
                seen[(support, rank)] = (float(expected.mean()), seconds)
                rows.append((placement, support, rank, checked, tangible,
                             virtual if placement == "fixed" else "-",
                             far_approaches(doc, prop_vertices, position)[1],
                             int(np.isfinite(gaps).sum()), int((gaps < -SINK_MM).sum()),
                             int((gaps > FLOAT_MM).sum()), f"{worst:+.1f}", f"{nominal.mean():.3f}",
                             f"{expected.mean():.3f}", f"{felt.mean():.3f}", f"{near:.0%}",
                             f"{seconds:.1f}"))
            (e_default, t_default), (e_nominal,
                                     t_nominal) = seen[("auto", "expected")], seen[(
                                         "auto", "nominal")]
            summary.append(f"{placement}: mean expected cost {e_default:.3f} ranked by it, "
                           f"{e_nominal:.3f} ranked "
                           f"on target ({e_default / e_nominal:.2f}x); wall time "
                           f"{t_default / t_nominal:.2f}x")
        for placement in ("fixed", "registered"):
            summary.append(seed_spread(folder, placement, count,
                                       [int(x) for x in args.seeds.split(",") if x], args.grasp))
    widths = [max(len(str(row[i])) for row in rows) for i in range(len(rows[0]))]
    print(f"# {len(lowest)} real objects on a counter at y = {COUNTER_Y_MM:g} mm, one scanned can "
          "as the prop, "
          f"{count} poses each; pinches: best choices and alternatives checked against the tables")
    for row in rows:
        print("  ".join(str(c).rjust(w) for c, w in zip(row, widths)))
    print("\n".join(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
