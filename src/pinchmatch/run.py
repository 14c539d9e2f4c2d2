"""``pinchmatch match`` over many files: per-object work in parallel, on this machine or a Dask cluster.

A run splits into tasks of one object each:

1. each tangible's candidate poses (from the cache, or computed);
2. with ``--normalize range``, each virtual object's feature bounds: the cost model needs every
   feature's range over the whole run before any search;
3. with ``--one-to-one``, each virtual object's row of the cost matrix: the assignment needs them all;
4. each virtual object's candidates, its search against every tangible, its result entry, glTF
   scene and criteria figure.

An :class:`Executor` runs the tasks: in this process (``--jobs 1``), on a pool of local processes
(``--jobs N``), or on an existing Dask cluster (``--scheduler ADDRESS``). Whatever runs them, the
results come back in input order and are the same bits as a serial run: the search of one virtual
object alone equals its row of the whole scene (:func:`pinchmatch.match.match_virtual`), and
candidates cross process boundaries as the cache's arrays (:func:`pinchmatch.cache.to_payload`).

Memory stays bounded: a virtual object's mesh and poses live only inside its task, and only a
window of tasks (twice the workers) is in flight. The parent keeps the tangibles and, per virtual
object, its entry (a few kB), or with ``--format jsonl`` nothing: each line is written as it comes.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
import pickle
import shutil
import signal
import sys
import tempfile
import threading
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .cache import FeatureCache, cached_candidates, from_payload, to_payload
from .cost import feature_bounds, ranges_from_bounds
from .errors import ConfigError, PinchmatchError, route_warnings
from .files import AtomicFile, write_atomic
from .match import (Candidates, MatchSettings, allowed_tangibles, cost_model, cost_row, match_virtual, _Search)
from .pinches import PinchSettings
from .report import (SCHEMA_MATCH_LINES, _num, cost_matrix_section, figure_file, match_entry, matches_header,
                     matches_rows, object_entry, scene_file, to_json)
from .scenes import match_scene_glb

log = logging.getLogger(__name__)


def default_jobs() -> int:
    """All the cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@dataclass(frozen=True)
class Job:
    """What every task of a run needs to know (small, sent with each task)."""

    units: str | None
    up: str | None
    settings: PinchSettings  # its patch_radius_mm is the run's one patch radius
    match: MatchSettings
    cache_folder: str | None = None  # None: no cache
    dump_poses: bool = False
    scenes: bool = True
    figures: bool = True


@dataclass(frozen=True)
class ObjectTask:
    role: str
    path: str
    given: tuple | None = None  # (p1_mm, p2_mm) arrays of given poses
    source: str | None = None  # the poses file they came from


@dataclass(frozen=True)
class Failure:
    """A file that could not be used, and why (the one-line error)."""

    role: str
    path: str
    error: str

    def as_dict(self) -> dict:
        return {"role": self.role, "path": self.path, "error": self.error}


@dataclass(frozen=True)
class Computed:
    """One object's candidates as the cache's arrays, and whether they came from the cache."""

    meta: dict
    arrays: dict
    cached: bool


@dataclass(frozen=True)
class VirtualResult:
    """Everything the output needs of one virtual object; its mesh and poses stay in the task."""

    name: str
    entry: dict  # its object entry in ``virtuals``
    match: dict  # its entry in ``matches``
    row: np.ndarray  # (n,) its row of the cost matrix
    scene_glb: bytes | None
    figure_png: bytes | None
    cached: bool


# --- tasks (run in workers: top-level functions, picklable arguments) ---------------------------

#: where a task reports the stage it is in: set in each local worker (a queue to the run's process),
#: or by the in-process executor; None on Dask workers
_STAGES = None


def _report(task: ObjectTask, stage: str) -> None:
    if _STAGES is not None:
        _STAGES.put((Path(task.path).name, stage))


def _candidates(task: ObjectTask, job: Job) -> tuple[Candidates, bool]:
    cache = FeatureCache(job.cache_folder) if job.cache_folder is not None else None
    c = cached_candidates(task.path, cache=cache, units=job.units, up=job.up, settings=job.settings,
                          given=task.given, source=task.source, progress=lambda stage: _report(task, stage))
    return c, bool(cache is not None and cache.hits)


def _per_file(fn: Callable) -> Callable:
    """A task whose item is an ObjectTask (or a tuple starting with one): a bad file makes a Failure."""

    @functools.wraps(fn)
    def task(item, *args):
        try:
            return fn(item, *args)
        except PinchmatchError as exc:
            t = item if isinstance(item, ObjectTask) else item[0]
            return Failure(t.role, t.path, str(exc))

    return task


