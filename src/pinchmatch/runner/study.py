"""The method paper's user study (Sec. 4.1.4, Table 2), rebuilt in code: ``pinchmatch demo``.

- Tangible: three coaxial 40 mm parts stacked along +Z, bottom to top a
  cylinder Ø40, a cube 40 and a cone frustum Ø60 -> Ø20 (Ø40 at mid-height).
- Tangible poses: three horizontal pinches along X at the mid-height of each
  part (z = 20, 60, 100 mm).
- Virtual objects: the six stacking orders of the parts, VO1 the tangible's
  own order, then in the order of ``itertools.permutations``.
- Candidate virtual poses: 17 horizontal pinches along X at z = 120·k/18 mm,
  k = 1..17 (evenly spaced, ends excluded; the mid-heights 20, 60 and 100 mm
  are among them). Poses that are not feasible (at the junctions of parts a
  finger would rest on an edge) are left out. ``full``: every sampled pose
  as well, so the search only gains.

Each of the 18 rows (tangible part x virtual object) gives three poses on
the virtual object: ``ours`` (the default criteria and normalisation),
``paper`` (``--criteria paper --normalize range``) and ``ref`` (the virtual
object superimposed on the tangible, the paper's Ref).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InternalError
from ..export.documents import json_number, json_vector
from ..files import write_atomic
from ..grasp.analysis import analyze_object
from ..grasp.pinches import PinchSettings
from ..match.candidates import Candidates, candidate_poses, merge_candidates
from ..match.cost import CRITERIA, PAPER_CRITERIA
from ..match.felt import FeltTables, felt_cost
from ..match.reference import line_contacts, reference_cost, reference_pose
from ..match.candidates import extend
from ..match.scene import SceneMatch, match_scene
from ..match.search import Choice, MatchSettings, cost_model, evaluate_pairs
from ..mesh.shapes import stacked_prop

PARTS = ("cylinder", "cube", "cone")
PART_HEIGHT_MM = 40.0
#: every stacking order; the first is the tangible's
ORDERS = tuple(itertools.permutations(PARTS))
CANDIDATE_HEIGHTS_MM = PART_HEIGHT_MM * 3 * np.arange(1, 18) / 18.0
TANGIBLE_HEIGHTS_MM = PART_HEIGHT_MM * (np.arange(3) + 0.5)
#: a study tripod's fingers: on lines this far apart across the stack's axis (contacts on the cube's
#: face 20 mm apart, two 16 mm pads side by side)
TRIPOD_SPACING_MM = 20.0


def part_at(order: tuple, height_mm: float) -> str:
    """The part of a stack at a height; ``"cylinder|cube"`` on a junction (within 0.5 mm)."""
    level = height_mm / PART_HEIGHT_MM
    nearest = round(level)
    if 0 < nearest < len(order) and abs(level - nearest) * PART_HEIGHT_MM < 0.5:
        return f"{order[nearest - 1]}|{order[nearest]}"
    return order[int(np.clip(np.floor(level), 0, len(order) - 1))]


def horizontal_poses(obj, heights_mm: np.ndarray, grasp: str = "pinch") -> tuple:
    """Pinches along X through the Z axis at the given heights, where the fingers meet the surface:
    (p1, p2) arrays. Tripods (``grasp``): the thumb where the pinch's first finger is, the index and
    the middle finger on lines along X ``TRIPOD_SPACING_MM`` apart across the axis, from the other
    side: a tuple of their (n, 3, 3) contacts."""
    lines = [np.zeros(2)] if grasp == "pinch" else [np.zeros(2), [-TRIPOD_SPACING_MM / 2,
                                                                  0], [TRIPOD_SPACING_MM / 2, 0]]
    found = []
    for z in heights_mm:
        row = []
        for y, _ in lines:
            contacts = line_contacts(obj, np.array([0.0, y, z]), np.array([1.0, 0.0, 0.0]))
            if contacts is None:
                raise InternalError(f"the study object has no surface at y = {y}, z = {z} mm")
            row.append(contacts)
        found.append(row[0] if grasp == "pinch" else [row[0][0], row[1][1], row[2][1]])
    found = np.array(found)
    return (found[:, 0], found[:, 1]) if grasp == "pinch" else (found,)


@dataclass
class Study:
    tangible: Candidates
    virtuals: list
    rows: list
    scene: SceneMatch


def study_mesh_names() -> list[str]:
    """The file names of the six virtual objects, then the tangible, as :func:`write_study_meshes`
    writes them."""
    return [f"vo{j}_{'_'.join(order)}.stl" for j, order in enumerate(ORDERS, start=1)] \
        + ["tangible_cylinder_cube_cone.stl"]


def write_study_meshes(folder: Path, *, sections: int = 96) -> tuple[Path, list[Path]]:
    """Write the tangible and the six virtual objects as STL (mm) into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    *names, tangible = [folder / name for name in study_mesh_names()]
    for path, order in zip(names, ORDERS):
        write_atomic(path, stacked_prop(order, sections=sections).export(file_type="stl"))
    write_atomic(tangible, stacked_prop(ORDERS[0], sections=sections).export(file_type="stl"))
    return tangible, names


