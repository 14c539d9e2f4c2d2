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
import re
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..version import __version__
from ..grasp.features import PinchFeatures, TripodFeatures
from ..mesh.load import LoadedMesh
from ..match.candidates import mass_ratio
from ..match.noticed import contact_offset_mm, criterion_table, p_noticed
from ..match.trust import uncertainty_jnd
from ..grasp.pinches import Pinches
from ..grasp.spread import other_order
from ..grasp.tripod_rules import FINGERS, Tripods
from ..mesh.properties import ObjectProperties

SCHEMA_POSES = "pinchmatch.poses/1"
SCHEMA_FEATURES = "pinchmatch.features/1"


def json_number(x, digits: int = 4):
    """A float for JSON: rounded, ``None`` for NaN or inf."""
    x = float(x)
    return round(x, digits) + 0.0 if math.isfinite(x) else None  # + 0.0: no -0.0


def json_vector(v, digits: int = 4) -> list:
    """A vector (any shape, flattened) for JSON, each component as :func:`json_number`."""
    return [json_number(x, digits) for x in np.asarray(v, dtype=float).ravel()]


def object_section(loaded: LoadedMesh, props: ObjectProperties, *, ray_engine: str) -> dict:
    """Properties of one object, for every document that names it."""
    mesh = loaded.mesh
    return {
        "file": loaded.path,
        "units_in": loaded.units_in,
        "up": loaded.up_label,
        "up_vector": json_vector(loaded.up, 6),
        "faces": int(len(mesh.faces)),
        "vertices": int(len(mesh.vertices)),
        "watertight": loaded.watertight,
        "repairs": list(loaded.repairs),
        "warnings": list(loaded.warnings),
        "bounds_mm": [json_vector(props.bounds_mm[0]), json_vector(props.bounds_mm[1])],
        "extent_mm": json_vector(props.bounds_mm[1] - props.bounds_mm[0]),
        "volume_mm3": json_number(props.volume_mm3, 2) if props.volume_mm3 is not None else None,
        "area_mm2": json_number(props.area_mm2, 2),
        "com_mm": json_vector(props.com_mm),
        "com_source": props.com_source,
        "principal_axis": json_vector(props.principal_axis, 6),
        "axis_source": props.axis_source,
        "variances_mm2": json_vector(props.variances_mm2, 3),
        "ray_engine": ray_engine,
    }


def pose_records(pinches: Pinches, features: PinchFeatures) -> list[dict]:
    """One JSON record per pinch: contacts, normals and the seven features (per tripod:
    :func:`tripod_records`)."""
    if isinstance(pinches, Tripods):
        return tripod_records(pinches, features)
    records = []
    for i in range(len(pinches)):
        patches = _patch_records(pinches, features, i)
        records.append(
            {
                "index": i,
                "p1_mm": json_vector(pinches.points[i, 0]),
                "p2_mm": json_vector(pinches.points[i, 1]),
                "n1": json_vector(pinches.normals[i, 0], 6),
                "n2": json_vector(pinches.normals[i, 1], 6),
                "face_index": [int(f) for f in pinches.face_index[i]],
                "width_mm": json_number(features.width_mm[i]),
                "com_distance_mm": json_number(features.com_distance_mm[i]),
                "tilt_deg": json_number(features.tilt_deg[i], 3),
                "approach": json_vector(pinches.approach[i], 6),
                "approach_clearance_mm": json_number(pinches.approach_clearance_mm[i], 3),
                "patches": patches,
                "feasible": bool(pinches.feasible[i]),
                "broken_rules": pinches.broken_rules(i),
            }
        )
    return records


def _patch_records(grasps: Pinches, features: PinchFeatures, i: int) -> list[dict]:
    """Grasp i's contact patches, one record per contact."""
    return [
        {
            "normal_angle_deg": json_number(features.normal_angle_deg[i, k], 3),
            "curvature_axis_angle_deg": json_number(features.curvature_axis_angle_deg[i, k], 3),
            "kappa_max_per_m": json_number(features.kappa_max_per_m[i, k], 3),
            "kappa_min_per_m": json_number(features.kappa_min_per_m[i, k], 3),
            "kappa_max_direction": json_vector(grasps.dir_max[i, k], 6),
        }
        for k in range(grasps.points.shape[1])
    ]