@_per_file
def candidates_task(task: ObjectTask, job: Job) -> Computed | Failure:
    c, cached = _candidates(task, job)
    return Computed(*to_payload(c), cached)


@_per_file
def bounds_task(task: ObjectTask, job: Job) -> np.ndarray | Failure:
    return feature_bounds(_candidates(task, job)[0].table)


#: per worker process: the run's tangibles, by token, rebuilt once from their payloads
_TANGIBLES: dict[str, list[Candidates]] = {}


def _tangibles(shared) -> list[Candidates]:
    token, source = shared
    if token not in _TANGIBLES:
        if isinstance(source, (str, os.PathLike)):  # a local pool: a file the parent wrote
            with open(source, "rb") as fh:
                source = pickle.load(fh)
        _TANGIBLES.clear()
        _TANGIBLES[token] = [from_payload(meta, arrays) for meta, arrays in source]
    return _TANGIBLES[token]


@_per_file
def row_task(task: ObjectTask, job: Job, shared, model) -> np.ndarray | Failure:
    c, _ = _candidates(task, job)
    return cost_row(_Search(_tangibles(shared), [c], model, job.match), 0)


@_per_file
def virtual_task(item: tuple, job: Job, shared, model) -> VirtualResult | Failure:
    """Item: (task, its entry of :func:`allowed_tangibles` or None, its cost row or None)."""
    task, allowed, row = item
    c, cached = _candidates(task, job)
    tangibles = _tangibles(shared)
    scene = match_virtual(tangibles, c, model, job.match, allowed=allowed, row=row,
                          pinch_settings=job.settings)
    return virtual_result(scene, 0, job, cached=cached)


def virtual_result(scene, k: int, job: Job, *, cached: bool = False) -> VirtualResult:
    """What the output needs of virtual object ``k`` of a matched scene: its entries, its cost row,
    and its glTF scene and criteria figure as bytes (when the job wants them). Every command's
    results reach the output through this and :class:`MatchesSink`."""
    vm = scene.matches[k]
    virtual = scene.virtuals[k]
    match = match_entry(scene, vm)
    glb = png = None
    if vm.best is not None:
        if job.scenes:
            glb = match_scene_glb(scene.tangibles[vm.best.tangible], virtual, vm.best, hand=job.settings.hand)
        if job.figures:
            from .figures import _png, criteria_figure  # matplotlib: imported when figures are wanted

            png = _png(criteria_figure(match))
    return VirtualResult(virtual.name, object_entry(virtual, dump_poses=job.dump_poses), match,
                         scene.cost_matrix[k], glb, png, cached)


# --- executors -------------------------------------------------------------------------------

class Executor:
    """Runs tasks in this process, one after another."""

    workers = 1

    @contextmanager
    def stages(self, show: Callable[[str, str], None]):
        """While the block runs, ``show(file name, stage)`` is called as a task enters each stage of
        loading an object (reading, repairing, ...): a large mesh shows where its load is."""
        global _STAGES
        previous, _STAGES = _STAGES, _Direct(show)
        try:
            yield
        finally:
            _STAGES = previous

    def map(self, fn: Callable, items: Iterable, *args) -> Iterator:
        """``fn(item, *args)`` for each item, in order."""
        for item in items:
            yield fn(item, *args)

    def share(self, payloads: list, tangibles: list[Candidates]) -> tuple:
        """A handle on the tangibles (``payloads`` rebuild them) for :func:`_tangibles`, valid in every worker."""
        token = _token(payloads)
        _TANGIBLES.clear()
        _TANGIBLES[token] = tangibles
        return token, None

    def close(self) -> None:
        _TANGIBLES.clear()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _token(payloads: list) -> str:
    h = hashlib.sha256()
    for meta, arrays in payloads:
        h.update(repr(sorted(meta.items())).encode())
        for name in sorted(arrays):
            h.update(np.ascontiguousarray(arrays[name]).tobytes())
    return h.hexdigest()


def _in_order(submit: Callable, items: Iterable, window: int) -> Iterator:
    """The results of ``submit(item)`` futures, in input order, with at most ``window`` in flight."""
    pending: deque = deque()
    for item in items:
        pending.append(submit(item))
        if len(pending) >= window:
            yield pending.popleft().result()
    while pending:
        yield pending.popleft().result()


def _die_with_parent() -> None:
    """Ask Linux to send this process SIGTERM when its parent dies (prctl PR_SET_PDEATHSIG), so a
    killed run leaves no worker behind; elsewhere nothing happens."""
    if sys.platform != "linux":
        return
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM, 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() == 1:  # the parent died before the request: go now
        os._exit(1)


