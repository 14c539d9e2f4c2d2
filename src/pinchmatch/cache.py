"""On-disk cache of each object's candidate poses and features.

An entry is one ``.npz`` file named by a key: the SHA-256 of the mesh file's bytes (and of the
buffers a ``.gltf`` names), the units and up direction, every sampling and patch setting, the given
poses if any, the pinchmatch version and ``CACHE_FORMAT``. It holds the repaired mesh, the loading
notes, and the feasible candidates' arrays. Matching settings (weights, criteria, normalisation,
top-k, ...) are not in the key: tuning them reuses the entry.

- Writes are atomic (a temporary file in the same folder, then ``os.replace``): a reader sees a whole
  entry or none, and two runs writing the same key write the same bytes.
- An entry that cannot be read, or whose stored key, format or shapes do not match, is a miss: it is
  deleted and computed again. A cache folder that cannot be written only loses the caching.
- A hit rebuilds exactly what a cold run computes (same arrays, bit for bit), so results do not
  depend on the cache.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from . import __version__
from .analysis import ObjectAnalysis, analyze_object
from .features import PinchFeatures
from .load import LoadedMesh, load_mesh
from .match import Candidates, candidate_poses
from .cost import feature_table
from .pinches import ARRAY_FIELDS, PinchSettings, Pinches
from .properties import object_properties
from .surface import SurfaceContext

log = logging.getLogger(__name__)

#: bump when what an entry holds, or how candidates are computed, changes
CACHE_FORMAT = 1
PINCH_ARRAYS = list(ARRAY_FIELDS)
FEATURE_ARRAYS = [f.name for f in dataclasses.fields(PinchFeatures)]


def default_cache_dir() -> Path:
    """``$PINCHMATCH_CACHE_DIR``, else ``$XDG_CACHE_HOME/pinchmatch``, else ``~/.cache/pinchmatch``."""
    if os.environ.get("PINCHMATCH_CACHE_DIR"):
        return Path(os.environ["PINCHMATCH_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "pinchmatch"


def _file_digest(path: Path) -> str:
    """SHA-256 of a mesh file, and for ``.gltf`` of the external buffers and images it names."""
    h = hashlib.sha256()
    data = path.read_bytes()
    h.update(data)
    if path.suffix.lower() == ".gltf":
        try:
            document = json.loads(data)
            uris = [b.get("uri") for b in document.get("buffers", []) + document.get("images", [])]
        except (ValueError, AttributeError, TypeError):
            uris = []  # not JSON: loading will say so
        for uri in uris:
            if uri and not uri.startswith("data:") and (path.parent / uri).is_file():
                h.update((path.parent / uri).read_bytes())
    return h.hexdigest()


@dataclass(frozen=True)
class CacheInfo:
    folder: Path
    entries: int
    size_bytes: int


class FeatureCache:
    """Candidate poses by key, in ``folder`` (created on first write)."""

    def __init__(self, folder: str | os.PathLike | None = None):
        self.folder = Path(folder) if folder is not None else default_cache_dir()
        self.hits = self.misses = 0

    def key(self, path: str | os.PathLike, *, units: str | None, up: str | None, patch_radius_mm: float,
            settings: PinchSettings, given: tuple[np.ndarray, np.ndarray] | None = None) -> str:
        h = hashlib.sha256()
        h.update(_file_digest(Path(path)).encode())
        h.update(json.dumps({"format": CACHE_FORMAT, "version": __version__, "suffix": Path(path).suffix.lower(),
                             "units": units, "up": up, "patch_radius_mm": float(patch_radius_mm),
                             "settings": settings.as_dict()}, sort_keys=True).encode())
        if given is not None:
            for array in given:
                h.update(np.ascontiguousarray(array, dtype=np.float64).tobytes())
        return h.hexdigest()

    def _path(self, key: str) -> Path:
        return self.folder / f"{key}.npz"

    def load(self, key: str, path: str | os.PathLike, *, patch_radius_mm: float) -> Candidates | None:
        """The candidates stored under ``key``, or None (a missing, unreadable or mismatched entry)."""
        entry = self._path(key)
        if not entry.is_file():
            return None
        try:
            with np.load(entry, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                if meta["key"] != key or meta["format"] != CACHE_FORMAT:
                    raise ValueError("the entry belongs to another key or format")
                arrays = {name: z[name] for name in z.files if name != "meta"}
            return _rebuild(meta, arrays, path, patch_radius_mm=patch_radius_mm)
        except Exception as exc:  # any damage makes a miss, never a crash or a wrong result
            log.warning("cache entry %s unusable (%s: %s); computing again", entry.name, type(exc).__name__, exc)
            entry.unlink(missing_ok=True)
            return None

    def store(self, key: str, candidates: Candidates) -> None:
        """Write the entry atomically; a folder that cannot be written is logged, not raised."""
        meta, arrays = to_payload(candidates)
        arrays = {"meta": np.array(json.dumps(meta | {"key": key, "format": CACHE_FORMAT}))} | arrays
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{key[:16]}.", suffix=".tmp", dir=self.folder)
            try:
                with os.fdopen(fd, "wb") as fh:
                    np.savez(fh, **arrays)
                os.replace(tmp, self._path(key))
            finally:
                if os.path.exists(tmp):
                    os.unlink(tmp)
        except OSError as exc:
            log.warning("cannot write the cache in %s (%s); going on without it", self.folder, exc.strerror or exc)

    def info(self) -> CacheInfo:
        entries = list(self.folder.glob("*.npz")) if self.folder.is_dir() else []
        return CacheInfo(self.folder, len(entries), sum(p.stat().st_size for p in entries))

    def clear(self) -> int:
        """Delete every entry (and stray temporary files); return how many entries went."""
        if not self.folder.is_dir():
            return 0
        entries = list(self.folder.glob("*.npz"))
        for p in entries + list(self.folder.glob(".*.tmp")):
            p.unlink(missing_ok=True)
        return len(entries)


def to_payload(candidates: Candidates) -> tuple[dict, dict]:
    """(meta, arrays): what a cache entry holds, plain JSON and numpy arrays; :func:`from_payload`
    makes the same candidates again. Also how parallel workers hand candidates over."""
    loaded = candidates.obj.loaded
    meta = {"version": __version__, "path": str(loaded.path), "units_in": loaded.units_in,
            "up_label": loaded.up_label, "watertight": bool(loaded.watertight), "repairs": list(loaded.repairs),
            "warnings": list(loaded.warnings), "given": bool(candidates.given),
            "patch_radius_mm": candidates.obj.context.patch_radius_mm,
            "rejected": {str(k): int(v) for k, v in candidates.pinches.rejected.items()}}
    arrays = {"vertices": loaded.mesh.vertices, "faces": loaded.mesh.faces, "up": loaded.up,
              "index": candidates.index}
    arrays |= {f"pinches.{name}": getattr(candidates.pinches, name) for name in PINCH_ARRAYS}
    arrays |= {f"features.{name}": getattr(candidates.features, name) for name in FEATURE_ARRAYS}
    return meta, arrays


def from_payload(meta: dict, arrays: dict, path=None, *, patch_radius_mm: float | None = None) -> Candidates:
    """Candidates as a cold run makes them, bit for bit, from :func:`to_payload`'s output."""
    return _rebuild(meta, arrays, meta["path"] if path is None else path,
                    patch_radius_mm=meta["patch_radius_mm"] if patch_radius_mm is None else patch_radius_mm)