def tripod_records(tripods: Tripods, features: TripodFeatures) -> list[dict]:
    """One JSON record per tripod: ``contacts_mm`` and ``normals`` (thumb, index, middle), the
    grasp's features and a patch per contact (docs/output-format.md)."""
    return [{
        "index": i,
        "fingers": list(FINGERS),
        "contacts_mm": [json_vector(p) for p in tripods.points[i]],
        "normals": [json_vector(n, 6) for n in tripods.normals[i]],
        "face_index": [int(f) for f in tripods.face_index[i]],
        "aperture_mm": json_number(features.width_mm[i]),
        "spacing_mm": json_number(features.spacing_mm[i]),
        "com_distance_mm": json_number(features.com_distance_mm[i]),
        "tilt_deg": json_number(features.tilt_deg[i], 3),
        "lever_arm_mm": json_number(features.lever_arm_mm[i]),
        "approach": json_vector(tripods.approach[i], 6),
        "approach_clearance_mm": json_number(tripods.approach_clearance_mm[i], 3),
        "patches": _patch_records(tripods, features, i),
        "feasible": bool(tripods.feasible[i]),
        "broken_rules": tripods.broken_rules(i),
    } for i in range(len(tripods))]


def record_contacts(pose: dict) -> list:
    """The contacts of a pose record (mm, its file's frame): a tripod's ``contacts_mm``, a pinch's
    ``p1_mm`` and ``p2_mm``."""
    return pose["contacts_mm"] if "contacts_mm" in pose else [pose["p1_mm"], pose["p2_mm"]]


def poses_document(loaded, props, settings: dict, pinches, features, *, ray_engine: str) -> dict:
    return {
        "schema": SCHEMA_POSES,
        "version": __version__,
        "settings": settings,
        "object": object_section(loaded, props, ray_engine=ray_engine),
        "grasp": "tripod" if isinstance(pinches, Tripods) else "pinch",
        "rejected_candidates": {rule: int(pinches.rejected.get(rule, 0)) for rule in pinches.rules},
        "pose_count": len(pinches),
        "poses": pose_records(pinches, features),
    }


def features_document(loaded, props, settings: dict, pinches, features, *, given,
                      ray_engine: str) -> dict:
    record = pose_records(pinches, features)[0]
    for k, point in enumerate(given, start=1):
        record[f"given_p{k}_mm"] = json_vector(point)
    record["snap_distance_mm"] = json_vector(pinches.snap_distance_mm[0])
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
    + [f"approach_{c}" for c in "xyz"] + ["approach_clearance_mm"]
    + [
        f"patch{k}_{name}"
        for k in (1, 2)
        for name in ("normal_angle_deg", "curvature_axis_angle_deg", "kappa_max_per_m",
                     "kappa_min_per_m")
    ]
)


TRIPOD_CSV_COLUMNS = (
    ["index", "feasible"]
    + [f"{f}_{c}_mm" for f in FINGERS for c in "xyz"]
    + [f"{f}_n{c}" for f in FINGERS for c in "xyz"]
    + ["aperture_mm", "spacing_mm", "com_distance_mm", "tilt_deg", "lever_arm_mm"]
    + [f"approach_{c}" for c in "xyz"] + ["approach_clearance_mm"]
    + [f"{f}_{name}" for f in FINGERS
       for name in ("normal_angle_deg", "curvature_axis_angle_deg", "kappa_max_per_m",
                    "kappa_min_per_m")]
)


