"""Parallel and distributed runs, streamed output: the same bits whatever runs the work."""

import json

import numpy as np
import pytest

from pinchmatch.config import Config
from pinchmatch.mesh.manifest import ObjectSpec
from pinchmatch.runner.cache import cached_candidates
from pinchmatch.cli.main import main
from pinchmatch.match.scene import match_scene
from pinchmatch.match.search import MatchSettings
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.export.documents import matches_document, matches_from_lines, to_json
from pinchmatch.mesh.shapes import ellipsoid, stacked_prop

COUNT = 300


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    """Two tangibles and four virtual objects (one file per object), in mm."""
    root = tmp_path_factory.mktemp("objects")
    (root / "t").mkdir()
    (root / "v").mkdir()
    stacked_prop(sections=48).export(root / "t" / "prop.stl")
    ellipsoid((45.0, 30.0, 20.0), faces=2000).mesh.export(root / "t" / "egg.stl")
    for k, axes in enumerate([(35.0, 20.0, 15.0), (50.0, 22.0, 22.0), (28.0, 28.0, 28.0),
                              (30.0, 20.0, 40.0)]):
        ellipsoid(axes, faces=2000, triangulation="random", seed=k).mesh.export(
            root / "v" / f"e{k}.stl")
    return root


def run(meshes, out, *extra):
    argv = ["match", "--tangible", str(meshes / "t"), "--virtual", str(meshes / "v"), "-o",
            str(out), "--count", str(COUNT), "-q", "--no-view", *extra]
    return main(argv)


