"""Executors: where a run's tasks run, in this process, on local processes or on a Dask cluster.

Whatever runs them, the results come back in input order and are the same bits as a serial run:
the search of one virtual object alone equals its row of the whole scene
(:func:`pinchmatch.match.scene.match_virtual`), and candidates cross process boundaries as the
cache's arrays (:func:`pinchmatch.runner.cache.to_payload`). Only a window of tasks is in flight.
"""

from __future__ import annotations

import os
import pickle
import shutil
import tempfile
import threading
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from ..errors import ConfigError
from ..cores import default_jobs, set_thread_budget
from ..match.candidates import Candidates
from .forkserver import worker_context
from .worker import forget_tangibles, init_worker, keep_tangibles, payload_token, stages_shown_by


class Executor:
    """Runs tasks in this process, one after another, on one core: the patch fits' threads and
    BLAS are held to one while it is open (``--jobs 1`` uses one core in all)."""

    workers = 1

    def __init__(self):
        from threadpoolctl import threadpool_limits

        self._budget_before = set_thread_budget(1)
        self._blas = threadpool_limits(limits=1)

    @contextmanager
    def stages(self, show: Callable[[str, str], None]):
        """While the block runs, ``show(file name, stage)`` is called as a task enters each stage of
        loading an object (reading, repairing, ...): a large mesh shows where its load is."""
        with stages_shown_by(show):
            yield

    def map(self, fn: Callable, items: Iterable, *args) -> Iterator:
        """``fn(item, *args)`` for each item, in order."""
        for item in items:
            yield fn(item, *args)

    def share(self, payloads: list, tangibles: list[Candidates]) -> tuple:
        """A handle on the tangibles (``payloads`` rebuild them) for
        :func:`pinchmatch.runner.worker.tangibles`, valid in every worker."""
        token = payload_token(payloads)
        keep_tangibles(token, tangibles)
        return token, None

    def close(self) -> None:
        forget_tangibles()
        if self._blas is not None:
            self._blas.restore_original_limits()
            set_thread_budget(self._budget_before)
            self._blas = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _in_order(submit: Callable, items: Iterable, window: int) -> Iterator:
    """The results of ``submit(item)`` futures, in input order, with at most ``window`` in
    flight."""
    pending: deque = deque()
    for item in items:
        pending.append(submit(item))
        if len(pending) >= window:
            yield pending.popleft().result()
    while pending:
        yield pending.popleft().result()



#: tasks in flight per local worker: enough that a slow task at the head of the order leaves the
#: other workers busy with those behind it (results come back in order, so they wait there)
WINDOW = 4

#: a local run's temporary folder: the prefix, then the pid of the run that owns it
RUN_FOLDER_PREFIX = "pinchmatch-run-"


def _remove_orphaned_run_folders() -> None:
    """Remove the temporary folders of local runs whose process is gone (killed, so it could
    not)."""
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
    """A pool of ``jobs`` local processes, forked from a server that holds the pipeline loaded
    (:mod:`pinchmatch.runner.forkserver`), or spawned where there is none; never forked from this
    process, whose threads would not survive the fork."""

    def __init__(self, jobs: int):
        from concurrent.futures import ProcessPoolExecutor

        self.workers = jobs
        context = worker_context()
        self._stages = context.SimpleQueue()  # handed to each worker as it starts
        self._pool = ProcessPoolExecutor(max_workers=jobs, mp_context=context,
                                         initializer=init_worker,
                                         initargs=(max(1, default_jobs() // jobs), self._stages,
                                                   os.getpid()))
        _remove_orphaned_run_folders()
        self._folder = tempfile.TemporaryDirectory(prefix=f"{RUN_FOLDER_PREFIX}{os.getpid()}-")
        # every worker started and running before anything else (a run that ends takes them all
        # down)
        for future in [self._pool.submit(os.getpid) for _ in range(jobs)]:
            future.result()

    def map(self, fn, items, *args):
        return _in_order(lambda item: self._pool.submit(fn, item, *args), items,
                         WINDOW * self.workers)

    @contextmanager
    def stages(self, show):
        """As :meth:`Executor.stages`, the workers' reports read by a thread of this process.

        This process never puts on the queue: a worker killed while it puts holds the queue's write
        lock for ever, and a put here would wait for it."""
        done = threading.Event()

        def read():
            while True:
                if not self._stages.empty():
                    show(*self._stages.get())
                elif done.wait(0.02):
                    return

        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        try:
            yield
        finally:
            done.set()
            reader.join(timeout=5)

    def share(self, payloads, tangibles):
        path = Path(self._folder.name) / "tangibles.pickle"
        with open(path, "wb") as fh:
            pickle.dump(payloads, fh, protocol=pickle.HIGHEST_PROTOCOL)
        return payload_token(payloads), str(path)

    def close(self):
        self._pool.shutdown(wait=True, cancel_futures=True)
        self._folder.cleanup()


def _probe_scheduler(address: str, timeout_s: float) -> None:
    """Refuse, in one line and at once, an address that is not a Dask address or where nothing
    listens (a Dask client left half-made by such an address hangs for 20 s when it is
    collected)."""
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
        raise ConfigError(f"--scheduler {address}: nothing answers there ({exc.strerror or exc}); "
                          "check the address and that the scheduler runs") from None


class DaskExecutor(Executor):
    """Tasks on an existing Dask cluster; the workers need pinchmatch installed and the mesh files
    in reach."""

    def __init__(self, address: str, *, timeout_s: float = 10.0):
        try:
            from distributed import Client
        except ImportError:
            raise ConfigError("--scheduler: Dask is not installed; install it with pip install "
                              "'pinchmatch[dask]'") \
                from None
        _probe_scheduler(address, timeout_s)
        try:
            self._client = Client(address, timeout=f"{timeout_s}s", set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise ConfigError(f"--scheduler {address}: cannot reach a Dask scheduler there "
                              f"({exc}); check the address and that the scheduler runs") from None
        self.workers = max(1, sum(self._client.nthreads().values()))

    def map(self, fn, items, *args):
        return _in_order(lambda item: self._client.submit(fn, item, *args, pure=False), items,
                         2 * self.workers)

    def share(self, payloads, tangibles):
        [future] = self._client.scatter([payloads], broadcast=True, hash=False)
        return payload_token(payloads), future

    def close(self):
        self._client.close()


def executor(jobs: int | None = None, scheduler: str | None = None) -> Executor:
    """The executor for ``--jobs`` and ``--scheduler`` (default: all local cores)."""
    if scheduler is not None:
        if jobs is not None:
            raise ConfigError("--jobs and --scheduler: give one of them; the cluster decides how "
                              "many workers run")
        return DaskExecutor(scheduler)
    jobs = default_jobs() if jobs is None else jobs
    if jobs < 1:
        raise ConfigError(f"--jobs: {jobs} must be 1 or more")
    return Executor() if jobs == 1 else LocalExecutor(jobs)