class _Direct:
    """A stage report in this process: shown at once."""

    def __init__(self, show):
        self.show = show

    def put(self, item) -> None:
        self.show(*item)


def _init_worker(threads: int, stages=None) -> None:
    """A local worker: numpy's BLAS gets its share of the cores, not all of them; it ends when the
    run that started it ends, however that ends; it reports stages on ``stages``."""
    global _LIMITS, _STAGES
    _die_with_parent()
    _STAGES = stages
    from threadpoolctl import threadpool_limits

    _LIMITS = threadpool_limits(limits=threads)
    logging.getLogger("pinchmatch").setLevel(logging.ERROR)  # the parent reports; workers stay quiet
    route_warnings(verbose=False)


_LIMITS = None


#: a local run's temporary folder: the prefix, then the pid of the run that owns it
RUN_FOLDER_PREFIX = "pinchmatch-run-"


def _remove_orphaned_run_folders() -> None:
    """Remove the temporary folders of local runs whose process is gone (killed, so it could not)."""
    root = Path(tempfile.gettempdir())
    for folder in root.glob(f"{RUN_FOLDER_PREFIX}*-*"):
        pid = folder.name[len(RUN_FOLDER_PREFIX):].split("-", 1)[0]
        if not pid.isdigit() or not folder.is_dir() or folder.is_symlink():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            shutil.rmtree(folder, ignore_errors=True)
        except PermissionError:
            pass  # someone else's live process


