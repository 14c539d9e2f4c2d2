"""The tasks of a run, one object each: top-level functions with picklable arguments.

1. :func:`candidates_task`: a tangible's candidate poses (from the cache, or computed);
   :func:`load_task` only reads a file (when no tangible could be used, every virtual file is read
   too, so that one run shows every file's problem);
2. :func:`bounds_task`: with ``--normalize range``, a virtual object's feature bounds;
3. :func:`row_task`: with ``--one-to-one``, a virtual object's row of the cost matrix;
4. :func:`served_task` (``pinchmatch select``): a virtual object's row of the served matrix, its
   least cost and whether it is noticeable on every prop of a shelf;
5. :func:`virtual_task`: a virtual object's candidates, its search against every tangible, its
   result entry, glTF scene and criteria figure (:class:`VirtualResult`), or all of these from the
   cache when an earlier run had the same inputs (:mod:`pinchmatch.runner.results`).

A bad file makes a :class:`Failure`, not an exception: the run goes on with the other files.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import PinchmatchError
from ..export.documents import match_entry, object_entry
from ..export.scenes import match_scene_glb
from ..grasp.pinches import PinchSettings
from ..grasp.hand import hand_of
from ..match.candidates import Candidates
from ..match.cost import feature_bounds
from ..config import Config
from ..match.refine import refined_search
from ..match.scene import match_one, match_virtual
from ..match.search import MatchSettings, cost_row
from ..match.steady import moments_key, moments_of, ranks_by_landings
from ..match.targeted import feature_pool
from ..mesh.load import load_mesh
from ..mesh.manifest import ObjectSpec
from .cache import FeatureCache, cached_candidates, to_payload
from .results import VirtualResult, load_result, result_key, store_result
from .worker import report_stage, tangibles


@dataclass(frozen=True)
class Job:
    """What every task of a run needs to know (small, sent with each task)."""

    units: str | None
    up: str | None
    config: Config  # the run's one configuration
    cache_folder: str | None = None  # None: no cache
    dump_poses: bool = False
    scenes: bool = True
    figures: bool = True

    @property
    def settings(self) -> PinchSettings:
        return self.config.pinch

    @property
    def match(self) -> MatchSettings:
        return self.config.match


@dataclass(frozen=True)
class ObjectTask:
    role: str
    path: str
    # (p1_mm, p2_mm) arrays of given pinches, or (contacts,) of tripods (n, 3, 3)
    given: tuple | None = None
    source: str | None = None  # the poses file they came from
    # a manifest entry or a level node (None: the file, with the job's options)
    spec: ObjectSpec | None = None

    @property
    def name(self) -> str:
        """How progress names the object: as the result does (its manifest name, its node, its
        file)."""
        return self.spec.display_name if self.spec is not None else Path(self.path).name

    @property
    def label(self) -> str:
        """How messages name the object: its file, and the scene node for one node of a level."""
        return (f"{self.path}#{self.spec.node}" if self.spec is not None and self.spec.node
                else self.path)


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
class ServedRow:
    """A virtual object's row of the served matrix (:func:`pinchmatch.match.scene.match_one`'s
    ranked row)."""

    name: str
    row: np.ndarray  # (n,) least cost on each prop, inf where none is allowed
    noticeable: np.ndarray  # (n,) bool
    cached: bool


def _candidates(task: ObjectTask, job: Job) -> tuple[Candidates, bool, FeatureCache | None]:
    """The task's candidates, whether they came from the cache, and the cache (None: none used)."""
    cache = FeatureCache(job.cache_folder) if job.cache_folder is not None else None
    c = cached_candidates(task.spec or task.path, cache=cache, units=job.units, up=job.up,
                          settings=job.settings, given=task.given, source=task.source,
                          progress=lambda stage: report_stage(task.name, stage))
    return c, bool(cache is not None and cache.hits), cache


def _per_file(fn: Callable) -> Callable:
    """A task whose item is an ObjectTask (or a tuple starting with one): a bad file makes a
    Failure."""

    @functools.wraps(fn)
    def task(item, *args):
        try:
            return fn(item, *args)
        except PinchmatchError as exc:
            t = item if isinstance(item, ObjectTask) else item[0]
            return Failure(t.role, t.label, exc.cli_message())

    return task


