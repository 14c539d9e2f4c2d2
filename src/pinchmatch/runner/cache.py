"""On-disk cache of each object's candidate poses and features: the first of the two cache
boundaries.

An entry is one ``.npz`` file named by a key: the SHA-256 of the mesh file's bytes (and of the
buffers and images a ``.gltf`` names), the units and up direction and what else in the object's spec
shapes its candidates, the pinch settings' digest (:func:`pinchmatch.options.digest`), the given
poses if any, the code's digest (:func:`pinchmatch.options.code_digest`: every module of the
package, so an upgrade or any edit never reads an old entry) and ``CACHE_FORMAT``. It holds the
repaired mesh, the loading notes, and the feasible candidates' arrays. Matching settings (weights,
criteria, normalisation, top-k, ...) are not in the key: tuning them reuses the entry.

- Writes are atomic (a temporary file in the same folder, then ``os.replace``): a reader sees a
  whole entry or none, and two runs writing the same key write the same bytes.
- An entry that cannot be read, or whose stored key, format or shapes do not match, is a miss
  (:class:`DamagedEntry`): it is deleted and computed again. A cache folder that cannot be written
  only loses the caching. An error of the code itself (not of the file) is raised, never turned into
  a miss.
- Beside an entry, ``<key>.probes.npz`` keeps the pinches checked along given lines on that object
  (the reference pose's, the memo of :func:`pinchmatch.match.reference.line_pinch`), added to as
  runs ask for new lines: part of the object's boundary, a function of the object alone.
- The second boundary, ``<key>.result.npz``, keeps a virtual object's whole result in one run's
  configuration (:mod:`pinchmatch.runner.results`, its key made of the object's, the tangibles', the
  configuration's digest and the code's).
- ``clear`` deletes only what the cache wrote: files named ``<64 hex digits>.npz`` (or
  ``.probes.npz``, ``.result.npz``) whose stored key is their name, and its own temporaries;
  anything else in the folder is left alone.
- A hit rebuilds exactly what a cold run computes (same arrays, bit for bit), so results do not
  depend on the cache.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import os
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from ..options import code_digest, digest
from ..version import __version__
from ..grasp.analysis import ObjectAnalysis, analyze_spec
from ..grasp.features import PinchFeatures, TripodFeatures
from ..grasp.tripod_rules import Tripods
from ..files import AtomicFile
from ..mesh.gltf_check import external_files, gltf_document
from ..mesh.load import LoadedMesh, load_mesh, node_digests
from ..mesh.manifest import ObjectSpec, spec_from_dict, spec_to_dict
from ..match.candidates import Candidates, candidate_poses
from ..match.cost import feature_table
from ..errors import ConfigError, MeshError, OutputError, PinchmatchError
from ..grasp.pinches import ARRAY_FIELDS, PinchSettings, Pinches
from ..mesh.properties import ObjectProperties
from ..mesh.support import support_plane
from ..mesh.surface import SurfaceContext

log = logging.getLogger(__name__)
#: cache folders found unwritable in this process: said once each
_UNWRITABLE: set[str] = set()

#: bump when the layout of an entry changes (what it holds and how it is named)
CACHE_FORMAT = 3
ENTRY_NAME = re.compile(r"^[0-9a-f]{64}(\.probes|\.result)?\.npz$")
TEMP_NAME = re.compile(r"^\.[0-9a-f]{64}(\.probes|\.result)?\.npz\..+\.tmp$")
PROBES = ".probes"
RESULT = ".result"  # a virtual object's whole result (:mod:`pinchmatch.runner.results`)


class DamagedEntry(Exception):
    """A cache file that is not a whole entry of its key: read as a miss, deleted and computed
    again. Raised only while an entry is read, so that an error of the code itself is never taken
    for one."""


class _Fields(dict):
    """An entry's meta or arrays: a missing name is a damaged entry, not a KeyError."""

    def __missing__(self, name):
        raise DamagedEntry(f"the entry lacks {name!r}")


#: what reading a damaged entry can raise; anything else is a bug and is raised
DAMAGED = (DamagedEntry, OSError)


