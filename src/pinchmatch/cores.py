"""How many cores a run may use, and how its threads share them.

A run works on objects in one process (``--jobs 1``) or in several (``--jobs N``, or a Dask
cluster), and inside each process the patch fits run on a pool of threads and numpy's BLAS on
its own. Unbounded, every process would start a thread per core and the machine would run N
times more threads than it has cores. The *thread budget* is how many threads one process may
use: every core where nothing says otherwise, its share in a worker of a local pool, one with
``--jobs 1``. The fits read it (:func:`thread_budget`); the runner sets it
(:func:`set_thread_budget`), together with threadpoolctl's limit on BLAS.

Imports nothing heavy, so that the command line can say the default in its help without loading
the pipeline. KD-tree queries run on the budget through :func:`query_tree`.
"""

from __future__ import annotations

import os

_BUDGET: int | None = None


def default_jobs() -> int:
    """All the cores this process may use (its CPU affinity where the system has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def thread_budget() -> int:
    """How many threads this process may run at once: the budget set, else every core it may use."""
    return _BUDGET if _BUDGET is not None else default_jobs()


def set_thread_budget(threads: int | None) -> int | None:
    """Let this process run at most ``threads`` threads at once (None: every core); return the
    budget before, so that a caller can give it back."""
    global _BUDGET
    if threads is not None and threads < 1:
        raise ValueError(f"a thread budget of {threads}: give 1 or more")
    before, _BUDGET = _BUDGET, threads
    return before


#: below this many query points a KD-tree query runs on the calling thread: scipy starts its
#: threads anew for every call, which costs more than a small batch takes
PARALLEL_QUERY_POINTS = 4_000


def query_workers(points: int) -> int:
    """``workers=`` for a scipy KD-tree query of ``points`` points, within the thread budget."""
    return thread_budget() if points >= PARALLEL_QUERY_POINTS else 1


def query_tree(tree, points, *, work: int, **options):
    """``tree.query(points, **options)`` (a scipy KD-tree) on :func:`query_workers` ``(work)``
    threads."""
    return tree.query(points, workers=query_workers(work), **options)