def _expected(tangible: Candidates, t_pose: int, virtual: Candidates, v_pose: int, *, cost, terms,
              swapped, transform, model, tables: FeltTables) -> float:
    """The expected cost over the landings (:mod:`pinchmatch.match.felt`) of a rated pose pair."""
    choice = Choice(0, 0, int(t_pose), int(v_pose), float(cost), np.asarray(terms), bool(swapped),
                    np.asarray(transform), False, np.zeros(3))
    return felt_cost(tangible, virtual, choice, model, tables).expected


def _contacts_fields(prefix: str, points, fingers: int) -> dict:
    """A pose's contacts (``fingers`` of them, or None: no pose) as the study's records name them:
    ``contacts_mm`` for every grasp, and a pinch's ``p1_mm`` and ``p2_mm``, each under ``prefix``;
    null where there is no pose."""
    vectors = [None] * fingers if points is None else [json_vector(p) for p in points]
    out = {f"{prefix}contacts_mm": None if points is None else vectors}
    if fingers == 2:
        out |= {f"{prefix}p1_mm": vectors[0], f"{prefix}p2_mm": vectors[1]}
    return out


def _pose_entry(order, candidates: Candidates, v_pose: int | None, *, points=None, flipped, cost,
                cost_paper, reason=None, transform=None, swapped=False, terms=None,
                cost_expected=None) -> dict:
    """One virtual pose of a row: candidate ``v_pose``, or the contacts ``points`` (neither: no
    pose, the reference's fingers met nothing). ``transform`` (virtual -> tangible, mm), ``swapped``
    (the virtual p1 lies on the tangible's p2) and ``terms`` (each criterion's contribution in
    JND², under our criteria) describe the pose pair as the headset's study shows and rates it."""
    pts = (points if points is not None else None if v_pose is None
           else candidates.pinches.points[v_pose])
    height = float(pts[:, 2].mean()) if pts is not None else None
    entry = {
        "part": part_at(order, height) if height is not None else None,
        "height_mm": json_number(height, 2) if height is not None else None,
        **_contacts_fields("", pts, candidates.pinches.points.shape[1]),
        "flipped": flipped,
        "cost": json_number(cost) if cost is not None else None,
        "cost_paper": json_number(cost_paper) if cost_paper is not None else None,
        "cost_expected": json_number(cost_expected) if cost_expected is not None else None,
        "reason": reason,
    }
    if transform is not None and terms is not None:
        entry["finger_order_swapped"] = bool(swapped)
        entry["transform_virtual_to_tangible"] = [json_vector(row, 6) for row in transform]
        entry["criteria_jnd"] = {c: json_number(np.sqrt(max(t, 0.0)))
                                 for c, t in zip(CRITERIA, terms)}
    return entry


