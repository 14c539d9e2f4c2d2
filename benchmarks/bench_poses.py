"""Benchmark of `pinchmatch poses`: speed on ~100k-face meshes and curvature accuracy.

    python benchmarks/bench_poses.py            # full run (a few minutes on 2 cores)
    python benchmarks/bench_poses.py --quick    # smaller meshes, fewer points
    python benchmarks/bench_poses.py --only speed --against ../base   # beside another checkout
    python benchmarks/bench_poses.py --only growth   # 2,000 to 10,000 pinches on one object

``--against DIR`` times the speed part in this tree and in the checkout DIR (for
example ``git worktree add ../base <commit>``) in alternating subprocesses, best
of ``--rounds`` warm runs each, and prints the ratio: the machine's speed drifts
by tens of percent within minutes, so only figures taken side by side compare.

Speed: wall time of the surface context (dense sample, KD-tree, ray engine)
and of sampling 2,000 feasible pinches with all features, after loading (one
cold run per mesh, after the compiled kernels are loaded). What bounds it: the
KD-tree queries of the reach search (most on the torus, whose pinches across
the hole need the hand leaned), the compiled patch fits, the ray casts.

Growth: poses with features for 2,000, 5,000 and 10,000 pinches on one 100k-face ellipsoid (the
same seed), the ratio to 2,000, and the share of the farthest-point spread and of the patch fits.

Accuracy: kappa_max, kappa_min, direction and normal errors against
closed-form truth at the same mesh vertices, for pinchmatch and, when the
``bench`` extra is installed (``pip install -e .[bench]``), libigl's
``principal_curvature`` (quadric fit on a 5-ring) and pymeshlab's
scale-dependent quadric fit at the 8 mm scale, with points per second.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import platform
import sys
import time

import numpy as np

from pinchmatch import PinchSettings, object_properties, pinch_features, sample_pinches
try:
    from pinchmatch.mesh import shapes
    from pinchmatch.grasp.curvature import patch_geometry
    from pinchmatch.mesh.surface import SurfaceContext
except ImportError:  # --against a checkout from before the pipeline's packages
    from pinchmatch import shapes
    from pinchmatch.curvature import patch_geometry
    from pinchmatch.surface import SurfaceContext

UP = np.array([0.0, 0.0, 1.0])


class _Timed:
    """Wall time spent inside a function, accumulated (the reach rule's share of a run)."""

    def __init__(self, module, name):
        self.module, self.name, self.seconds = module, name, 0.0
        self.inner = getattr(module, name)

    def __enter__(self):
        def timed(*args, **kwargs):
            t = time.perf_counter()
            try:
                return self.inner(*args, **kwargs)
            finally:
                self.seconds += time.perf_counter() - t

        setattr(self.module, self.name, timed)
        return self

    def __exit__(self, *exc):
        setattr(self.module, self.name, self.inner)


SPEED_SHAPES = {
    "sphere_random": lambda faces: shapes.sphere(30.0, triangulation="random", faces=faces),
    "torus_regular": lambda faces: shapes.torus(triangulation="regular", faces=faces),
    "ellipsoid_random": lambda faces: shapes.ellipsoid(triangulation="random", faces=faces),
    "cylinder_random": lambda faces: shapes.cylinder(triangulation="random", faces=faces),
}


def time_warm(name: str, faces: int, count: int, rounds: int) -> float:
    """Best of ``rounds`` warm runs of poses with features on one speed mesh (seconds)."""
    mesh = SPEED_SHAPES[name](faces).mesh
    ctx = SurfaceContext(mesh)
    props = object_properties(mesh, up=UP, watertight=True)
    best = np.inf
    for _ in range(rounds + 1):  # the first run loads compiled kernels
        t = time.perf_counter()
        pinch_features(sample_pinches(ctx, settings=PinchSettings(count=count, seed=0)), props)
        best = min(best, time.perf_counter() - t)
    return best


def side_by_side(other: str, faces: int, count: int, rounds: int) -> list[list]:
    """This tree against the checkout ``other``, alternating subprocesses per mesh."""
    import subprocess

    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    rows = []
    for name in SPEED_SHAPES:
        best = {}
        for _ in range(rounds):
            for label, tree in (("before", other), ("after", here)):
                env = dict(os.environ, PYTHONPATH=os.path.join(os.path.abspath(tree), "src"))
                out = subprocess.run([sys.executable, os.path.abspath(__file__), "--time-one", name,
                                      "--faces", str(faces), "--count", str(count)],
                                     env=env, capture_output=True, text=True, check=True).stdout
                best[label] = min(best.get(label, np.inf), float(out.split()[-1]))
        rows.append([name, f"{best['before']:.3f}", f"{best['after']:.3f}",
                     f"{best['before'] / best['after']:.2f}"])
    return rows


def speed(faces: int, count: int) -> list[list]:
    from pinchmatch.grasp import pinches as pinches_module

    rows = []
    # the compiled kernels load once per process (compiled and cached on disk on the first run ever)
    t = time.perf_counter()
    small = shapes.sphere(30.0, faces=2000).mesh
    sample_pinches(SurfaceContext(small), settings=PinchSettings(count=20, seed=0))
    print(f"kernels loaded, once per process: {time.perf_counter() - t:.2f} s")
    meshes = [make(faces) for make in SPEED_SHAPES.values()]
    for shape in meshes:
        mesh = shape.mesh
        t0 = time.perf_counter()
        ctx = SurfaceContext(mesh)
        ctx.tree, ctx.rays  # built on first use: timed here as the context
        t1 = time.perf_counter()
        props = object_properties(mesh, up=UP, watertight=True)
        with _Timed(pinches_module, "reach") as reach:  # every reach search, pre-check and final
            pinches = sample_pinches(ctx, settings=PinchSettings(count=count, seed=0))
        features = pinch_features(pinches, props)
        t2 = time.perf_counter()
        assert len(features.width_mm) == len(pinches)
        rows.append([shape.name, len(mesh.faces), ctx.ray_engine_name, f"{t1 - t0:.3f}",
                     len(pinches), f"{t2 - t1:.3f}", f"{len(pinches) / (t2 - t1):.0f}",
                     f"{reach.seconds / (t2 - t1):.0%}"])
    # the numpy fallback when embreex is missing, on a smaller mesh
    from trimesh.ray.ray_triangle import RayMeshIntersector

    shape = shapes.ellipsoid(triangulation="regular", faces=5000)
    ctx = SurfaceContext(shape.mesh)
    ctx.rays = RayMeshIntersector(shape.mesh)  # in place of the cached embree engine
    t1 = time.perf_counter()
    pinches = sample_pinches(ctx, settings=PinchSettings(count=200, seed=0))
    t2 = time.perf_counter()
    rows.append([shape.name, len(shape.mesh.faces), "numpy", "-", len(pinches), f"{t2 - t1:.3f}",
                 f"{len(pinches) / (t2 - t1):.0f}", "-"])
    return rows


def growth(faces: int, counts=(2000, 5000, 10000)) -> list[list]:
    from pinchmatch.grasp import pinches as pinches_module, spread

    sample_pinches(SurfaceContext(shapes.sphere(30.0, faces=2000).mesh),
                   settings=PinchSettings(count=20, seed=0))
    mesh = SPEED_SHAPES["ellipsoid_random"](faces).mesh
    props = object_properties(mesh, up=UP, watertight=True)
    rows, base = [], None
    for count in counts:
        ctx = SurfaceContext(mesh)
        ctx.tree, ctx.rays
        with _Timed(spread, "spread_order") as spreading, _Timed(
            pinches_module, "patch_geometry") as fits:
            t = time.perf_counter()
            pinches = sample_pinches(ctx, settings=PinchSettings(count=count, seed=0))
            pinch_features(pinches, props)
            seconds = time.perf_counter() - t
        base = base or seconds
        rows.append([count, len(pinches), f"{seconds:.3f}", f"{seconds / base:.2f}",
                     f"{count / counts[0]:.1f}", f"{spreading.seconds / seconds:.0%}",
                     f"{fits.seconds / seconds:.0%}"])
    return rows


def _errors(k_max, k_min, truth, d_max=None, normal=None):
    k_err = np.abs(k_max - truth.kappa_max_per_m) / np.abs(truth.kappa_max_per_m) * 100
    out = {
        "kmax_med_pct": np.median(k_err),
        "kmax_p95_pct": np.percentile(k_err, 95),
        "kmin_med_per_m": np.median(np.abs(k_min - truth.kappa_min_per_m)),
        "dir_med_deg": np.nan,
        "normal_med_deg": np.nan,
    }
    if d_max is not None and not np.isnan(truth.dir_max).all():
        c = np.abs(np.einsum("ij,ij->i", d_max / np.linalg.norm(d_max, axis=1, keepdims=True),
                             truth.dir_max))
        out["dir_med_deg"] = np.nanmedian(np.degrees(np.arccos(np.clip(c, 0, 1))))
    if normal is not None:
        c = np.einsum("ij,ij->i", normal, truth.normal)
        out["normal_med_deg"] = np.median(np.degrees(np.arccos(np.clip(c, -1, 1))))
    return out


def accuracy(sizes, n_points: int, noise_mm: float, report=lambda row: None) -> list[dict]:
    try:
        import igl
    except ImportError:
        igl = None
    try:
        import pymeshlab
    except ImportError:
        pymeshlab = None

    rng = np.random.default_rng(0)
    results = []
    for make in (shapes.sphere, shapes.cylinder, shapes.torus, shapes.ellipsoid):
        for tri in ("regular", "cad", "random"):
            for faces in sizes:
                for noise in (0.0, noise_mm):
                    shape = make(triangulation=tri, faces=faces)
                    mesh = shape.mesh.copy()
                    if noise:
                        if tri == "cad":
                            continue  # noise on long slivers is not a scan
                        mesh.vertices = mesh.vertices + rng.normal(
                            scale=noise, size=mesh.vertices.shape)
                    clean_v = shape.mesh.vertices
                    interior = np.flatnonzero(shape.interior(clean_v, 8.0))
                    if len(interior) == 0:
                        continue
                    pick = rng.choice(interior, size=min(n_points, len(interior)), replace=False)
                    truth = shape.truth(clean_v[pick])
                    label = f"{shape.name} {len(mesh.faces)}" + (
                        f" noise {noise:g}" if noise else "")

                    ctx = SurfaceContext(mesh)
                    t = time.perf_counter()
                    geom = patch_geometry(ctx, mesh.vertices[pick], mesh.vertex_normals[pick])
                    dt = time.perf_counter() - t
                    row = _errors(geom.kappa_max_per_m, geom.kappa_min_per_m, truth, geom.dir_max,
                                  geom.normal)
                    results.append({"mesh": label, "method": "pinchmatch",
                                    "pts_per_s": len(pick) / dt, **row})
                    report(results[-1])

                    if igl is not None:
                        t = time.perf_counter()
                        pd1, pd2, pv1, pv2 = igl.principal_curvature(
                            mesh.vertices.astype(np.float64), mesh.faces.astype(np.int64))[:4]
                        dt = time.perf_counter() - t
                        pv1, pv2, pd1 = (np.asarray(pv1) * 1000, np.asarray(pv2) * 1000,
                                         np.asarray(pd1))
                        row = _errors(pv1[pick], pv2[pick], truth, pd1[pick])
                        results.append({"mesh": label, "method": "libigl",
                                        "pts_per_s": len(mesh.vertices) / dt, **row})
                        report(results[-1])

                    if pymeshlab is not None:
                        ms = pymeshlab.MeshSet()
                        ms.add_mesh(pymeshlab.Mesh(mesh.vertices, mesh.faces))
                        t = time.perf_counter()
                        values = []
                        for which in ("Max Curvature", "Min Curvature"):
                            with quiet_stdout():
                                ms.compute_curvature_principal_directions_per_vertex(
                                    method="Scale Dependent Quadric Fitting", curvcolormethod=which,
                                    scale=pymeshlab.PureValue(8.0), autoclean=False)
                            values.append(ms.current_mesh().vertex_scalar_array() * 1000)
                        dt = time.perf_counter() - t
                        kmax, kmin = np.maximum(*values), np.minimum(*values)
                        row = _errors(kmax[pick], kmin[pick], truth)
                        results.append({"mesh": label, "method": "pymeshlab",
                                        "pts_per_s": len(mesh.vertices) / dt, **row})
                        report(results[-1])
    return results


@contextlib.contextmanager
def quiet_stdout():
    """Silence output written by C++ code straight to file descriptor 1 (pymeshlab)."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "w") as devnull:
        os.dup2(devnull.fileno(), 1)
        try:
            yield
        finally:
            os.dup2(saved, 1)
            os.close(saved)


def table(header, rows) -> str:
    widths = [max(len(str(x)) for x in col) for col in zip(header, *rows)]
    fmt = "  ".join(f"{{:>{w}}}" for w in widths)
    return "\n".join([fmt.format(*header), fmt.format(*["-" * w for w in widths])]
                     + [fmt.format(*r) for r in rows])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller meshes and fewer points")
    parser.add_argument("--only", choices=("speed", "accuracy", "growth"), help="run one part only")
    parser.add_argument("--against", metavar="DIR",
                        help="also time the speed part in the checkout DIR, side by side")
    parser.add_argument("--rounds", type=int, default=3,
                        help="alternating rounds of --against (default 3)")
    parser.add_argument("--time-one", metavar="MESH", help=argparse.SUPPRESS)
    parser.add_argument("--faces", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--count", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.time_one:  # a subprocess of --against
        print(time_warm(args.time_one, args.faces, args.count, rounds=2))
        return
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, python "
          f"{platform.python_version()}")

    faces = 20_000 if args.quick else 100_000
    count = 500 if args.quick else 2000
    if args.only == "growth":
        print(f"\n## Growth with the count: poses with features on one ellipsoid of {faces} faces, "
              "after loading\n")
        print(table(["asked", "found", "seconds", "time_ratio", "count_ratio", "spread_share",
                     "fits_share"],
                    growth(faces)))
        print("\ntarget: 10,000 pinches in at most 6x the time of 2,000")
        return
    if args.only != "accuracy":
        print(f"\n## Speed: {count} feasible poses with all features, after loading (target <= 1.5 "
              "s at 100k faces)\n")
        print(table(["mesh", "faces", "rays", "context_s", "poses", "poses+features_s",
                     "poses_per_s", "reach_share"],
                    speed(faces, count)))
        if args.against:
            print(f"\n## Side by side with {args.against}: best of {args.rounds} alternating "
                  "subprocesses, "
                  "each the best of 2 warm runs (s)\n")
            print(table(["mesh", "before_s", "after_s", "ratio"],
                        side_by_side(args.against, faces, count, args.rounds)))
    if args.only == "speed":
        return

    sizes = (2_000, 20_000) if args.quick else (2_000, 100_000)
    n_points = 100 if args.quick else 300
    print(f"\n## Curvature accuracy at {n_points} interior vertices per mesh (truth: closed "
          "form)\n")
    header = ["mesh", "method", "kmax_med_%", "kmax_p95_%", "kmin_med_per_m", "dir_med_deg",
              "normal_med_deg", "pts_per_s"]
    widths = [34, 10, 10, 10, 14, 11, 14, 9]
    line = "  ".join(f"{{:>{w}}}" for w in widths)
    print(line.format(*header))
    print(line.format(*["-" * w for w in widths]))

    def report(r):
        print(line.format(r["mesh"], r["method"], f"{r['kmax_med_pct']:.2f}",
                          f"{r['kmax_p95_pct']:.2f}", f"{r['kmin_med_per_m']:.2f}",
                          f"{r['dir_med_deg']:.2f}", f"{r['normal_med_deg']:.3f}",
                          f"{r['pts_per_s']:.0f}"), flush=True)

    accuracy(sizes, n_points, noise_mm=0.05, report=report)
    print("\ntargets (clean, 2k-100k faces): kmax median <= 1.5 %, p95 <= 5 %, kmin median <= 1 "
          "/m, "
          "direction <= 1 deg, normal <= 0.5 deg; with 0.05 mm noise kmax median <= 3 %")


if __name__ == "__main__":
    main()