class LocalExecutor(Executor):
    """A pool of ``jobs`` local processes (started fresh, not forked, so that BLAS threads are sane)."""

    def __init__(self, jobs: int):
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        self.workers = jobs
        context = multiprocessing.get_context("spawn")
        self._stages = context.SimpleQueue()  # handed to each worker as it starts
        self._pool = ProcessPoolExecutor(max_workers=jobs, mp_context=context, initializer=_init_worker,
                                         initargs=(max(1, default_jobs() // jobs), self._stages))
        _remove_orphaned_run_folders()
        self._folder = tempfile.TemporaryDirectory(prefix=f"{RUN_FOLDER_PREFIX}{os.getpid()}-")

    def map(self, fn, items, *args):
        return _in_order(lambda item: self._pool.submit(fn, item, *args), items, 2 * self.workers)

    @contextmanager
    def stages(self, show):
        """As :meth:`Executor.stages`, the workers' reports read by a thread of this process."""
        def read():
            while (item := self._stages.get()) is not None:
                show(*item)

        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        try:
            yield
        finally:
            self._stages.put(None)
            reader.join(timeout=5)

    def share(self, payloads, tangibles):
        path = Path(self._folder.name) / "tangibles.pickle"
        with open(path, "wb") as fh:
            pickle.dump(payloads, fh, protocol=pickle.HIGHEST_PROTOCOL)
        return _token(payloads), str(path)

    def close(self):
        self._pool.shutdown(wait=True, cancel_futures=True)
        self._folder.cleanup()


def _probe_scheduler(address: str, timeout_s: float) -> None:
    """Refuse, in one line and at once, an address that is not a Dask address or where nothing
    listens (a Dask client left half-made by such an address hangs for 20 s when it is collected)."""
    import socket

    from distributed.comm import parse_address, parse_host_port
    from distributed.comm.registry import backends

    hint = "give it as tcp://HOST:PORT, the address the scheduler prints"
    try:
        scheme, location = parse_address(address, strict=True)
    except (ValueError, TypeError):
        raise ConfigError(f"--scheduler {address}: not a Dask address; {hint}") from None
    if scheme not in backends:
        raise ConfigError(f"--scheduler {address}: {scheme!r} is not a Dask protocol "
                          f"({', '.join(sorted(backends))}); {hint}")
    if scheme not in ("tcp", "tls"):
        return
    try:
        host, port = parse_host_port(location)
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except (ValueError, TypeError):
        raise ConfigError(f"--scheduler {address}: no host and port in it; {hint}") from None
    except OSError as exc:
        raise ConfigError(f"--scheduler {address}: nothing answers there ({exc.strerror or exc}); check the "
                          "address and that the scheduler runs") from None


class DaskExecutor(Executor):
    """Tasks on an existing Dask cluster; the workers need pinchmatch installed and the mesh files in reach."""

    def __init__(self, address: str, *, timeout_s: float = 10.0):
        try:
            from distributed import Client
        except ImportError:
            raise ConfigError("--scheduler: Dask is not installed; install it with pip install 'pinchmatch[dask]'") \
                from None
        _probe_scheduler(address, timeout_s)
        try:
            self._client = Client(address, timeout=f"{timeout_s}s", set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise ConfigError(f"--scheduler {address}: cannot reach a Dask scheduler there ({exc}); "
                              "check the address and that the scheduler runs") from None
        self.workers = max(1, sum(self._client.nthreads().values()))

    def map(self, fn, items, *args):
        return _in_order(lambda item: self._client.submit(fn, item, *args, pure=False), items, 2 * self.workers)

    def share(self, payloads, tangibles):
        [future] = self._client.scatter([payloads], broadcast=True, hash=False)
        return _token(payloads), future

    def close(self):
        self._client.close()


def executor(jobs: int | None = None, scheduler: str | None = None) -> Executor:
    """The executor for ``--jobs`` and ``--scheduler`` (default: all local cores)."""
    if scheduler is not None:
        if jobs is not None:
            raise ConfigError("--jobs and --scheduler: give one of them; the cluster decides how many workers run")
        return DaskExecutor(scheduler)
    jobs = default_jobs() if jobs is None else jobs
    if jobs < 1:
        raise ConfigError(f"--jobs: {jobs} must be 1 or more")
    return Executor() if jobs == 1 else LocalExecutor(jobs)


# --- the run ---------------------------------------------------------------------------------

@dataclass
class RunResult:
    tangibles: list[Candidates]
    cost_rows: dict  # virtual index -> row
    failed: list[Failure]
    cached: int  # objects whose candidates came from the cache
    computed: int


def run_match(tangible_tasks: list[ObjectTask], virtual_tasks: list[ObjectTask], job: Job, ex: Executor, *,
              on_failure: Callable[[Failure], None], on_result: Callable[[int, VirtualResult], None],
              step: Callable, header: Callable[[list[Candidates]], None] = lambda tangibles: None) -> RunResult:
    """Run every task; hand each virtual object's result, in input order, to ``on_result(k, result)``.

    ``header(tangibles)`` is called once the tangibles are known, before any virtual object's result.
    ``step(description, total)`` is a context manager yielding ``advance(note, done=...)``, as
    :meth:`pinchmatch._console.Presenter.step`. A role with no usable file raises the single error,
    or a :class:`ConfigError` naming the first.
    """
    failed: list[Failure] = []
    counts = {"cached": 0, "computed": 0}

    def each(description: str, fn: Callable, tasks: list[ObjectTask], items: list, *args) -> Iterator:
        """(position, result) of ``fn`` over ``items`` (one per task), in order; failures recorded, left out."""
        with step(description, len(tasks)) as advance, \
                ex.stages(lambda name, stage: advance(f"{name}: {stage}", done=False)):
            for k, (task, r) in enumerate(zip(tasks, ex.map(fn, items, *args))):
                advance(Path(task.path).name)
                if not isinstance(r, Failure):
                    yield k, r
                    continue
                failed.append(r)
                if len(tangible_tasks if r.role == "tangible" else virtual_tasks) > 1:
                    on_failure(r)  # a role's only file: the run stops, and its error says it once

    def none_usable(role: str):
        errors = [f for f in failed if f.role == role]
        if not errors:
            return ConfigError(f"no {role} object given; name at least one with --{role}")
        if len(errors) == 1:
            return _Failed(errors[0].error)
        return ConfigError(f"none of the {len(errors)} {role} files could be used (first: {errors[0].error}); "
                           "fix or remove them")

    payloads = []
    for _, r in each("tangibles: poses and features", candidates_task, tangible_tasks, tangible_tasks, job):
        payloads.append((r.meta, r.arrays))
        counts["cached" if r.cached else "computed"] += 1
    if not payloads:
        raise none_usable("tangible")
    tangibles = [from_payload(meta, arrays) for meta, arrays in payloads]
    shared = ex.share(payloads, tangibles)
    header(tangibles)

    todo = list(range(len(virtual_tasks)))  # the virtual objects not failed yet
    ranges = None
    if job.match.normalize == "range":
        bounds = [feature_bounds(t.table) for t in tangibles]
        done = list(each("virtual objects: feature ranges", bounds_task, virtual_tasks, virtual_tasks, job))
        todo = [k for k, _ in done]
        ranges = ranges_from_bounds(bounds + [b for _, b in done])
    model = cost_model(job.match, tangibles, ranges=ranges)

    plan: dict[int, tuple] = {k: (None, None) for k in todo}
    if job.match.one_to_one:
        tasks = [virtual_tasks[k] for k in todo]
        done = [(todo[i], row) for i, row in each("virtual objects: cost rows", row_task, tasks, tasks, job, shared,
                                                    model)]
        todo = [k for k, _ in done]
        if todo:
            allowed = allowed_tangibles(np.array([row for _, row in done]), job.match)
            plan = {k: (allowed[i], row) for i, (k, row) in enumerate(done)}

    cost_rows = {}
    tasks = [virtual_tasks[k] for k in todo]
    items = [(virtual_tasks[k], *plan[k]) for k in todo]
    for i, r in each("virtual objects: poses, features, search", virtual_task, tasks, items, job, shared, model):
        counts["cached" if r.cached else "computed"] += 1
        cost_rows[todo[i]] = r.row
        on_result(todo[i], r)
    if not cost_rows:
        raise none_usable("virtual")
    return RunResult(tangibles, cost_rows, failed, counts["cached"], counts["computed"])


class _Failed(PinchmatchError):
    """A role's only file failed: its own error, as one line."""


class RunError(Exception):
    """The run itself broke (a worker died), not the input: one line, exit 1, and what to change."""


# --- output, as results come ------------------------------------------------------------------

class MatchesSink:
    """Writes a run's results as they come: each scene and criteria figure at once, and either
    ``matches.json`` at the end or ``matches.jsonl`` line by line (docs/output-format.md).

    Every file appears whole (a temporary file, then a rename); a run that stops early leaves no
    result file. The tables for the summary are kept (one short row per object).
    """

    def __init__(self, out: Path, fmt: str, stems: list[str]):
        self.out, self.fmt, self.stems = Path(out), fmt, stems
        self.result_path = self.out / f"matches.{fmt}"
        self.scenes = 0
        self.objects = [("object", "role", "faces", "feasible poses")]
        self.rows = matches_rows({"matches": []})
        self._header = None
        self._virtuals, self._matches, self._names, self._cost_rows, self._chosen = [], [], [], [], []
        self._lines = None  # the AtomicFile of matches.jsonl while it is being written

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self._lines is not None:  # stopped before finish: no half-written result
            self._lines.abort()
            self._lines = None

    def _line(self, record: dict) -> None:
        self._lines.write(json.dumps(record, allow_nan=False, separators=(",", ":")) + "\n")

    def start(self, settings: dict, tangibles: list[Candidates], dump_poses: bool) -> None:
        entries = [object_entry(t, dump_poses=dump_poses) for t in tangibles]
        self.objects += [(e["name"], "tangible", e["faces"], e["pose_count"]) for e in entries]
        self._header = matches_header(settings, entries)
        if self.fmt == "jsonl":
            self._lines = AtomicFile(self.result_path)
            self._line({"record": "header", **self._header, "schema": SCHEMA_MATCH_LINES})

    def add(self, k: int, r: VirtualResult) -> None:
        stem = self.stems[k]
        if r.scene_glb is not None:
            write_atomic(self.out / scene_file(stem), r.scene_glb)
            r.match.update(scene_file=scene_file(stem), figure_file=None)
            self.scenes += 1
        if r.figure_png is not None:
            write_atomic(self.out / figure_file(stem), r.figure_png)
            r.match["figure_file"] = figure_file(stem)
        self.objects.append((r.name, "virtual", r.entry["faces"], r.entry["pose_count"]))
        self.rows += matches_rows({"matches": [r.match]})[1:]
        self._names.append(r.name)
        self._cost_rows.append(r.row)
        self._chosen.append(r.match.get("tangible"))
        if self._lines is not None:
            self._line({"record": "match", "object": r.entry, "cost_row": [_num(x, 6) for x in r.row],
                        "match": r.match})
        else:
            self._virtuals.append(r.entry)
            self._matches.append(r.match)

    def overview(self) -> dict:
        """The cost matrix and the chosen tangibles, as :func:`pinchmatch.figures.cost_matrix_figure` reads them."""
        return {"cost_matrix": cost_matrix_section(self._names, [t["name"] for t in self._header["tangibles"]],
                                                   self._cost_rows),
                "matches": [{"virtual": n, "tangible": t} for n, t in zip(self._names, self._chosen)]}

    def finish(self, result: RunResult) -> dict | None:
        """Close the result file; return the matches document (None for jsonl, never held whole)."""
        failed = [f.as_dict() for f in result.failed]
        if self._lines is None:
            doc = self._header | {"virtuals": self._virtuals, "matches": self._matches, "failed": failed,
                                  "cost_matrix": self.overview()["cost_matrix"]}
            write_atomic(self.result_path, to_json(doc))
            return doc
        for f in failed:
            self._line({"record": "failed", **f})
        self._line({"record": "end", "virtual_count": len(self._names),
                    "matched_count": sum(t is not None for t in self._chosen), "failed_count": len(failed)})
        self._lines.commit()
        self._lines = None
        return None