def poses_csv(document: dict) -> str:
    """The poses of a poses document as CSV, one row per pose (units in the header)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    tripods = document.get("grasp") == "tripod"
    writer.writerow(TRIPOD_CSV_COLUMNS if tripods else CSV_COLUMNS)
    for pose in document["poses"]:
        row = [pose["index"], int(pose["feasible"])]
        if tripods:
            row += sum(pose["contacts_mm"], []) + sum(pose["normals"], [])
            row += [pose[k] for k in ("aperture_mm", "spacing_mm", "com_distance_mm", "tilt_deg",
                                      "lever_arm_mm")]
        else:
            row += pose["p1_mm"] + pose["p2_mm"] + pose["n1"] + pose["n2"]
            row += [pose["width_mm"], pose["com_distance_mm"], pose["tilt_deg"]]
        row += pose["approach"] + [pose["approach_clearance_mm"]]
        for patch in pose["patches"]:
            row += [patch["normal_angle_deg"], patch["curvature_axis_angle_deg"],
                    patch["kappa_max_per_m"], patch["kappa_min_per_m"]]
        writer.writerow(["" if v is None else v for v in row])
    return out.getvalue()


def to_json(document: dict) -> str:
    return json.dumps(document, indent=1, allow_nan=False) + "\n"


SCHEMA_MATCHES = "pinchmatch.matches/1"
#: a placement is ``noticeable`` when its difference is noticed at least this often (p_noticed)
NOTICED_LEVEL = 0.5
SCHEMA_STUDY = "pinchmatch.study/1"
#: ``--format jsonl``: a header line, one line per virtual object, failed files, an end line
SCHEMA_MATCH_LINES = "pinchmatch.matches.jsonl/1"

#: how transforms are to be read, stated in every matches document
FRAME_NOTE = (
    "transform_virtual_to_tangible maps points of the virtual object, in its file's frame scaled "
    "to mm, "
    "into the tangible's file frame in mm: x_t = R x_v + t; row-major 4x4, right-handed, det +1. "
    "position_mm is t; quaternion_xyzw is R as a unit quaternion [x, y, z, w]."
)


def _candidate_record(candidates, i: int, *, swapped: bool = False) -> dict:
    """A candidate pose as a record; with ``swapped`` its contacts are given in the other order."""
    one = candidates.subset([i])
    record = pose_records(one.pinches, one.features)[0]
    record.update(_index(candidates, i))
    if swapped and "contacts_mm" in record:  # a tripod: index and middle change places
        other = other_order(3)
        for key in ("contacts_mm", "normals", "face_index", "patches"):
            record[key] = [record[key][k] for k in other]
    elif swapped:
        record["p1_mm"], record["p2_mm"] = record["p2_mm"], record["p1_mm"]
        record["n1"], record["n2"] = record["n2"], record["n1"]
        record["face_index"] = record["face_index"][::-1]
        record["patches"] = record["patches"][::-1]
    record["finger_order_swapped"] = bool(swapped)
    return record


def _index(candidates, i: int) -> dict:
    """A pose's place in its object's sampled (or given) list, and whether refinement found it
    instead (then it has no place: ``index`` is null)."""
    refined = bool(candidates.index[i] < 0)
    return {"index": None if refined else int(candidates.index[i]), "refined": refined}


def _rigid(transform: np.ndarray) -> dict:
    return {
        "transform_virtual_to_tangible": [json_vector(row, 6) for row in transform],
        "position_mm": json_vector(transform[:3, 3]),
        "quaternion_xyzw": json_vector(Rotation.from_matrix(transform[:3, :3]).as_quat(), 6),
    }


def _choice_record(scene, vm, choice, *, full: bool) -> dict:
    tangibles, V = scene.objects(vm)
    T = tangibles[choice.tangible]
    up_t = T.obj.loaded.up
    chance = choice.p_noticed if choice.p_noticed is not None else p_noticed(T, V, choice,
                                                                             scene.model)
    record = {
        "tangible": T.name,
        "cost": json_number(choice.cost, 6),
        "p_noticed": json_number(chance, 4),
        "noticeable": bool(chance >= NOTICED_LEVEL),
        "tangible_pose": _candidate_record(T, choice.t_pose) if full
        else _contacts(T, choice.t_pose),
        "virtual_pose": (_candidate_record(V, choice.v_pose, swapped=choice.swapped) if full
                         else _contacts(V, choice.v_pose, swapped=choice.swapped)),
        **_rigid(choice.transform),
        "flipped": choice.flipped,
        "up_turn_deg": json_number(up_turn_deg(choice.placement, V.obj.loaded.up, up_t), 2),
        "contact_offset_mm": json_number(contact_offset_mm(T, V, choice)),
        "mass_ratio": json_number(mass_ratio(T, V), 6),
        "mass_mismatch_mm": json_vector(choice.mass_delta_mm),
        "mass_mismatch_vertical_mm": json_number(float(choice.mass_delta_mm @ up_t)),
        "rest_gap_mm": None if choice.rest_gap_mm is None else json_number(choice.rest_gap_mm),
        "approach_elevation_deg": None if choice.approach_elevation_deg is None else json_number(
            choice.approach_elevation_deg, 2),
        "approach_azimuth_deg": None if choice.approach_azimuth_deg is None else json_number(
            choice.approach_azimuth_deg, 2),
        "scan_uncertainty_jnd": json_number(uncertainty_jnd(T, [choice.t_pose], scene.model)[0],
                                            4),
    }
    return record


def up_turn_deg(transform: np.ndarray, up_virtual: np.ndarray, up_tangible: np.ndarray) -> float:
    """How far the placement turns the virtual object from upright: the angle (deg) between its up
    direction, registered, and the tangible's up. ``flipped`` is this beyond 90°."""
    seen = np.asarray(transform)[:3, :3] @ np.asarray(up_virtual, dtype=np.float64)
    return float(np.degrees(np.arccos(np.clip(seen @ np.asarray(up_tangible, dtype=np.float64),
                                              -1.0, 1.0))))