def run_study(folder: Path, *, full: bool = False, settings: PinchSettings = PinchSettings(),
              match_settings: MatchSettings = MatchSettings(), progress=None) -> Study:
    """Build the study objects in ``folder`` and compute its 18 rows and the scene's matches."""
    say = progress or (lambda message: None)
    tangible_path, virtual_paths = write_study_meshes(folder)
    t_obj = analyze_object(tangible_path, units="mm", up="z")
    tangible = candidate_poses(t_obj, settings=settings,
                               given=horizontal_poses(t_obj, TANGIBLE_HEIGHTS_MM, settings.grasp),
                               source="study tangible poses")
    if len(tangible) != 3:
        raise InternalError("a study tangible pose is not feasible")
    virtuals = []
    for j, path in enumerate(virtual_paths, start=1):
        say(f"VO{j}: {' / '.join(ORDERS[j - 1])}")
        obj = analyze_object(path, units="mm", up="z")
        candidates = candidate_poses(obj, settings=settings,
                                     given=horizontal_poses(obj, CANDIDATE_HEIGHTS_MM,
                                                            settings.grasp),
                                     source=f"VO{j} candidate poses")
        if full:
            candidates = merge_candidates(candidate_poses(obj, settings=settings), candidates)
        virtuals.append(candidates)

    everything = [tangible] + virtuals
    ours_model = cost_model(match_settings, everything)
    paper_settings = MatchSettings(weights=dict.fromkeys(PAPER_CRITERIA, 1.0),
                                   criteria=PAPER_CRITERIA,
                                   # the paper's algorithm, exactly
                                   normalize="range", pooling="sum")
    paper_model = cost_model(paper_settings, everything)

    rows = []
    for i, t_part in enumerate(PARTS):
        for j, V in enumerate(virtuals):
            order = ORDERS[j]
            it, iv = np.full(len(V), i), np.arange(len(V))
            ours = evaluate_pairs(tangible, V, it, iv, model=ours_model)
            paper = evaluate_pairs(tangible, V, it, iv, model=paper_model)
            k_ours, k_paper = int(np.argmin(ours.cost)), int(np.argmin(paper.cost))
            ref = reference_pose(tangible, i, V, ours_model, settings=settings)
            # the paper's pose in the paper's finger order, judged by our criteria
            paper_pair = evaluate_pairs(tangible, V, it[:1], iv[k_paper:k_paper + 1],
                                        model=ours_model, swapped=bool(paper.swapped[k_paper]))
            tables = FeltTables(match_settings.landing_mm, settings)
            felt = {name: _expected(tangible, i, V, k, cost=r.cost[n], terms=r.terms[n],
                                    swapped=r.swapped[n], transform=r.transform[n],
                                    model=ours_model, tables=tables)
                    for name, r, k, n in (("ours", ours, k_ours, k_ours),
                                          ("paper", paper_pair, k_paper, 0))}
            if ref.pinches is not None:
                # the reference's virtual pinch, placed as the files place it
                with_ref = extend(V, ref.pinches)
                felt["ref"] = _expected(tangible, i, with_ref, len(V), cost=ref.cost,
                                        terms=ref.terms, swapped=False, transform=np.eye(4),
                                        model=ours_model, tables=tables)
            rows.append({
                "tangible_part": t_part,
                "tangible_height_mm": float(TANGIBLE_HEIGHTS_MM[i]),
                "virtual": j + 1,
                "virtual_order": list(order),
                **_contacts_fields("tangible_", tangible.pinches.points[i],
                                   tangible.pinches.points.shape[1]),
                "ours": _pose_entry(order, V, k_ours, flipped=bool(ours.flipped[k_ours]),
                                    cost=ours.cost[k_ours], cost_paper=paper.cost[k_ours],
                                    transform=ours.transform[k_ours], swapped=ours.swapped[k_ours],
                                    terms=ours.terms[k_ours], cost_expected=felt["ours"]),
                "paper": _pose_entry(order, V, k_paper, flipped=bool(paper.flipped[k_paper]),
                                     cost=paper_pair.cost[0], cost_paper=paper.cost[k_paper],
                                     transform=paper_pair.transform[0],
                                     swapped=paper_pair.swapped[0], terms=paper_pair.terms[0],
                                     cost_expected=felt["paper"]),
                "ref": _pose_entry(order, V, None,
                                   points=ref.pinches.points[0] if ref.pinches is not None
                                   else None, flipped=ref.flipped,
                                   cost=ref.cost,
                                   cost_paper=reference_cost(tangible, i, V, ref, paper_model),
                                   reason=ref.reason, transform=np.eye(4), terms=ref.terms,
                                   cost_expected=felt.get("ref")),
            })
    say("matching the scene")
    scene = match_scene([tangible], virtuals, settings=match_settings, model=ours_model)
    return Study(tangible, virtuals, rows, scene)
