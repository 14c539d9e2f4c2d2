"""``pinchmatch match`` over many files: the run, its tasks handed to an executor.

A run splits into tasks of one object each (:mod:`pinchmatch.runner.tasks`). An executor runs
them (:mod:`pinchmatch.runner.executors`): in this process (``--jobs 1``), on a pool of local
processes (``--jobs N``), or on an existing Dask cluster (``--scheduler ADDRESS``).

Memory stays bounded: a virtual object's mesh and poses live only inside its task, and only a
window of tasks is in flight. The parent keeps the tangibles and, per virtual object, its entry
(a few kB), or with ``--format jsonl`` nothing: each line is written as it comes
(:class:`pinchmatch.export.sink.MatchesSink`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, PinchmatchError
from ..match.candidates import Candidates
from ..match.cost import feature_bounds, ranges_from_bounds
from ..match.scene import allowed_tangibles
from ..match.search import cost_model
from .executors import Executor
from .worker import tangible_of
from .tasks import (Failure, Job, ObjectTask, VirtualResult, bounds_task, candidates_task,
                    load_task, row_task, virtual_task)


@dataclass
class RunResult:
    tangibles: list[Candidates]
    cost_rows: dict  # virtual index -> row
    failed: list[Failure]
    cached: int  # objects whose candidates came from the cache
    computed: int


def run_match(tangible_tasks: list[ObjectTask], virtual_tasks: list[ObjectTask], job: Job,
              ex: Executor, *, on_failure: Callable[[Failure], None],
              on_result: Callable[[int, VirtualResult], None], step: Callable,
              header: Callable[[list[Candidates]], None] = lambda tangibles: None,
              virtual_fn: Callable = virtual_task, plan: dict | None = None) -> RunResult:
    """Run every task; hand each virtual object's result, in input order, to ``on_result(k,
    result)``.

    ``virtual_fn`` is the virtual objects' task: :func:`virtual_task` (the whole result), or
    :func:`~pinchmatch.runner.tasks.served_task` (the row of the served matrix, for ``select``).
    ``plan`` gives, per virtual object (by position), the tangibles it may use and why none, as
    :func:`~pinchmatch.match.scene.allowed_tangibles` does (default: every tangible).

    ``header(tangibles)`` is called once the tangibles are known, before any virtual object's
    result. ``step(description, total)`` is a context manager yielding ``advance(note, done=...)``,
    as :meth:`pinchmatch.cli.console.Presenter.step`. A role with no usable file raises the single
    error, or a :class:`ConfigError` naming the first.
    """
    failed: list[Failure] = []
    counts = {"cached": 0, "computed": 0}

    def each(description: str, fn: Callable, tasks: list[ObjectTask], items: list,
             *args) -> Iterator:
        """(position, result) of ``fn`` over ``items`` (one per task), in order; failures recorded,
        left out."""
        with step(description, len(tasks)) as advance, \
                ex.stages(lambda name, stage: advance(f"{name}: {stage}", done=False)):
            for k, (task, r) in enumerate(zip(tasks, ex.map(fn, items, *args))):
                advance(task.name)
                if not isinstance(r, Failure):
                    yield k, r
                    continue
                failed.append(r)
                if len(tangible_tasks if r.role == "tangible" else virtual_tasks) > 1:
                    on_failure(r)  # a role's only file: the run stops, and its error says it once

    def none_usable(role: str, also: str = ""):
        errors = [f for f in failed if f.role == role]
        if not errors:
            return ConfigError(f"no {role} object given; name at least one with --{role}{also}")
        if len(errors) == 1:
            return RoleFailed(errors[0].error + also)
        return ConfigError(f"none of the {len(errors)} {role} files could be used (first: "
                           f"{errors[0].error}); fix or remove them{also}")

    payloads = []
    for _, r in each("tangibles: poses and features", candidates_task, tangible_tasks,
                     tangible_tasks, job):
        payloads.append((r.meta, r.arrays))
        counts["cached" if r.cached else "computed"] += 1
    if not payloads:
        # the virtual files are read too, so that one run shows every file's problem (units, say)
        bad = [f for f in ex.map(load_task, virtual_tasks, job) if isinstance(f, Failure)]
        also = "" if not bad else (f"; the virtual file {bad[0].error}" if len(bad) == 1 else
                                   f"; {len(bad)} of the {len(virtual_tasks)} virtual files cannot "
                                   f"be used either (first: {bad[0].error})")
        raise none_usable("tangible", also)
    tangibles = [tangible_of(meta, arrays) for meta, arrays in payloads]
    shared = ex.share(payloads, tangibles)
    header(tangibles)

    todo = list(range(len(virtual_tasks)))  # the virtual objects not failed yet
    ranges = None
    if job.match.normalize == "range":
        bounds = [feature_bounds(t.table) for t in tangibles]
        done = list(each("virtual objects: feature ranges", bounds_task, virtual_tasks,
                         virtual_tasks, job))
        todo = [k for k, _ in done]
        ranges = ranges_from_bounds(bounds + [b for _, b in done])
    model = cost_model(job.match, tangibles, ranges=ranges)

    plan = {k: (None if plan is None else plan[k], None) for k in todo}
    if job.match.one_to_one:
        tasks = [virtual_tasks[k] for k in todo]
        done = [(todo[i], row)
                for i, row in each("virtual objects: cost rows", row_task, tasks, tasks, job,
                                   shared,
                                                    model)]
        todo = [k for k, _ in done]
        if todo:
            allowed = allowed_tangibles(np.array([row for _, row in done]), job.match)
            plan = {k: (allowed[i], row) for i, (k, row) in enumerate(done)}

    cost_rows = {}
    tasks = [virtual_tasks[k] for k in todo]
    items = [(virtual_tasks[k], *plan[k]) for k in todo]
    for i, r in each("virtual objects: poses, features, search", virtual_fn, tasks, items, job,
                     shared, model):
        counts["cached" if r.cached else "computed"] += 1
        cost_rows[todo[i]] = r.row
        on_result(todo[i], r)
    if not cost_rows:
        raise none_usable("virtual")
    return RunResult(tangibles, cost_rows, failed, counts["cached"], counts["computed"])


class RoleFailed(PinchmatchError):
    """A role's only file failed: its own error, as one line."""