def _contacts(candidates, i: int, *, swapped: bool = False) -> dict:
    p, n = candidates.pinches.points[i], candidates.pinches.normals[i]
    if swapped:
        p, n = p[other_order(len(p))], n[other_order(len(p))]
    if len(p) > 2:
        return {**_index(candidates, i), "contacts_mm": [json_vector(c) for c in p],
                "normals": [json_vector(c, 6) for c in n],
                "approach": json_vector(candidates.pinches.approach[i], 6),
                "aperture_mm": json_number(float(np.linalg.norm(p[1:].mean(axis=0) - p[0]))),
                "finger_order_swapped": bool(swapped)}
    return {**_index(candidates, i), "p1_mm": json_vector(p[0]), "p2_mm": json_vector(p[1]),
            "n1": json_vector(n[0], 6), "n2": json_vector(n[1], 6),
            "approach": json_vector(candidates.pinches.approach[i], 6),
            "finger_order_swapped": bool(swapped)}


def _landing_record(landing) -> dict | None:
    """A match's landing tolerance (:class:`pinchmatch.match.landing.Landing`), costs to 6
    digits."""
    if landing is None:
        return None
    record = landing.as_dict()
    for key in ("cost_nominal", "cost_mean", "cost_worst"):
        record[key] = json_number(record[key], 6)
    record["p_noticed_worst"] = json_number(record["p_noticed_worst"], 4)
    return record


def _reference_record(ref, model) -> dict:
    if ref is None:
        return None
    if ref.pinches is None:
        return {"cost": None, "reason": ref.reason}
    record = pose_records(ref.pinches, ref.features)[0]
    return {"cost": json_number(ref.cost, 6), "reason": None, "flipped": ref.flipped,
            "transform_virtual_to_tangible": [json_vector(row, 6) for row in np.eye(4)],
            "virtual_pose": record}


