"""Virtual objects' whole results, kept in the cache beside their candidates: the second cache
boundary.

A virtual object's result (its entries in the matches document, its row of the cost matrix, its glTF
scene and criteria figure) is a function of its candidates, the run's tangibles, the cost model, the
run's configuration and the plan of a one-to-one run. A warm run whose inputs are all unchanged
reads it back instead of searching again: the exact search against every tangible is most of what a
warm run would otherwise do.

The key (SHA-256) is made of:

- the object's candidate key (:meth:`FeatureCache.key`) and the rest of its task: the path and label
  it is reported under, its whole spec (name, mass, manifest, pose), where given poses came from;
- the tangibles, by the digest of their payloads (:func:`pinchmatch.runner.worker.payload_token`:
  their meshes, candidates, names, masses and poses);
- the cost model (its ranges under ``--normalize range``), the configuration's digest
  (:meth:`pinchmatch.config.Config.digest`: every field), the plan (allowed tangibles and cost
  row of a one-to-one run), what the run writes (scenes, figures, poses);
- ``RESULT_FORMAT``, the code's digest (:func:`pinchmatch.options.code_digest`) and the ray engine
  this machine has (it is reported).

An entry is ``<key>.result.npz``: the entries as JSON, the row, the scene and figure bytes. It is
written and read as the candidate entries are (atomic, a damaged one is a miss and removed).
"""

from __future__ import annotations

import hashlib
import json
import logging
from dataclasses import dataclass

import numpy as np

from ..mesh.manifest import ObjectSpec, spec_to_dict
from ..mesh.surface import ray_engine_name
from ..options import code_digest, plain
from .cache import (CACHE_FORMAT, DAMAGED, RESULT, DamagedEntry, FeatureCache, read_entry,
                    remove_file)

log = logging.getLogger(__name__)

#: bump when the layout of a result entry changes
RESULT_FORMAT = 1


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


def result_key(cache: FeatureCache, task, job, shared, model, allowed, row) -> str:
    """The key of a virtual object's result in this run (see the module notes). Raises OSError when
    its file cannot be read (the task then reports the loader's error)."""
    spec = task.spec if task.spec is not None else ObjectSpec(str(task.path))
    spec = spec.with_defaults(units=job.units, up=job.up)
    candidate_key = cache.key(spec, settings=job.config.pinch, given=task.given)
    described = {"format": RESULT_FORMAT, "cache_format": CACHE_FORMAT, "code": code_digest(),
                 "candidates": candidate_key, "label": task.label, "path": task.path,
                 "role": task.role, "source": task.source, "spec": spec_to_dict(spec),
                 "tangibles": shared[0], "model": plain(model), "config": job.config.digest(),
                 "writes": {"scenes": job.scenes, "figures": job.figures, "poses": job.dump_poses},
                 "allowed": plain(allowed), "row": plain(row), "rays": ray_engine_name()}
    return hashlib.sha256(json.dumps(described, sort_keys=True, default=repr).encode()).hexdigest()


def load_result(cache: FeatureCache, key: str):
    """The :class:`VirtualResult` stored under ``key`` (marked as cached), or None."""

    path = cache.folder / f"{key}{RESULT}.npz"
    if not path.is_file():
        return None
    try:
        meta, arrays = read_entry(path)
        if meta["key"] != key + RESULT:
            raise DamagedEntry("the entry belongs to another key")
        row = arrays["row"]
        if row.ndim != 1 or row.dtype.kind != "f":
            raise DamagedEntry("the stored cost row is not a row of numbers")
        blobs = {name: arrays[name].tobytes() if meta[name] else None
                 for name in ("scene_glb", "figure_png")}
        return VirtualResult(meta["name"], meta["entry"], meta["match"], row, blobs["scene_glb"],
                             blobs["figure_png"], cached=True)
    except DAMAGED as exc:
        log.warning("cache result %s unusable (%s: %s); searching again", path.name,
                    type(exc).__name__, exc)
        remove_file(path)
        return None


def store_result(cache: FeatureCache, key: str, result) -> None:
    """Keep a virtual object's result under ``key``; a folder that cannot be written is logged, not
    raised."""
    meta = {"key": key + RESULT, "format": CACHE_FORMAT, "name": result.name, "entry": result.entry,
            "match": result.match, "scene_glb": result.scene_glb is not None,
            "figure_png": result.figure_png is not None}
    arrays = {"meta": np.array(json.dumps(meta)), "row": np.asarray(result.row, dtype=np.float64)}
    for name in ("scene_glb", "figure_png"):
        arrays[name] = np.frombuffer(getattr(result, name) or b"", dtype=np.uint8)
    cache.write_entry(cache.folder / f"{key}{RESULT}.npz", arrays)