PINCH_ARRAYS = list(ARRAY_FIELDS)
#: the mass properties an entry holds, as arrays and as plain values
PROPS_ARRAYS = ("com_mm", "principal_axis", "variances_mm2", "bounds_mm")
PROPS_VALUES = ("axis_source", "com_source", "volume_mm3", "area_mm2")
FEATURE_ARRAYS = [f.name for f in dataclasses.fields(PinchFeatures)]
TRIPOD_FEATURE_ARRAYS = [f.name for f in dataclasses.fields(TripodFeatures)]


def _feature_arrays(grasps) -> list[str]:
    return TRIPOD_FEATURE_ARRAYS if isinstance(grasps, Tripods) else FEATURE_ARRAYS


def default_cache_dir() -> Path:
    """``$PINCHMATCH_CACHE_DIR``, else ``$XDG_CACHE_HOME/pinchmatch``, else
    ``~/.cache/pinchmatch``."""
    if os.environ.get("PINCHMATCH_CACHE_DIR"):
        return Path(os.environ["PINCHMATCH_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "pinchmatch"


def _file_digest(path: Path) -> str:
    """SHA-256 of a mesh file, and for a .gltf or .glb of every external buffer and image it names,
    found as the loader finds them (URIs percent-decoded, beside the file; a missing one counts as
    missing)."""
    h = hashlib.sha256()
    data = path.read_bytes()
    h.update(data)
    suffix = path.suffix.lower()
    if suffix in (".gltf", ".glb"):
        try:
            document = gltf_document(path, suffix[1:])
        except MeshError:
            return h.hexdigest()  # loading will refuse it
        folder = path.parent.resolve()
        for uri, file in external_files(path, document):
            h.update(len(uri.encode("utf-8")).to_bytes(8, "little") + uri.encode("utf-8"))
            # one outside is refused when loading: never read
            inside = file.resolve().is_relative_to(folder)
            h.update(hashlib.sha256(file.read_bytes()).digest() if inside and file.is_file()
                     else b"missing")
    return h.hexdigest()


#: per level file, the digest of its bytes and of each node
#: (:func:`pinchmatch.mesh.load.node_digests`)
_NODE_DIGESTS: dict[str, tuple[str, dict]] = {}


def _object_digest(spec: ObjectSpec) -> str:
    """What an object's entry depends on of its file: the file's bytes, or for a level's node the
    node's own triangles in world coordinates (editing, adding or removing another node changes
    nothing)."""
    path = Path(spec.path)
    whole = _file_digest(path)
    if spec.node is None:
        return whole
    memo = _NODE_DIGESTS.get(str(path))
    if memo is None or memo[0] != whole:
        try:
            memo = (whole, node_digests(path))
        except PinchmatchError:
            memo = (whole, {})  # loading the node says what is wrong
        _NODE_DIGESTS[str(path)] = memo
    return "node:" + memo[1][spec.node] if spec.node in memo[1] else whole


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
        self.last_key: str | None = None  # the key of the object last loaded or stored

    def key(self, spec: ObjectSpec, *, settings: PinchSettings,
            given: tuple[np.ndarray, np.ndarray] | None = None) -> str:
        """The entry of an object: its file's bytes (and the buffers and images a glTF names; a
        level's node: its own triangles in the world, :func:`_object_digest`), what in its spec
        shapes its candidates (units, up, centre of mass, axis, regions, scene node), the pinch
        settings' digest, the given poses and the code's digest."""
        h = hashlib.sha256()
        h.update(_object_digest(spec).encode())
        h.update(json.dumps({"format": CACHE_FORMAT, "code": code_digest(),
                             "suffix": Path(spec.path).suffix.lower(), "object": spec.shape_key(),
                             "settings": digest(settings)}, sort_keys=True).encode())
        if given is not None:
            for array in given:
                h.update(np.ascontiguousarray(array, dtype=np.float64).tobytes())
        return h.hexdigest()

    def _path(self, key: str) -> Path:
        return self.folder / f"{key}.npz"

    def write_entry(self, path: Path, arrays: dict) -> None:
        """One entry file, atomically; a folder that cannot be written (no permission, a full disk)
        is said once, not raised: the run goes on without caching."""
        try:
            entry = AtomicFile(path, binary=True)
            try:
                np.savez(entry.file, **arrays)
            except BaseException as exc:
                entry.abort()
                if isinstance(exc, OSError):
                    raise entry._error(exc) from None
                raise
            entry.commit()
        except OutputError as exc:
            if str(self.folder) not in _UNWRITABLE:
                reason = str(exc).split("(", 1)[-1].split(")", 1)[0]
                log.warning("cannot write the cache in %s (%s); going on without it", self.folder,
                            reason)
            _UNWRITABLE.add(str(self.folder))

    def load_probes(self, key: str) -> dict:
        """The reference lines' pinches kept beside the key's entry (the memo of
        :func:`pinchmatch.match.reference.line_pinch`), empty without a whole file."""
        path = self._path(key + PROBES)
        probes: dict = {}
        if not path.is_file():
            return probes
        try:
            meta, arrays = read_entry(path)
            if meta["key"] != key + PROBES:
                raise DamagedEntry("the probes belong to another key")
            for name, present in meta["probes"].items():
                probes[name] = Pinches(**{f: arrays[f"{name}.{f}"] for f in PINCH_ARRAYS}) \
                    if present else None
        except DAMAGED as exc:
            log.warning("cache probes %s unusable (%s: %s); computing again", path.name,
                        type(exc).__name__, exc)
            remove_file(path)
            probes.clear()
        return probes

    def store_probes(self, key: str, probes: dict) -> None:
        """Keep ``probes`` beside the key's entry when it holds a line the file lacks."""
        path = self._path(key + PROBES)
        try:
            known = set(read_entry(path, arrays=False)[0]["probes"]) if path.is_file() else set()
        except DAMAGED:
            known = set()
        if set(probes) <= known:
            return
        meta = {"key": key + PROBES, "format": CACHE_FORMAT,
                "probes": {name: p is not None for name, p in sorted(probes.items())}}
        arrays = {f"{name}.{f}": getattr(p, f) for name, p in sorted(probes.items())
                  if p is not None
                  for f in PINCH_ARRAYS}
        self.write_entry(path, {"meta": np.array(json.dumps(meta))} | arrays)

    def load(self, key: str, spec: ObjectSpec, *, patch_radius_mm: float) -> Candidates | None:
        """The candidates stored under ``key``, or None (a missing, unreadable or mismatched
        entry)."""
        entry = self._path(key)
        if not entry.is_file():
            return None
        try:
            meta, arrays = read_entry(entry)
            if meta["key"] != key:
                raise DamagedEntry("the entry belongs to another key")
            _check_arrays(arrays)
        except DAMAGED as exc:  # a damaged file is a miss, never a crash or a wrong result
            log.warning("cache entry %s unusable (%s: %s); computing again", entry.name,
                        type(exc).__name__, exc)
            entry.unlink(missing_ok=True)
            remove_file(self._path(key + PROBES))
            return None
        return _rebuild(meta, arrays, spec, patch_radius_mm=patch_radius_mm)

    def store(self, key: str, candidates: Candidates) -> None:
        """Write the entry atomically; a folder that cannot be written is logged, not raised."""
        meta, arrays = to_payload(candidates)
        self.write_entry(self._path(key),
                         {"meta": np.array(json.dumps(meta | {"key": key, "format": CACHE_FORMAT}))}
                    | arrays)
        remove_file(self._path(key + PROBES))  # a stale file's lines are asked again

    def _check_folder(self) -> bool:
        if self.folder.exists() and not self.folder.is_dir():
            raise ConfigError(f"{self.folder}: a file, not a cache folder; give the folder with "
                              "--cache")
        return self.folder.is_dir()

    def _entries(self) -> list[Path]:
        """The entries this cache wrote: named by a key, a regular file, holding that key."""
        out = []
        for p in sorted(self.folder.iterdir()):
            if not ENTRY_NAME.match(p.name) or p.is_symlink() or not p.is_file():
                continue
            try:
                meta, _ = read_entry(p, arrays=False)
                ours = meta.get("key") == p.name[:-len(".npz")]
            except DAMAGED:
                ours = False  # damaged, or a user's own file named like an entry: left alone
            if ours:
                out.append(p)
        return out

    def info(self) -> CacheInfo:
        entries = self._entries() if self._check_folder() else []
        return CacheInfo(self.folder, sum(not p.name.endswith((PROBES + ".npz", RESULT + ".npz"))
                                           for p in entries),
                         sum(p.stat().st_size for p in entries))

    def clear(self) -> int:
        """Delete every entry this cache wrote, and its temporary files; return how many entries
        went."""
        if not self._check_folder():
            return 0
        entries = self._entries()
        temporaries = [p for p in self.folder.iterdir()
                       if TEMP_NAME.match(p.name) and p.is_file() and not p.is_symlink()]
        for p in entries + temporaries:
            try:
                p.unlink(missing_ok=True)
            except OSError as exc:
                raise OutputError(f"{self.folder}: cannot delete its entries "
                                  f"({exc.strerror or exc}); make the folder "
                                  "writable, or give another with --cache") from None
        return len(entries)


def remove_file(path: Path) -> None:
    """Delete a file of the cache if it is there; a folder that cannot be written keeps it."""
    try:
        path.unlink(missing_ok=True)
    except OSError as exc:
        log.debug("cannot remove %s: %s", path, exc)


def read_entry(entry: Path, *, arrays: bool = True) -> tuple[dict, dict]:
    """(meta, arrays) of an entry file; raises :class:`DamagedEntry` (or OSError, the file
    unreadable) when it is not a whole entry."""
    with open(entry, "rb") as fh:  # closed however numpy fails on a damaged file
        try:
            z = np.load(fh, allow_pickle=False)
            if not isinstance(z, np.lib.npyio.NpzFile):
                raise DamagedEntry("not an .npz archive")
            with z:
                if "meta" not in z.files:
                    raise DamagedEntry("not a pinchmatch cache entry")
                meta = json.loads(str(z["meta"]))
                if not isinstance(meta, dict) or meta.get("format") != CACHE_FORMAT:
                    raise DamagedEntry("an entry of another format")
                return _Fields(meta), _Fields({name: z[name] for name in z.files if name != "meta"}
                                              if arrays else {})
        except (ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
            # numpy's and zipfile's words for damage
            raise DamagedEntry(f"{type(exc).__name__}: {str(exc).split('.', 1)[0]}") from None


def _check_arrays(arrays: dict) -> None:
    """Raise ValueError unless the arrays can make a mesh and candidates (shapes, kinds,
    indices)."""
    vertices, faces = arrays["vertices"], arrays["faces"]
    if (vertices.ndim != 2 or vertices.shape[1] != 3 or vertices.dtype.kind != "f"
        or not np.isfinite(vertices).all()):
        raise DamagedEntry("the stored vertices are not finite (n, 3) floats")
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.dtype.kind not in "iu" or len(faces) == 0 \
            or faces.min() < 0 or faces.max() >= len(vertices):
        raise DamagedEntry("the stored faces do not index the vertices")
    missing = [name for name in [f"pinches.{p}" for p in PINCH_ARRAYS]
               + [f"features.{f}" for f in FEATURE_ARRAYS]
               + [f"props.{p}" for p in PROPS_ARRAYS] if name not in arrays]
    if missing:
        raise DamagedEntry(f"the entry lacks {', '.join(missing)}")


def to_payload(candidates: Candidates) -> tuple[dict, dict]:
    """(meta, arrays): what a cache entry holds, plain JSON and numpy arrays; :func:`from_payload`
    makes the same candidates again. Also how parallel workers hand candidates over."""
    loaded = candidates.obj.loaded
    spec = candidates.obj.spec or ObjectSpec(str(loaded.path))
    meta = {"version": __version__, "spec": spec_to_dict(spec), "units_in": loaded.units_in,
            "up_label": loaded.up_label, "watertight": bool(loaded.watertight),
            "repairs": list(loaded.repairs), "warnings": list(loaded.warnings),
            "given": bool(candidates.given),
            "grasp": "tripod" if isinstance(candidates.pinches, Tripods) else "pinch",
            "patch_radius_mm": candidates.obj.context.patch_radius_mm,
            "rejected": {str(k): int(v) for k, v in candidates.pinches.rejected.items()},
            "props": {name: getattr(candidates.obj.props, name) for name in PROPS_VALUES}}
    arrays = {"vertices": loaded.mesh.vertices, "faces": loaded.mesh.faces, "up": loaded.up,
              "index": candidates.index}
    arrays |= {f"props.{name}": getattr(candidates.obj.props, name) for name in PROPS_ARRAYS}
    arrays |= {f"pinches.{name}": getattr(candidates.pinches, name) for name in PINCH_ARRAYS}
    arrays |= {f"features.{name}": getattr(candidates.features, name)
               for name in _feature_arrays(candidates.pinches)}
    return meta, arrays


def from_payload(meta: dict, arrays: dict, *, patch_radius_mm: float | None = None) -> Candidates:
    """Candidates as a cold run makes them, bit for bit, from :func:`to_payload`'s output."""
    return _rebuild(meta, arrays, spec_from_dict(meta["spec"]),
                    patch_radius_mm=meta["patch_radius_mm"] if patch_radius_mm is None
                    else patch_radius_mm)


def _rebuild(meta: dict, arrays: dict, spec: ObjectSpec, *, patch_radius_mm: float) -> Candidates:
    """Candidates as a cold run makes them, from an entry's arrays, described by ``spec`` (its
    name and mass may differ from the run that stored the entry: they are not in the key)."""
    mesh = trimesh.Trimesh(arrays["vertices"], arrays["faces"], process=False)
    loaded = LoadedMesh(mesh=mesh, path=str(spec.path), units_in=meta["units_in"],
                        up_label=meta["up_label"], up=arrays["up"], watertight=meta["watertight"],
                        repairs=meta["repairs"], warnings=meta["warnings"], node=spec.node)
    props = ObjectProperties(**{name: arrays[f"props.{name}"] for name in PROPS_ARRAYS},
                             **{name: meta["props"][name] for name in PROPS_VALUES})
    context = SurfaceContext(mesh, patch_radius_mm=patch_radius_mm, regions=spec.regions,
                             support=support_plane(spec, mesh.vertices, arrays["up"]))
    obj = ObjectAnalysis(loaded, props, context,
                         spec)
    tripods = meta.get("grasp", "pinch") == "tripod"
    kinds = (Tripods, TripodFeatures, TRIPOD_FEATURE_ARRAYS) if tripods else (Pinches,
                                                                              PinchFeatures,
                                                                              FEATURE_ARRAYS)
    pinches = kinds[0](**{name: arrays[f"pinches.{name}"] for name in PINCH_ARRAYS},
                       rejected=meta["rejected"])
    features = kinds[1](**{name: arrays[f"features.{name}"] for name in kinds[2]})
    n = len(pinches)
    if not (len(arrays["index"]) == n and all(len(getattr(features, f)) == n for f in kinds[2])
            and all(len(arrays[f"pinches.{p}"]) == n for p in PINCH_ARRAYS)):
        raise DamagedEntry("the entry's arrays disagree in length")
    return Candidates(obj, pinches, features, feature_table(features), arrays["index"],
                      meta["given"])


def cached_candidates(path: str | os.PathLike | ObjectSpec, *, cache: FeatureCache | None,
                      units: str | None = None, up: str | None = None,
                      settings: PinchSettings = PinchSettings(),
                      given: tuple[np.ndarray, np.ndarray] | None = None, source: str | None = None,
                      progress=None) -> Candidates:
    """An object's candidate poses: from ``cache`` when it holds them, else computed (and stored).

    ``path`` is a mesh file, read with ``units`` and ``up``, or an object's spec (a manifest entry,
    a level node), whose own units and up come first. The patch radius is the settings' (the
    object is analysed for it); ``progress`` is called with each stage of loading a computed
    object."""
    spec = path if isinstance(path, ObjectSpec) else ObjectSpec(str(path))
    spec = spec.with_defaults(units=units, up=up)
    patch_radius_mm = settings.patch_radius_mm
    key = None
    if cache is not None:
        try:
            if not Path(spec.path).is_file():
                raise FileNotFoundError(spec.path)
            key = cache.key(spec, settings=settings, given=given)
        except OSError:
            # raises the loader's one-line error for this path
            load_mesh(spec.path, units=spec.units, up=spec.up)
            raise
        cache.last_key = key
        hit = cache.load(key, spec, patch_radius_mm=patch_radius_mm)
        if hit is not None:
            cache.hits += 1
            return hit
        cache.misses += 1
    obj = analyze_spec(spec, patch_radius_mm=patch_radius_mm, progress=progress)
    candidates = candidate_poses(obj, settings=settings, given=given, source=source)
    if cache is not None:
        cache.store(key, candidates)
    return candidates