def object_entry(candidates, *, dump_poses: bool = False) -> dict:
    """One object of a matches document; with ``dump_poses``, every feasible pose as a record."""
    obj = candidates.obj
    spec = obj.spec
    entry = {"name": candidates.name,
             "node": obj.loaded.node, "node_path": spec.node_path if spec is not None else None,
             "manifest": spec.manifest if spec is not None else None, "mass_g": obj.mass_g,
             "regions": obj.context.regions.as_dict(),
             "support": None if obj.context.support is None else obj.context.support.as_dict(),
             **object_section(obj.loaded, obj.props, ray_engine=obj.context.ray_engine_name),
             "pose_count": len(candidates), "poses_given": candidates.given,
             "scan": None if spec is None or spec.scale_verified is None and spec.scan_noise_mm
             is None else {"noise_mm": spec.scan_noise_mm, "residual_mm": spec.scan_residual_mm,
                           "scale_verified": spec.scale_verified}}
    if spec is not None and spec.pose is not None:  # where the prop stands in the level (mm, y up)
        entry["pose"] = {"position_mm": [float(c) for c in spec.pose[0]],
                         "quaternion_xyzw": [float(c) for c in spec.pose[1]]}
    if dump_poses:
        entry["poses"] = pose_records(candidates.pinches, candidates.features)
        for record, index in zip(entry["poses"], candidates.index):
            record["index"] = int(index)
    return entry


def match_entry(scene, vm) -> dict:
    """One virtual object's entry in ``matches``."""
    tangibles, V = scene.objects(vm)
    entry = {"virtual": V.name}
    if vm.best is None:
        return entry | {"tangible": None, "cost": None, "reason": vm.reason}
    best = vm.best
    entry.update(_choice_record(scene, vm, best, full=True))
    entry["reason"] = None
    entry["criteria"] = criterion_table(tangibles[best.tangible], V, best, scene.model)
    entry["alternatives"] = [_choice_record(scene, vm, a, full=False) for a in vm.alternatives]
    entry["reference"] = _reference_record(vm.reference, scene.model)
    entry["landing"] = _landing_record(vm.landing)
    entry["equivalent_tangibles"] = [{"tangible": tangibles[t].name, "cost": json_number(c, 6)}
                                     for t, c in (vm.equivalent or [])]
    if vm.redirection is not None:
        entry["redirection"] = vm.redirection
    # keys in a stable, readable order
    order = ["virtual", "tangible", "cost", "p_noticed", "noticeable", "reason", "criteria",
             "tangible_pose", "virtual_pose"]
    return {k: entry[k] for k in order} | {k: v for k, v in entry.items() if k not in order}


def matches_header(settings: dict, tangibles: list[dict]) -> dict:
    """What a matches document says before any virtual object: schema, settings, the grasp, frames,
    tangibles."""
    return {"schema": SCHEMA_MATCHES, "version": __version__, "settings": settings,
            "grasp": settings.get("grasp", "pinch"),
            "frames": FRAME_NOTE, "tangibles": tangibles}


def cost_matrix_section(virtual_names: list[str], tangible_names: list[str], values) -> dict:
    return {"rows_virtual": list(virtual_names), "columns_tangible": list(tangible_names),
            "values": [[json_number(x, 6) for x in row] for row in values]}


#: the longest scene or figure stem, in bytes of UTF-8: with a suffix for uniqueness (``_12``), the
#: extension and a temporary file's suffix, well within the 255 bytes a file name may take
MAX_STEM_BYTES = 150


def scene_stems(virtual_names: list[str]) -> list[str]:
    """File stems for the virtual objects' scenes and figures, unique by construction.

    The name's stem, with characters that some file systems refuse (``<>:"/\\|?*``, control
    characters) as ``_``; a stem already taken (case-insensitively: macOS and Windows fold case)
    gets ``_2``, ``_3``, ... until it is free, in the order of the names. ``a.obj``, ``a.stl``,
    ``a_2.stl`` give ``a``, ``a_2``, ``a_2_2``. ``matches.json`` records the file of each object's
    scene and figure, so readers never derive them again. A stem is at most ``MAX_STEM_BYTES`` bytes
    of UTF-8, cut on a character boundary: file systems take 255 bytes a name, and the name of an
    object or a level's node may be longer (80 CJK characters are 240 bytes).
    """
    taken: set[str] = set()
    out = []
    for name in virtual_names:
        base = re.sub(r'[<>:"/\\|?*\x00-\x1f]', "_", Path(name).stem).strip(" .") or "object"
        base = base.encode("utf-8")[:MAX_STEM_BYTES].decode("utf-8",
                                                            errors="ignore").strip(" .") or "object"
        stem, k = base, 1
        while stem.lower() in taken:
            k += 1
            stem = f"{base}_{k}"
        taken.add(stem.lower())
        out.append(stem)
    return out


