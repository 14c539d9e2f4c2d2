"""The poses refinement adds, kept in the feature cache under a key of their own.

Refinement (:mod:`pinchmatch.match.refine`) adds, for one virtual object against a run's tangibles,
feasible poses on both. They depend on the virtual object's candidates (its cache entry's key), the
tangibles (the digest of their payloads), the cost model, ``--keep-upright``, the pinch settings and
the code; not on ``--top-k``, ``--distinct-mm``, the landing options or ``--one-to-one``'s assignment.
So a run that changes only those, and the two tasks of a ``--one-to-one`` run (its cost row, then its
result), refine once: ``<key>.refined.npz`` holds the added poses' arrays, per object, and a hit
rebuilds the same candidates, bit for bit (features are recomputed from the stored pinches, as
refinement computes them). A damaged file is a miss; a folder that cannot be written only loses the
caching (:meth:`FeatureCache.write_entry`).
"""

from __future__ import annotations

import hashlib
import json
import logging

import numpy as np

from ..grasp.pinches import Pinches, PinchSettings
from ..match.candidates import Candidates
from ..match.refine import extend, refined_search
from ..match.search import Search
from ..version import __version__
from .cache import (ALGORITHM_DIGEST, CACHE_FORMAT, DAMAGED, PINCH_ARRAYS, REFINED, FeatureCache, read_entry,
                    remove_file, source_digest)
from .results import plain

log = logging.getLogger(__name__)

#: modules whose code shapes the added poses (besides ALGORITHM_DIGEST's)
REFINED_MODULES = ("match/refine", "match/search", "match/register", "match/cost", "match/redirect",
                   "runner/refined")
#: the match settings refinement depends on
REFINE_SETTINGS = ("criteria", "weights", "normalize", "pooling", "keep_upright", "refine", "placement",
                   "hand_start_mm", "redirect_threshold_deg", "max_redirect_deg", "axis_threshold_deg")


REFINED_DIGEST = source_digest(REFINED_MODULES, ALGORITHM_DIGEST)


def refined_key(candidate_key: str, tangibles_token: str, model, match, pinch: PinchSettings) -> str:
    """The key of the poses refinement adds for the virtual object of cache entry ``candidate_key``."""
    described = {"format": CACHE_FORMAT, "version": __version__, "code": REFINED_DIGEST,
                 "candidates": candidate_key, "tangibles": tangibles_token, "model": plain(model),
                 "match": {name: plain(getattr(match, name)) for name in REFINE_SETTINGS}, "pinch": plain(pinch)}
    return hashlib.sha256(json.dumps(described, sort_keys=True, default=repr).encode()).hexdigest()


def cached_refined_search(cache: FeatureCache | None, key: str | None, tangibles: list[Candidates],
                          virtual: Candidates, model, match, *, pinch_settings: PinchSettings) -> Search:
    """:func:`pinchmatch.match.refine.refined_search`, its added poses read from ``cache`` under ``key``
    when an earlier run stored them, else found and stored."""
    if cache is None or key is None or not match.refine:
        return refined_search(tangibles, virtual, model, match, pinch_settings=pinch_settings)
    path = cache.folder / f"{key}{REFINED}.npz"
    if path.is_file():
        try:
            meta, arrays = read_entry(path)
            if meta["key"] != key + REFINED or meta["tangibles"] != len(tangibles):
                raise ValueError("the entry belongs to another key")
            grown = [_grown(base, arrays, f"tangible{t}") for t, base in enumerate(tangibles)]
            return Search(grown, [_grown(virtual, arrays, "virtual")], model, match)
        except DAMAGED as exc:
            log.warning("cache refinement %s unusable (%s: %s); refining again", path.name, type(exc).__name__, exc)
            remove_file(path)
    search = refined_search(tangibles, virtual, model, match, pinch_settings=pinch_settings)
    arrays = {"meta": np.array(json.dumps({"key": key + REFINED, "format": CACHE_FORMAT,
                                           "tangibles": len(tangibles)}))}
    for name, base, grown in [("virtual", virtual, search.virtuals[0])] + [
            (f"tangible{t}", base, g) for t, (base, g) in enumerate(zip(tangibles, search.tangibles))]:
        added = grown.pinches.subset(np.arange(len(base), len(grown)))
        arrays |= {f"{name}.{field}": getattr(added, field) for field in PINCH_ARRAYS}
    cache.write_entry(path, arrays)
    return search


def _grown(base: Candidates, arrays: dict, name: str) -> Candidates:
    """``base`` with the stored poses added (none: ``base`` itself)."""
    pinches = Pinches(**{field: arrays[f"{name}.{field}"] for field in PINCH_ARRAYS}, rejected={})
    if any(len(getattr(pinches, field)) != len(pinches) for field in PINCH_ARRAYS):
        raise ValueError("the stored poses' arrays disagree in length")
    return extend(base, pinches) if len(pinches) else base
