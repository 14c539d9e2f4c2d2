"""Result documents (JSON and CSV) and atomic file writing.

Every document carries ``schema``, ``version`` and the settings used; every
numeric field carries its unit in its name. Undefined values are ``null``.
The format is documented in ``docs/output-format.md``.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from . import __version__
from .features import PinchFeatures
from .load import LoadedMesh
from .pinches import RULES, Pinches
from .properties import ObjectProperties

SCHEMA_POSES = "pinchmatch.poses/1"
SCHEMA_FEATURES = "pinchmatch.features/1"


def _num(x, digits: int = 4):
    """A float for JSON: rounded, ``None`` for NaN or inf."""
    x = float(x)
    return round(x, digits) if math.isfinite(x) else None


def _vec(v, digits: int = 4) -> list:
    return [_num(x, digits) for x in np.asarray(v, dtype=float).ravel()]


def object_section(loaded: LoadedMesh, props: ObjectProperties, *, ray_engine: str) -> dict:
    """Properties of one object, for every document that names it."""
    mesh = loaded.mesh
    return {
        "file": loaded.path,
        "units_in": loaded.units_in,
        "up": loaded.up_label,
        "up_vector": _vec(loaded.up, 6),
        "faces": int(len(mesh.faces)),
        "vertices": int(len(mesh.vertices)),
        "watertight": loaded.watertight,
        "repairs": list(loaded.repairs),
        "warnings": list(loaded.warnings),
        "bounds_mm": [_vec(props.bounds_mm[0]), _vec(props.bounds_mm[1])],
        "extent_mm": _vec(props.bounds_mm[1] - props.bounds_mm[0]),
        "volume_mm3": _num(props.volume_mm3, 2) if props.volume_mm3 is not None else None,
        "area_mm2": _num(props.area_mm2, 2),
        "com_mm": _vec(props.com_mm),
        "com_source": props.com_source,
        "principal_axis": _vec(props.principal_axis, 6),
        "axis_source": props.axis_source,
        "variances_mm2": _vec(props.variances_mm2, 3),
        "ray_engine": ray_engine,
    }


def pose_records(pinches: Pinches, features: PinchFeatures) -> list[dict]:
    """One JSON record per pinch: contacts, normals and the seven features."""
    records = []
    for i in range(len(pinches)):
        patches = [
            {
                "normal_angle_deg": _num(features.normal_angle_deg[i, k], 3),
                "curvature_axis_angle_deg": _num(features.curvature_axis_angle_deg[i, k], 3),
                "kappa_max_per_m": _num(features.kappa_max_per_m[i, k], 3),
                "kappa_min_per_m": _num(features.kappa_min_per_m[i, k], 3),
                "kappa_max_direction": _vec(pinches.dir_max[i, k], 6),
            }
            for k in range(2)
        ]
        records.append(
            {
                "index": i,
                "p1_mm": _vec(pinches.points[i, 0]),
                "p2_mm": _vec(pinches.points[i, 1]),
                "n1": _vec(pinches.normals[i, 0], 6),
                "n2": _vec(pinches.normals[i, 1], 6),
                "face_index": [int(f) for f in pinches.face_index[i]],
                "width_mm": _num(features.width_mm[i]),
                "com_distance_mm": _num(features.com_distance_mm[i]),
                "tilt_deg": _num(features.tilt_deg[i], 3),
                "patches": patches,
                "feasible": bool(pinches.feasible[i]),
                "broken_rules": pinches.broken_rules(i),
            }
        )
    return records


def poses_document(loaded, props, settings: dict, pinches, features, *, ray_engine: str) -> dict:
    return {
        "schema": SCHEMA_POSES,
        "version": __version__,
        "settings": settings,
        "object": object_section(loaded, props, ray_engine=ray_engine),
        "rejected_candidates": {rule: int(pinches.rejected.get(rule, 0)) for rule in RULES},
        "pose_count": len(pinches),
        "poses": pose_records(pinches, features),
    }


def features_document(loaded, props, settings: dict, pinches, features, *, given, ray_engine: str) -> dict:
    record = pose_records(pinches, features)[0]
    record["given_p1_mm"] = _vec(given[0])
    record["given_p2_mm"] = _vec(given[1])
    record["snap_distance_mm"] = _vec(pinches.snap_distance_mm[0])
    return {
        "schema": SCHEMA_FEATURES,
        "version": __version__,
        "settings": settings,
        "object": object_section(loaded, props, ray_engine=ray_engine),
        "pose": record,
    }


CSV_COLUMNS = (
    ["index", "feasible"]
    + [f"{p}_{c}_mm" for p in ("p1", "p2") for c in "xyz"]
    + [f"{p}_{c}" for p in ("n1", "n2") for c in "xyz"]
    + ["width_mm", "com_distance_mm", "tilt_deg"]
    + [
        f"patch{k}_{name}"
        for k in (1, 2)
        for name in ("normal_angle_deg", "curvature_axis_angle_deg", "kappa_max_per_m", "kappa_min_per_m")
    ]
)


def poses_csv(document: dict) -> str:
    """The poses of a poses document as CSV, one row per pose (units in the header)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for pose in document["poses"]:
        row = [pose["index"], int(pose["feasible"])]
        row += pose["p1_mm"] + pose["p2_mm"] + pose["n1"] + pose["n2"]
        row += [pose["width_mm"], pose["com_distance_mm"], pose["tilt_deg"]]
        for patch in pose["patches"]:
            row += [patch["normal_angle_deg"], patch["curvature_axis_angle_deg"],
                    patch["kappa_max_per_m"], patch["kappa_min_per_m"]]
        writer.writerow(["" if v is None else v for v in row])
    return out.getvalue()


def to_json(document: dict) -> str:
    return json.dumps(document, indent=1, allow_nan=False) + "\n"


def write_atomic(path: str | os.PathLike, text: str | bytes) -> None:
    """Write ``text`` (or bytes) to ``path`` via a temporary file and ``os.replace``: never half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        if isinstance(text, bytes):
            with os.fdopen(fd, "wb") as fh:
                fh.write(text)
        else:
            with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
                fh.write(text)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the file ordinary permissions
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):  # only when something failed before the replace
            os.unlink(tmp)