def scene_file(stem: str) -> str:
    """A scene's path inside OUT, as matches.json records it."""
    return f"scenes/{stem}.glb"


def figure_file(stem: str) -> str:
    """A criteria figure's path inside OUT, as matches.json records it."""
    return f"figures/criteria/{stem}.png"


def matches_document(scene, settings: dict, *, failed: list | None = None, dump_poses: bool = False,
                     figures: bool = True) -> dict:
    """The ``pinchmatch match`` result (schema ``pinchmatch.matches/1``, docs/output-format.md);
    each match names its scene's and criteria figure's files (``figures``: whether figures are
    written)."""
    stems = scene_stems([v.name for v in scene.virtuals])
    matches = [match_entry(scene, vm) for vm in scene.matches]
    for stem, m in zip(stems, matches):
        if m.get("tangible") is not None:
            m.update(scene_file=scene_file(stem), figure_file=figure_file(stem) if figures
                     else None)
    return matches_header(settings,
                          [object_entry(c, dump_poses=dump_poses) for c in scene.tangibles]) | {
        "virtuals": [object_entry(c, dump_poses=dump_poses) for c in scene.virtuals],
        "matches": matches,
        "failed": list(failed or []),
        "cost_matrix": cost_matrix_section([v.name for v in scene.virtuals],
                                           [t.name for t in scene.tangibles], scene.cost_matrix),
    }


def matches_from_lines(lines: Iterable[str]) -> dict:
    """The ``matches.json`` document that a ``matches.jsonl`` stream holds (see
    ``SCHEMA_MATCH_LINES``).

    Raises ValueError when the lines are not a whole stream."""
    records = [json.loads(line) for line in lines if line.strip()]
    if (not records or records[0].get("record") != "header"
        or records[0].get("schema") != SCHEMA_MATCH_LINES):
        raise ValueError(f"the first line is not a {SCHEMA_MATCH_LINES} header")
    if records[-1].get("record") != "end":
        raise ValueError("the end line is missing: the stream was cut short")
    header = {k: v for k, v in records[0].items() if k != "record"} | {"schema": SCHEMA_MATCHES}
    matches = [r for r in records if r.get("record") == "match"]
    failed = [{k: v for k, v in r.items() if k != "record"} for r in records if r.get("record")
              == "failed"]
    return header | {
        "virtuals": [r["object"] for r in matches],
        "matches": [r["match"] for r in matches],
        "failed": failed,
        "cost_matrix": {"rows_virtual": [r["match"]["virtual"] for r in matches],
                        "columns_tangible": [t["name"] for t in header["tangibles"]],
                        "values": [r["cost_row"] for r in matches]},
    }


def matches_rows(document: dict, placed_fixed: bool | None = None) -> list[tuple]:
    """The rows of the matches table, header first."""
    fixed = placed_fixed if placed_fixed is not None else any(m.get("redirection")
                                                              for m in document["matches"])
    rows = [("virtual", "tangible", *(("mode",) if fixed else ()), "cost", "p_noticed",
             "nominal/expected/worst", "criteria >= 1 JND", "flipped", "offset_mm", "ref_cost")]
    for m in document["matches"]:
        if m.get("tangible") is None:
            rows.append((m["virtual"], "-", *(("-",) if fixed else ()), "-", "-", "",
                         m.get("reason") or "", "", "", ""))
            continue
        loud = [c for c, v in m["criteria"].items() if v["noticeable"]]
        ref, land = m["reference"], m.get("landing")
        felt = "/".join(f"{land[k]:.3g}"
                        for k in ("cost_nominal", "cost_mean", "cost_worst")) if land else ""
        mode = ((m.get("redirection") or {}).get("mode") or "-",) if fixed else ()
        rows.append((m["virtual"], m["tangible"], *mode, f"{m['cost']:.4g}",
                     f"{m['p_noticed']:.2f}", felt, ",".join(loud) or "none",
                     "F" if m["flipped"] else "", f"{m['contact_offset_mm']:+.2f}",
                     f"{ref['cost']:.4g}" if ref and ref["cost"] is not None else "null"))
    return rows


