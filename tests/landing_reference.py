"""The exact closing-line reference of the felt cost (:mod:`pinchmatch.match.felt`), for the tests:
the prop's contacts found by closing the fingers along every landing's own line, each pair's
geometry anew (about ten times the time), the landings weighed alike. The model is
:mod:`pinchmatch.match.landing`'s."""

from __future__ import annotations

import numpy as np

from pinchmatch.grasp.features import pinch_features
from pinchmatch.grasp.pinches import PinchSettings, Pinches, patches
from pinchmatch.match.candidates import Candidates, pair_terms
from pinchmatch.match.cost import CRITERIA, CostModel, feature_table
from pinchmatch.match.landing import (LANDING_AXIS_DEG, LANDING_MM, MISS_JND, RING_POINTS, Landing,
                                      disc_offsets)
from scipy.spatial.transform import Rotation
from pinchmatch.match.refine import close_fingers, move_directions
from pinchmatch.match.noticed import criterion_table, p_noticed


def _described(context, points: np.ndarray, faces: np.ndarray, settings: PinchSettings) -> Pinches:
    """Pinches (n, 2) at given surface points, with their patches (no rule is checked)."""
    n = len(points)
    geom = patches(context, points, context.face_normals[faces], settings)
    return Pinches(points=points, normals=geom.normal.reshape(n, 2, 3), face_index=faces,
                   kappa_max_per_m=geom.kappa_max_per_m.reshape(n, 2),
                   kappa_min_per_m=geom.kappa_min_per_m.reshape(n, 2),
                   dir_max=geom.dir_max.reshape(n, 2, 3), feasible=np.ones(n, dtype=bool),
                   broken=np.zeros((n, 7), dtype=bool), snap_distance_mm=np.zeros((n, 2)),
                   approach=np.full((n, 3), np.nan), approach_clearance_mm=np.full(n, np.nan))


def landing_pinches(virtual: Candidates, v_pose: int, swapped: bool, radius_mm: float,
                    axis_deg: float, rings=RING_POINTS) -> np.ndarray:
    """(k, 2, 3) the landings on the virtual object (target first), in the tangible's finger
    order, and (k, 2) their triangles."""
    p = virtual.pinches.points[v_pose]
    f = virtual.pinches.face_index[v_pose]
    if swapped:
        p, f = p[::-1], f[::-1]
    dirs = move_directions(p[None], virtual.obj.props.principal_axis)[0]  # (2, 3)
    offsets = disc_offsets(radius_mm, rings)
    u = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0])
    back = radius_mm * np.tan(np.radians(axis_deg)) + radius_mm + 1.0
    context = virtual.obj.context
    landed, faces = [], []
    for k, toward in ((0, u), (1, -u)):
        moved = p[k] + offsets @ dirs
        contact, face = (close_fingers(context, moved, np.broadcast_to(toward, moved.shape).copy(),
                                       back))
        contact[0], face[0] = p[k], f[k]  # the target itself
        landed.append(contact)
        faces.append(face)
    i, j = np.meshgrid(np.arange(len(offsets)), np.arange(len(offsets)), indexing="ij")
    i, j = i.ravel(), j.ravel()
    ok = (faces[0][i] >= 0) & (faces[1][j] >= 0)
    points = np.stack([landed[0][i], landed[1][j]], axis=1)[ok]
    faces = np.stack([faces[0][i], faces[1][j]], axis=1)[ok]
    axis = points[:, 1] - points[:, 0]
    cos = axis @ u / np.maximum(np.linalg.norm(axis, axis=1), 1e-300)
    keep = cos >= np.cos(np.radians(axis_deg)) - 1e-12
    return points[keep], faces[keep]