def outputs(out):
    """Every file a run wrote, by its path under ``out``: name -> bytes."""
    return {str(p.relative_to(out)): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("extra, settings", [
    ([], MatchSettings()),
    (["--normalize", "range", "--one-to-one", "--keep-upright", "--top-k", "2"],
     MatchSettings(normalize="range", one_to_one=True, keep_upright=True, top_k=2)),
])
def test_a_run_equals_the_library_search_of_the_whole_scene(meshes, tmp_path, extra, settings):
    assert run(meshes, tmp_path / "out", "--jobs", "1", "--no-figures", *extra) == 0
    pinch = PinchSettings(count=COUNT)
    # the props stand on their tables (--support auto); virtual objects of their own files stand
    # nowhere
    def load(folder, support):
        return [cached_candidates(ObjectSpec(str(p), support=support), cache=None, settings=pinch)
                for p in sorted((meshes / folder).glob("*.stl"))]

    scene = match_scene(load("t", "auto"), load("v", None), settings=settings, pinch_settings=pinch)
    doc = matches_document(scene,
                           {**pinch.as_dict(), **settings.as_dict(), "units": None, "up": None,
                            "split": "none",
                                   "support": "auto"}, figures=False)
    assert (tmp_path / "out" / "matches.json").read_text() == to_json(doc)


def test_two_processes_write_the_same_bytes_as_one(meshes, tmp_path):
    assert run(meshes, tmp_path / "one", "--jobs", "1", "--figures") == 0
    assert run(meshes, tmp_path / "two", "--jobs", "2", "--figures") == 0
    one, two = outputs(tmp_path / "one"), outputs(tmp_path / "two")
    assert len([p for p in one if p.startswith("scenes/")]) == 4
    assert len([p for p in one if p.startswith("figures/criteria/")]) == 4
    assert one.keys() == two.keys()
    assert all(one[p] == two[p] for p in one), [p for p in one if one[p] != two[p]]


def test_a_dask_cluster_writes_the_same_bytes(meshes, tmp_path):
    distributed = pytest.importorskip("distributed")
    extra = ["--normalize", "range", "--no-figures"]
    assert run(meshes, tmp_path / "serial", "--jobs", "1", *extra) == 0
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        assert run(meshes, tmp_path / "dask", "--scheduler", cluster.scheduler_address, *extra) == 0
    assert outputs(tmp_path / "serial") == outputs(tmp_path / "dask")


def test_results_do_not_depend_on_the_cache(meshes, tmp_path):
    assert run(meshes, tmp_path / "cold", "--jobs", "1", "--no-figures") == 0
    # every object from the cache
    assert run(meshes, tmp_path / "warm", "--jobs", "1", "--no-figures") == 0
    assert outputs(tmp_path / "cold") == outputs(tmp_path / "warm")


def test_jsonl_streams_one_line_per_virtual_object_and_holds_the_same_document(
    meshes, tmp_path, capsys):
    assert run(meshes, tmp_path / "json", "--jobs", "1", "--no-figures") == 0
    # an earlier run, in json
    assert run(meshes, tmp_path / "lines", "--jobs", "1", "--no-figures") == 0
    (tmp_path / "lines" / "notes.json").write_text("{}")  # the user's own file
    assert run(meshes, tmp_path / "lines", "--jobs", "1", "--no-figures", "--format", "jsonl") == 0
    # the earlier run's: stale once jsonl is written
    assert not (tmp_path / "lines" / "matches.json").exists()
    assert (tmp_path / "lines" / "notes.json").read_text() == "{}"
    lines = (tmp_path / "lines" / "matches.jsonl").read_text().splitlines()
    records = [json.loads(line) for line in lines]
    assert [r["record"] for r in records] == ["header"] + ["match"] * 4 + ["end"]
    assert records[-1] == {"record": "end", "virtual_count": 4, "matched_count": 4,
                           "failed_count": 0}
    expected = json.loads((tmp_path / "json" / "matches.json").read_text())
    assert matches_from_lines(lines) == expected
    assert not list((tmp_path / "lines").glob(".*.tmp"))
    # the viewer reads the stream
    assert main(["view", str(tmp_path / "lines"), "-q"]) == 0
    assert (tmp_path / "lines" / "index.html").stat().st_size > 100_000


def test_a_cut_stream_is_refused_by_the_viewer(meshes, tmp_path, capsys):
    assert run(meshes, tmp_path / "lines", "--jobs", "1", "--no-figures", "--format", "jsonl") == 0
    path = tmp_path / "lines" / "matches.jsonl"
    path.write_text("\n".join(path.read_text().splitlines()[:-2]) + "\n")
    capsys.readouterr()
    assert main(["view", str(tmp_path / "lines")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "matches.jsonl" in err[0] and "cut short" in err[0]


def test_poses_are_dumped_only_on_request(meshes, tmp_path):
    # unrefined, so that the best poses are sampled ones, in the dumped lists (a refined pose has
    # none)
    assert run(meshes, tmp_path / "plain", "--jobs", "1", "--no-figures", "--refine", "off") == 0
    assert run(meshes, tmp_path / "dump", "--jobs", "1", "--no-figures", "--dump-poses", "--refine",
               "off") == 0
    plain = json.loads((tmp_path / "plain" / "matches.json").read_text())
    dump = json.loads((tmp_path / "dump" / "matches.json").read_text())
    assert not any("poses" in o for o in plain["tangibles"] + plain["virtuals"])
    for o in dump["tangibles"] + dump["virtuals"]:
        assert len(o["poses"]) == o["pose_count"] > 0
        indices = [p["index"] for p in o["poses"]]
        assert indices == sorted(set(indices)) and all(p["feasible"] for p in o["poses"])
    assert dump["matches"] == plain["matches"]
    best = dump["matches"][0]
    virtual = next(o for o in dump["virtuals"] if o["name"] == best["virtual"])
    pose = next(p for p in virtual["poses"] if p["index"] == best["virtual_pose"]["index"])
    assert pose["width_mm"] == best["virtual_pose"]["width_mm"]
    assert len(json.dumps(dump)) > 10 * len(json.dumps(plain))


def test_a_failed_run_leaves_no_stream(meshes, tmp_path):
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "broken.stl").write_bytes(b"solid x\nfacet nonsense")
    argv = ["match", "--tangible", str(meshes / "t"), "--virtual", str(tmp_path / "bad"), "-o",
            str(tmp_path / "out"), "--count", str(COUNT), "-q", "--jobs", "1", "--format", "jsonl"]
    assert main(argv) == 2
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("role", ["--tangible", "--virtual"])
def test_a_role_whose_only_file_is_missing_fails_in_one_line(meshes, tmp_path, capsys, role):
    paths = {"--tangible": str(meshes / "t"),
             "--virtual": str(meshes / "v")} | {role: str(tmp_path / "gone.stl")}
    argv = ["match", "--tangible", paths["--tangible"], "--virtual", paths["--virtual"], "-o",
            str(tmp_path / "out"), "--count", str(COUNT), "--jobs", "1", "--format", "jsonl"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "gone.stl" in err[0] and "no such file" in err[0], err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("extra, words", [
    (["--jobs", "0"], "--jobs"),
    (["--jobs", "2", "--scheduler", "tcp://127.0.0.1:8786"], "give one of them"),
    (["--json", "--format", "jsonl"], "give one of them"),
    (["--scheduler", "tcp://127.0.0.1:9"], "nothing answers there"),
    (["--scheduler", "notaurl:::"], "not a Dask address"),
    (["--scheduler", "http://127.0.0.1:1"], "'http' is not a Dask protocol"),
])
def test_bad_parallel_options_fail_in_one_line(meshes, tmp_path, capsys, extra, words):
    import time

    argv = ["match", "--tangible", str(meshes / "t"), "--virtual", str(meshes / "v"), "-o",
            str(tmp_path / "out"), "--count", str(COUNT), *extra]
    start = time.perf_counter()
    assert main(argv) == 2
    assert time.perf_counter() - start < 15  # no hang
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not (tmp_path / "out").exists()


def test_the_pool_size_does_not_change_the_result(meshes, monkeypatch):
    import pinchmatch.match.search as search_module

    pinch = PinchSettings(count=COUNT)
    tangibles = [cached_candidates(p, cache=None, settings=pinch)
                 for p in sorted((meshes / "t").glob("*.stl"))]
    virtual = cached_candidates(meshes / "v" / "e2.stl", cache=None, settings=pinch)
    settings = MatchSettings(top_k=4)
    default = match_scene(tangibles, [virtual], settings=settings, pinch_settings=pinch)
    monkeypatch.setattr(search_module, "MIN_POOL", 5)
    monkeypatch.setattr(search_module, "MAX_POOL", 5)
    small = match_scene(tangibles, [virtual], settings=settings, pinch_settings=pinch)
    a, b = default.matches[0], small.matches[0]
    assert np.array_equal(default.cost_matrix, small.cost_matrix)
    for x, y in zip([a.best] + a.alternatives, [b.best] + b.alternatives, strict=True):
        assert (x.tangible, x.t_pose, x.v_pose, x.cost, x.swapped) == (
            y.tangible, y.t_pose, y.v_pose, y.cost, y.swapped)
        assert np.array_equal(x.transform, y.transform)


@pytest.mark.parametrize("jobs", [1, 2])
def test_workers_report_the_stages_of_loading_each_object(meshes, jobs):
    """A large mesh shows where its load is, also when it loads in a worker process."""
    from contextlib import contextmanager

    from pinchmatch.runner.tasks import Job, ObjectTask
    from pinchmatch.runner.executors import executor
    from pinchmatch.runner.matching import run_match

    notes = []

    @contextmanager
    def step(description, total):
        yield lambda note=None, *, done=True: notes.append((description.split(":")[0], note, done))

    settings = PinchSettings(count=60)
    job = Job(units=None, up=None, config=Config(settings, MatchSettings()), scenes=False,
              figures=False)
    tasks = lambda role, folder: [ObjectTask(role, str(p), None, None)  # noqa: E731
                                  for p in sorted((meshes / folder).glob("*.stl"))]
    with executor(jobs) as ex:
        run_match(tasks("tangible", "t"), tasks("virtual", "v")[:2], job, ex,
                  on_failure=lambda f: None, on_result=lambda k, r: None, step=step)
    stages = [(what, note) for what, note, done in notes if not done]
    for name in ("egg.stl", "prop.stl"):
        assert ("tangibles", f"{name}: reading") in stages and (
            "tangibles", f"{name}: surface sample and index") \
            in stages
    # the virtual objects' step
    assert ("e0.stl: repairing: merging "
            "vertices" in [note for what, note in stages if what != "tangibles"])


def test_threads_never_outnumber_the_cores():
    from threadpoolctl import threadpool_info

    from pinchmatch.cores import default_jobs, set_thread_budget, thread_budget
    from pinchmatch.runner.executors import executor

    before = thread_budget()
    with executor(1):  # --jobs 1: one core in all, the patch fits' threads and BLAS included
        assert thread_budget() == 1
        assert all(pool["num_threads"] == 1 for pool in threadpool_info())
    assert thread_budget() == before
    share = max(1, default_jobs() // 2)
    with executor(2) as ex:
        # --jobs 2: each worker its share (set_thread_budget returns the one it had)
        budgets = list(ex.map(set_thread_budget, [share] * 4))
    assert budgets == [share] * 4


class _RecordingTree:
    """A KD-tree that records the ``workers`` of every query."""

    def __init__(self, tree):
        self.tree, self.workers = tree, []

    def query(self, *args, workers=1, **kwargs):
        self.workers.append(workers)
        return self.tree.query(*args, workers=workers, **kwargs)

    def __getattr__(self, name):
        return getattr(self.tree, name)


def test_kd_tree_queries_keep_to_the_thread_budget():
    """Under --jobs 1 every KD-tree query of sampling, the hand and the patch fits runs on one
    thread; with a budget of two, only batches large enough to gain from it use both."""
    from pinchmatch.cores import PARALLEL_QUERY_POINTS, query_workers, set_thread_budget
    from pinchmatch.grasp.sampling import sample_pinches
    from pinchmatch.mesh.shapes import torus
    from pinchmatch.mesh.surface import SurfaceContext
    from pinchmatch.runner.executors import executor

    def queries():
        context = SurfaceContext(torus(triangulation="regular", faces=8000).mesh)
        context.tree = _RecordingTree(context.tree)
        sample_pinches(context, settings=PinchSettings(count=150, seed=1))
        return context.tree.workers

    with executor(1):
        workers = queries()
    assert len(workers) > 10 and set(workers) == {1}
    before = set_thread_budget(2)
    try:
        assert (query_workers(PARALLEL_QUERY_POINTS - 1) == 1
                and query_workers(PARALLEL_QUERY_POINTS) == 2)
        assert set(queries()) <= {1, 2}
    finally:
        set_thread_budget(before)


@pytest.mark.parametrize("rank", ["expected", "nominal"])
def test_a_tangibles_landing_moments_are_made_once_with_its_poses(meshes, monkeypatch, rank):
    """The tangible task makes the steady search's moments; whoever rebuilds the tangible takes them
    as they are (a worker makes none), the same arrays a worker would have made. Ranked on target,
    none are made."""
    from pinchmatch.match import felt, steady
    from pinchmatch.runner.tasks import Job, ObjectTask, candidates_task
    from pinchmatch.runner.worker import tangible_of

    settings = PinchSettings(count=60)
    job = Job(units=None, up=None, config=Config(settings, MatchSettings(rank=rank, refine=False)),
              scenes=False, figures=False)
    computed = candidates_task(ObjectTask("tangible", str(meshes / "t" / "prop.stl")), job)
    assert ("moments_key" in computed.meta) == (rank != "nominal")
    assert "pool_settings" not in computed.meta
    if rank == "nominal":
        return
    made = []
    real = felt.landing_moments
    monkeypatch.setattr(steady, "landing_moments", lambda *a, **k: made.append(1) or real(*a, **k))
    kept = tangible_of(computed.meta, computed.arrays)
    mean, var = steady.moments_of(kept, job.match.landing_mm, settings)
    assert not made  # taken as they came
    fresh = tangible_of({k: v for k, v in computed.meta.items() if k != "moments_key"},
                        computed.arrays)
    again = steady.moments_of(fresh, job.match.landing_mm, settings)
    assert made == [1]
    assert (np.array_equal(mean, again[0], equal_nan=True)
            and np.array_equal(var, again[1], equal_nan=True))


@pytest.mark.parametrize("refine", [True, False])
def test_a_tangibles_feature_pool_and_distance_field_are_made_once_with_its_poses(
    meshes, monkeypatch, refine):
    """Where the match refines, the tangible task draws the targeted step's feature pool and makes
    the surface's distance field; a rebuilt tangible takes both (nothing drawn or made again), equal
    to what it would have made, and the match over them is the same."""
    from pinchmatch.match import targeted
    from pinchmatch.match.scene import match_one
    from pinchmatch.match.search import cost_model
    from pinchmatch.runner.cache import from_payload
    from pinchmatch.runner.tasks import Job, ObjectTask, candidates_task
    from pinchmatch.runner.worker import tangible_of

    settings = PinchSettings(count=60)
    config = Config(settings, MatchSettings(refine=refine))
    job = Job(units=None, up=None, config=config, scenes=False, figures=False)
    computed = candidates_task(ObjectTask("tangible", str(meshes / "t" / "egg.stl")), job)
    assert ("pool_settings" in computed.meta) == refine
    if not refine:
        return
    drawn = []
    real = targeted.cheap_candidates
    monkeypatch.setattr(targeted, "cheap_candidates", lambda *a,
                        **k: drawn.append(1) or real(*a, **k))
    kept = tangible_of(computed.meta, computed.arrays)
    points, faces, tree, _ = targeted.feature_pool(kept, settings)
    field = kept.obj.context.distance_field
    assert not drawn and "distance_field" in kept.obj.context.__dict__
    fresh = from_payload(computed.meta, computed.arrays)  # rebuilt alone: draws and makes its own
    f_points, f_faces, f_tree, _ = targeted.feature_pool(fresh, settings)
    assert drawn == [1]
    assert np.array_equal(points, f_points) and np.array_equal(faces, f_faces)
    assert np.array_equal(tree.data, f_tree.data)
    f_field = fresh.obj.context.distance_field
    assert (np.array_equal(field.distance_mm, f_field.distance_mm)
            and np.array_equal(field.origin_mm, f_field.origin_mm))
    assert (field.voxel_mm, field.margin_mm) == (f_field.voxel_mm, f_field.margin_mm)
    virtual = cached_candidates(str(meshes / "v" / "e1.stl"), cache=None, settings=settings)
    a, b = (match_one([t], virtual, config, model=cost_model(config.match, [t, virtual]),
                      details=False)
            for t in (kept, fresh))
    assert (a.best.t_pose, a.best.v_pose, a.best.cost) == (
        b.best.t_pose, b.best.v_pose, b.best.cost)