#: the columns of the matches table a narrow terminal leaves out first (matches.json has them all)
OPTIONAL_COLUMNS = ("offset_mm", "ref_cost", "flipped", "p_noticed", "nominal/expected/worst")


def study_document(study, settings: dict) -> dict:
    return {"schema": SCHEMA_STUDY, "version": __version__, "settings": settings,
            "rows": study.rows}


def study_rows(rows: list) -> list[tuple]:
    """The rows of the study table, header first, narrow enough for 80 columns (see
    :func:`study_legend`; study.json holds every number)."""
    short = {"cylinder": "cyl", "cube": "cube", "cone": "cone"}

    def cell(p):
        if p["height_mm"] is None:
            return "none", "null"
        where = f"{short.get(p['part'], p['part'])} {p['height_mm']:.0f}" + ("F" if p["flipped"]
                                                                             else "")
        return where, "null" if p["cost"] is None else f"{p['cost']:.3g}"

    out = [("part", "VO", "ours", "cost", "paper", "cost", "ref", "cost")]
    for r in rows:
        out.append((r["tangible_part"], str(r["virtual"]), *cell(r["ours"]), *cell(r["paper"]),
                    *cell(r["ref"])))
    return out


def study_legend(rows: list) -> list[str]:
    """What the study table's columns mean, and each virtual object's parts."""
    orders = {}
    for r in rows:
        orders.setdefault(r["virtual"], "/".join(r["virtual_order"]))
    return [
        "VO: the virtual objects, their parts bottom to top: "
        + ", ".join(f"{k} {v}" for k, v in orders.items()),
        "ours, paper, ref: where each placement puts the pinch on the virtual object: its part "
        "(cyl: cylinder) and height in mm; F: turned upside down",
        f"cost: pinchmatch's cost of that placement, {cost_unit({'normalize': 'jnd'})}; the "
        "paper's own cost of each is in study.json",
    ]


def cost_unit(settings: dict) -> str:
    """What a cost is, in a run's normalisation and pooling."""
    if settings.get("normalize", "jnd") == "range":
        scale = "(difference / range of the run)"
        return (f"sum of weight x {scale}^2, the paper's scaling" if settings.get("pooling")
                == "sum" else
                f"probability summation of weight x {scale}^3.5, in range units")
    if settings.get("pooling") == "sum":
        return "sum of weight x (difference / JND)^2 (1: just noticeable)"
    return "the differences in JND pooled by probability summation (1: noticed half of the time)"


def matches_legend(settings: dict) -> list[str]:
    """What the matches table's columns mean, in the run's normalisation."""
    rank = settings.get("rank", "nominal")
    support = settings.get("support")
    landing_mm = settings.get("landing_mm", 5)
    return [f"cost: {cost_unit(settings)}, ranked by the {rank} cost (nominal: the fingers on "
            f"their targets; expected: over where guided fingers land, within {landing_mm:g} mm; "
            "worst: the worst landing); p_noticed: the probability that the ranked difference is "
            "noticed; "
            "criteria >= 1 JND: those noticeable on their own on target; flipped: F where the "
            "placement turns the virtual object upside down"
            + (f"; support {support}: props stand on the plane through their lowest point (posed: "
               "the level's), "
               "a level's nodes on the table under them (else their lowest point), no hand below it"
               if support == "auto" else ""),
            "offset_mm: each virtual fingertip's offset from the prop's contact along the pinch "
            "line; ref_cost: the paper's reference placement (null: its fingers meet nothing on "
            "the virtual object)"]