def landing(tangible: Candidates, virtual: Candidates, choice, model: CostModel, *,
            settings: PinchSettings, radius_mm: float = LANDING_MM,
            axis_deg: float = LANDING_AXIS_DEG, rings=RING_POINTS) -> Landing:
    """The cost of ``choice`` (a :class:`pinchmatch.match.choice.Choice`) over its landings; with a
    radius of 0, the choice itself (nothing of either surface is built)."""
    if radius_mm == 0:
        chance = p_noticed(tangible, virtual, choice, model)
        loud = tuple(c for c, row in criterion_table(tangible, virtual, choice, model).items()
                     if row["noticeable"])
        return Landing(0.0, float(axis_deg), choice.cost, choice.cost, choice.cost, chance, loud, 1,
                       0)
    seen_points, seen_faces = (landing_pinches(virtual, choice.v_pose, choice.swapped, radius_mm,
                                               axis_deg, rings))
    X = choice.transform
    R, t = X[:3, :3], X[:3, 3]
    placed = seen_points @ R.T + t  # the landings in the tangible's frame
    u = placed[:, 1] - placed[:, 0]
    u = u / np.linalg.norm(u, axis=1, keepdims=True)
    tp = tangible.pinches.points[choice.t_pose]
    # the fingers close from outside either surface: far enough back to pass the larger width
    back = 0.5 * abs(float(np.linalg.norm(tp[1] - tp[0]))
                     - float(np.linalg.norm(seen_points[0, 1] - seen_points[0, 0]))) \
        + radius_mm + settings.fingertip_radius_mm
    felt, felt_faces = [], []
    for k, toward in ((0, u), (1, -u)):
        contact, face = close_fingers(tangible.obj.context, placed[:, k], toward, back)
        felt.append(contact)
        felt_faces.append(face)
    hit = (felt_faces[0] >= 0) & (felt_faces[1] >= 0)
    hit[0] = True  # the nominal landing is the match itself
    felt_points = np.stack(felt, axis=1)[hit]
    felt_points[0] = tp
    felt_f = np.stack(felt_faces, axis=1)[hit]
    felt_f[0] = tangible.pinches.face_index[choice.t_pose]
    seen = _described(virtual.obj.context, seen_points[hit], seen_faces[hit], settings)
    felt_p = _described(tangible.obj.context, felt_points, felt_f, settings)
    t_rows = feature_table(pinch_features(felt_p, tangible.obj.props))
    v_rows = feature_table(pinch_features(seen, virtual.obj.props))
    # the mass turns with the placement: the registration, or where the level keeps the object
    # the turn the seen mass offset takes, worked out here: the registration's when the object is
    # brought onto the prop; when it stays in the level, the level's frame seen from the prop's, the
    # inverse of its pose
    pose = tangible.obj.spec.pose if tangible.obj.spec is not None else None
    R_mass = R if choice.redirect_terms is None else (
        np.eye(3) if pose is None else Rotation.from_quat(pose[1]).as_matrix().T)
    terms, _ = pair_terms(tangible, virtual, t_rows, v_rows, model, R=R_mass,
                          t_points=felt_p.points, v_points=seen.points)
    # a redirection is planned for the targets: as the match's
    cost = model.pool(terms, extra=choice.redirect_terms, rest=choice.rest_jnd)
    jnd = model.as_jnd()
    jnd_all = CostModel(normalize="jnd", criteria=CRITERIA, weights=dict.fromkeys(CRITERIA, 1.0))
    jnd_terms, _ = pair_terms(tangible, virtual, t_rows, v_rows, jnd_all, R=R_mass,
                              t_points=felt_p.points, v_points=seen.points)
    loud = tuple(c for k, c in enumerate(CRITERIA) if c in model.criteria
                 and (jnd_terms[:, k] >= 1.0).any())
    worst = int(np.argmax(cost))
    p_worst = float(jnd.p_noticed(jnd.pool(jnd_terms[worst], extra=choice.redirect_terms)))
    missed = int((~hit).sum())
    if missed:  # a finger that meets no surface is noticed for certain
        miss = float(model.pool(np.full((1, len(CRITERIA)), MISS_JND ** 2)
                                * (np.arange(len(CRITERIA)) == 0))[0])
        cost = np.concatenate([cost, np.full(missed, max(miss, float(cost.max())))])
        worst, p_worst = len(cost) - 1, 1.0
    return Landing(float(radius_mm), float(axis_deg), float(cost[0]), float(cost.mean()),
                   float(cost[worst]), p_worst, loud, int(hit.sum()) + missed, missed)
