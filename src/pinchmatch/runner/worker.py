"""What each worker process of a run holds: where it reports stages, and the run's tangibles.

A task runs in this process (``--jobs 1``), in a local worker process (``--jobs N``) or on a Dask
worker. Wherever it runs, it reports the stage of an object's load with :func:`report_stage` and
finds the run's tangibles with :func:`tangibles`; the executors set both up
(:mod:`pinchmatch.runner.executors`).
"""

from __future__ import annotations

import hashlib
import logging
import os
import pickle
import select
import signal
import sys
import threading
import time
from collections.abc import Callable
from contextlib import contextmanager

import numpy as np

from ..cores import set_thread_budget
from ..errors import route_warnings
from ..match.candidates import Candidates
from ..match.steady import keep_moments
from ..match.targeted import keep_pool
from ..mesh.distance_field import DistanceField
from .cache import from_payload

#: where a task reports the stage it is in: set in each local worker (a queue to the run's process),
#: or by the in-process executor; None on Dask workers
_STAGES = None


def report_stage(name: str, stage: str) -> None:
    """Tell the run that the object in file ``name`` entered ``stage`` (nothing when no one
    listens)."""
    if _STAGES is not None:
        _STAGES.put((name, stage))


class _Direct:
    """A stage report in this process: shown at once."""

    def __init__(self, show):
        self.show = show

    def put(self, item) -> None:
        self.show(*item)


@contextmanager
def stages_shown_by(show: Callable[[str, str], None]):
    """While the block runs, the stages reported in this process go to ``show(file name,
    stage)``."""
    global _STAGES
    previous, _STAGES = _STAGES, _Direct(show)
    try:
        yield
    finally:
        _STAGES = previous


#: per worker process: the run's tangibles, by token, rebuilt once from their payloads
_TANGIBLES: dict[str, list[Candidates]] = {}


def tangible_of(meta: dict, arrays: dict) -> Candidates:
    """A tangible's candidates from its payload, with what its task made of them, where it did
    (:func:`pinchmatch.runner.tasks.candidates_task`)."""
    c = from_payload(meta, arrays)
    if "moments_key" in meta:
        keep_moments(c, tuple(meta["moments_key"]), (arrays["moments.mean"], arrays["moments.var"]))
    if "pool_settings" in meta:
        keep_pool(c, meta["pool_settings"], arrays["pool.points"], arrays["pool.faces"])
        origin, voxel, margin = meta["distance_field"]
        c.obj.context.keep_distance_field(DistanceField(np.array(origin), voxel,
                                                        arrays["distance_field"], margin))
    return c


def payload_token(payloads: list) -> str:
    """A digest of the tangibles' payloads: the key under which each worker keeps them."""
    h = hashlib.sha256()
    for meta, arrays in payloads:
        h.update(repr(sorted(meta.items())).encode())
        for name in sorted(arrays):
            h.update(np.ascontiguousarray(arrays[name]).tobytes())
    return h.hexdigest()


def keep_tangibles(token: str, tangibles: list[Candidates]) -> None:
    """This process holds the run's tangibles already (the in-process executor)."""
    _TANGIBLES.clear()
    _TANGIBLES[token] = tangibles


def forget_tangibles() -> None:
    _TANGIBLES.clear()


def tangibles(shared) -> list[Candidates]:
    """The run's tangibles from a handle of :meth:`Executor.share`: (token, payloads, or the path
    of a file holding them, or None when this process keeps them already)."""
    token, source = shared
    if token not in _TANGIBLES:
        if isinstance(source, (str, os.PathLike)):  # a local pool: a file the parent wrote
            with open(source, "rb") as fh:
                source = pickle.load(fh)
        _TANGIBLES.clear()
        _TANGIBLES[token] = [tangible_of(meta, arrays) for meta, arrays in source]
    return _TANGIBLES[token]


def _die_with_parent() -> None:
    """Ask Linux to send this process SIGTERM when its parent dies (prctl PR_SET_PDEATHSIG);
    elsewhere nothing happens."""
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


def _die_with_run(run_pid: int) -> None:
    """End this worker (SIGTERM) when the run's process ends, however it ends, even killed: a killed
    run leaves no worker behind. A spawned worker's parent is the run (PR_SET_PDEATHSIG); a worker
    forked from the fork server has the server as its parent, so a thread waits on the run's process
    (a pidfd where Linux has them, else polling)."""
    if os.getppid() == run_pid:
        _die_with_parent()
        return

    def watch():
        try:
            fd = os.pidfd_open(run_pid)
        except (AttributeError, OSError):
            fd = None
        if fd is not None:
            select.select([fd], [], [])  # readable once the process has ended
        else:
            while _alive(run_pid):
                time.sleep(0.2)
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=watch, name="pinchmatch-run-watch", daemon=True).start()
    if not _alive(run_pid):  # the run ended before the watch began
        os._exit(1)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True



def init_worker(threads: int, stages=None, run_pid: int | None = None) -> None:
    """A local worker: numpy's BLAS and the patch fits get its share of the cores, not all of them;
    it ends when the run that started it (process ``run_pid``, default the parent) ends, however
    that ends; it reports stages on ``stages``."""
    global _LIMITS, _STAGES
    _die_with_run(os.getppid() if run_pid is None else run_pid)
    _STAGES = stages
    from threadpoolctl import threadpool_limits

    _LIMITS = threadpool_limits(limits=threads)
    set_thread_budget(threads)  # the patch fits' threads too
    # the parent reports; workers stay quiet
    logging.getLogger("pinchmatch").setLevel(logging.ERROR)
    route_warnings(verbose=False)


_LIMITS = None