@_per_file
def candidates_task(task: ObjectTask, job: Job) -> Computed | Failure:
    """A tangible's candidates, and what every worker's matches would each make of it, made once
    here, in parallel (:func:`pinchmatch.runner.worker.tangible_of` takes them): where the match
    ranks by the felt cost, its poses' landing moments (:func:`pinchmatch.match.steady.moments_of`);
    where it refines, its feature pool (:func:`pinchmatch.match.targeted.feature_pool`) and its
    surface's distance field (the hand's reach)."""
    c, cached, _ = _candidates(task, job)
    meta, arrays = to_payload(c)
    if ranks_by_landings(job.match):
        key = moments_key(job.match.landing_mm, job.settings)
        mean, var = moments_of(c, job.match.landing_mm, job.settings)
        meta, arrays = meta | {"moments_key": list(key)}, arrays | {"moments.mean": mean,
                                                                    "moments.var": var}
    if job.match.refine and not c.given:
        points, faces, _, _ = feature_pool(c, job.settings)
        field = c.obj.context.distance_field
        meta = meta | {"pool_settings": job.settings,
                       "distance_field": [list(map(float, field.origin_mm)),
                                                                          field.voxel_mm,
                                                                          field.margin_mm]}
        arrays = arrays | {"pool.points": points, "pool.faces": faces,
                           "distance_field": field.distance_mm}
    return Computed(meta, arrays, cached)


@_per_file
def load_task(task: ObjectTask, job: Job) -> None | Failure:
    """Only read the object's file (and node) as the run would: a Failure says what is wrong with
    it."""
    spec = (task.spec or ObjectSpec(task.path)).with_defaults(units=job.units, up=job.up)
    load_mesh(spec.path, units=spec.units, up=spec.up, node=spec.node)
    return None


@_per_file
def bounds_task(task: ObjectTask, job: Job) -> np.ndarray | Failure:
    return feature_bounds(_candidates(task, job)[0].table)


@_per_file
def row_task(task: ObjectTask, job: Job, shared, model) -> np.ndarray | Failure:
    """A virtual object's row of the cost matrix (a one-to-one run's assignment needs every row)."""
    c = _candidates(task, job)[0]
    return cost_row(refined_search(tangibles(shared), c, model, job.match,
                                   pinch_settings=job.settings), 0)


@_per_file
def served_task(item: tuple, job: Job, shared, model) -> ServedRow | Failure:
    """Item: (task, unused, unused), as for :func:`virtual_task`."""
    c, cached, _ = _candidates(item[0], job)
    vm = match_one(tangibles(shared), c, job.config, model=model, details=False)
    return ServedRow(c.name, vm.row, vm.row_noticed, cached)


@_per_file
def virtual_task(item: tuple, job: Job, shared, model) -> VirtualResult | Failure:
    """Item: (task, its entry of :func:`allowed_tangibles` or None, its cost row or None)."""
    task, allowed, row = item
    key = None
    if job.cache_folder is not None:  # the whole result of an earlier run with the same inputs
        try:
            key = result_key(FeatureCache(job.cache_folder), task, job, shared, model, allowed, row)
        except OSError:
            key = None  # the file cannot be read: the candidates' loading says why
        hit = load_result(FeatureCache(job.cache_folder), key) if key is not None else None
        if hit is not None:
            return hit
    c, cached, cache = _candidates(task, job)
    key_c = cache.last_key if cache is not None else None
    probes = cache.load_probes(key_c) if cache is not None else {}
    scene = match_virtual(tangibles(shared), c, model=model, config=job.config, allowed=allowed,
                          probes=probes)
    result = virtual_result(scene, 0, job, cached=cached)
    if cache is not None:
        cache.store_probes(key_c, probes)  # the reference pose's pinch, for the next run
        if key is not None:
            store_result(cache, key, result)
    return result


def virtual_result(scene, k: int, job: Job, *, cached: bool = False) -> VirtualResult:
    """What the output needs of virtual object ``k`` of a matched scene: its entries, its cost row,
    and its glTF scene and criteria figure as bytes (when the job wants them). Every command's
    results reach the output through this and :class:`MatchesSink`."""
    vm = scene.matches[k]
    tangibles_k, virtual = scene.objects(vm)
    match = match_entry(scene, vm)
    glb = png = None
    if vm.best is not None:
        if job.scenes:
            glb = match_scene_glb(tangibles_k[vm.best.tangible], virtual, vm.best,
                                  hand=hand_of(job.settings))
        if job.figures:
            # matplotlib: imported when figures are wanted
            from ..export.figures import criteria_figure, png_bytes

            png = png_bytes(criteria_figure(match))
    return VirtualResult(virtual.name, object_entry(scene.virtuals[k], dump_poses=job.dump_poses),
                         match, scene.cost_matrix[k], glb, png, cached)