def _rebuild(meta: dict, arrays: dict, path, *, patch_radius_mm: float) -> Candidates:
    """Candidates as a cold run makes them, from an entry's arrays."""
    mesh = trimesh.Trimesh(arrays["vertices"], arrays["faces"], process=False)
    loaded = LoadedMesh(mesh=mesh, path=str(path), units_in=meta["units_in"], up_label=meta["up_label"],
                        up=arrays["up"], watertight=meta["watertight"], repairs=meta["repairs"],
                        warnings=meta["warnings"])
    props = object_properties(mesh, up=loaded.up, watertight=loaded.watertight)
    obj = ObjectAnalysis(loaded, props, SurfaceContext(mesh, patch_radius_mm=patch_radius_mm))
    pinches = Pinches(**{name: arrays[f"pinches.{name}"] for name in PINCH_ARRAYS}, rejected=meta["rejected"])
    features = PinchFeatures(**{name: arrays[f"features.{name}"] for name in FEATURE_ARRAYS})
    n = len(pinches)
    if not (len(arrays["index"]) == n and all(len(getattr(features, f)) == n for f in FEATURE_ARRAYS)
            and all(len(arrays[f"pinches.{p}"]) == n for p in PINCH_ARRAYS)):
        raise ValueError("the entry's arrays disagree in length")
    return Candidates(obj, pinches, features, feature_table(features), arrays["index"], meta["given"])


def cached_candidates(path: str | os.PathLike, *, cache: FeatureCache | None, units: str | None = None,
                      up: str | None = None, patch_radius_mm: float = 8.0,
                      settings: PinchSettings = PinchSettings(),
                      given: tuple[np.ndarray, np.ndarray] | None = None, source: str | None = None) -> Candidates:
    """An object's candidate poses: from ``cache`` when it holds them, else computed (and stored)."""
    key = None
    if cache is not None:
        if not Path(path).is_file():
            load_mesh(path, units=units, up=up)  # raises the loader's one-line error for this path
        key = cache.key(path, units=units, up=up, patch_radius_mm=patch_radius_mm, settings=settings, given=given)
        hit = cache.load(key, path, patch_radius_mm=patch_radius_mm)
        if hit is not None:
            cache.hits += 1
            return hit
        cache.misses += 1
    obj = analyze_object(path, units=units, up=up, patch_radius_mm=patch_radius_mm)
    candidates = candidate_poses(obj, settings=settings, given=given, source=source)
    if cache is not None:
        cache.store(key, candidates)
    return candidates
