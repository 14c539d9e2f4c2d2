"""Hand redirection: a virtual object stays where the level puts it, and the hand is led to the
prop.

With ``placement="fixed"`` the virtual object is not moved onto the prop. While the hand reaches
from its start to the physical pinch on the prop, the virtual hand is offset a little more with
every centimetre (body warping, Azmandian et al. 2016), so that the virtual fingers land on the
virtual pinch exactly when the real ones land on the prop. How far the hand must be redirected
depends on the pinch pair: this module measures it and turns it into cost.

Frames: the world is the level's (the glTF file's frame: y up), in mm. A virtual object's
coordinates are world coordinates (a level's node is read with every transform above it applied).
A prop's file coordinates (in mm) are mapped into the world by its manifest ``pose``
(:class:`pinchmatch.mesh.object_spec.ObjectSpec`, ``R x + p``); a prop without a pose stands at the
world's origin, unturned.

Per pose pair (the virtual pose's fingers in the order the search chose: p1 on the tangible's p1,
or on its p2 when swapped):

- ``physical_target_mm``, ``virtual_target_mm``: the pinch midpoints in the world;
- ``offset_mm``: the distance between them;
- ``angle_deg``: the angle at the hand's start between the directions to the two targets, the
  quantity that body-warping studies threshold (Zenner and Krüger 2019);
- ``axis_turn_deg``: the turn from the physical pinch axis (p1 to p2; a tripod's thumb to the middle
  of its fingers) to the virtual one.

Cost, in threshold units (1 = at the threshold, as a criterion at 1 JND): ``angle_deg /
threshold_deg`` and ``axis_turn_deg / axis_threshold_deg``, each squared and pooled with the haptic
criteria's contributions, weight 1 (:meth:`pinchmatch.match.cost.CostModel.pool`). A pair is within
the budget when its angle is at most ``max_angle_deg`` and its reach gain (``gain``: the virtual
target's distance from the hand's start over the physical one's) within ``gain_range``. A virtual
object with no pair within the budget, or whose best redirected pair costs more than the carousel's
plus the margin (``--carousel-margin-jnd``), is served by the carousel (the registered placement,
brought to the prop: :func:`pinchmatch.match.scene.match_one`). Both terms are at least 0 and the
search's blockwise pass adds a lower bound of the angle's and drops the pairs beyond the budget
(:func:`pair_budget`), so its bounds stay lower bounds and the search stays exact. The model, its
thresholds and their sources are in docs/redirection.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import (AXIS_THRESHOLD_DEG, DEFAULT_HAND_OFFSET_MM, MAX_HAND_START_MM,
                      MAX_REDIRECT_DEG,  # noqa: F401
                      MAX_THRESHOLD_DEG, PLACEMENTS, REDIRECT_THRESHOLD_DEG, Redirect)

@dataclass(frozen=True)
class Redirection:
    """The redirection of k pose pairs (mm and degrees, world frame); ``terms`` (k, 2) the angle's
    and the axis turn's contributions (threshold units squared); ``allowed`` (k,) within the budget;
    ``gain`` (k,) the reach gain (:func:`reach_gain`)."""

    angle_deg: np.ndarray
    offset_mm: np.ndarray
    axis_turn_deg: np.ndarray
    hand_start_mm: np.ndarray
    physical_target_mm: np.ndarray
    virtual_target_mm: np.ndarray
    terms: np.ndarray
    allowed: np.ndarray
    gain: np.ndarray

    def record(self, k: int, mode: str) -> dict:
        """Pair ``k``'s entry of ``matches.json`` (``mode``: ``redirect`` or ``carousel``)."""
        def vec(v):
            return [round(float(c), 3) for c in v]

        return {"mode": mode, "angle_deg": round(float(self.angle_deg[k]), 4),
                "offset_mm": round(float(self.offset_mm[k]), 3),
                "gain": round(float(self.gain[k]), 4),
                "axis_turn_deg": round(float(self.axis_turn_deg[k]), 4),
                "hand_start_mm": vec(self.hand_start_mm),
                "physical_target_mm": vec(self.physical_target_mm[k]),
                "virtual_target_mm": vec(self.virtual_target_mm[k])}


def world_pose(spec) -> tuple[np.ndarray, np.ndarray]:
    """(R (3, 3), p (3,)): the map of an object's file coordinates (mm) into the world; the
    identity where its spec gives no pose."""
    pose = getattr(spec, "pose", None) if spec is not None else None
    if pose is None:
        return np.eye(3), np.zeros(3)
    return quaternion_matrix(pose[1]), np.asarray(pose[0], dtype=np.float64)


def seen_turn(tangible_obj, registration: np.ndarray, redirected: bool) -> np.ndarray:
    """The turn of the virtual object as seen from the prop, which turns its mass offset and its up:
    the registration's rotation (``registration``: (..., 3, 3)) when the object is brought onto the
    prop, the prop's pose inverted when it stays where the level puts it (``redirected``: the
    registration is then the hand's warp onto the prop, not a placement). The one place this is
    decided."""
    return world_pose(tangible_obj.spec)[0].T if redirected else registration


def placed_transform(spec) -> np.ndarray:
    """(4, 4) the map of world coordinates (mm) into an object's file frame: where a virtual object
    that stays in the level lies as seen from the prop (the inverse of :func:`world_pose`)."""
    R, p = world_pose(spec)
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = R.T, -R.T @ p
    return out


def quaternion_matrix(xyzw) -> np.ndarray:
    """The rotation matrix of a unit quaternion (x, y, z, w)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(np.asarray(xyzw, dtype=np.float64)).as_matrix()


def hand_start(spec, redirect: Redirect, vertices_mm: np.ndarray) -> np.ndarray:
    """Where the hand starts (mm, world): the given point, else a user standing at the prop's table
    (:data:`DEFAULT_HAND_OFFSET_MM` from the middle of the prop's footprint on its support, the
    plane of its lowest point in the world: never from where its file puts its origin).
    ``vertices_mm`` (n, 3) are the prop's, in its file frame. In a level of another up (the spec's
    ``level_up``), the same point as the level turned into glTF's frame puts it
    (:func:`pinchmatch.mesh.frames.level_turn`)."""
    from ..mesh.frames import level_turn

    if redirect.hand_start_mm is not None:
        return np.asarray(redirect.hand_start_mm, dtype=np.float64)
    R, p = world_pose(spec)
    C = level_turn(getattr(spec, "level_up", None) if spec is not None else None)
    world = (np.asarray(vertices_mm, dtype=np.float64) @ R.T + p) @ C.T  # in glTF's frame: y up
    low, high = world.min(axis=0), world.max(axis=0)
    footprint = np.array([(low[0] + high[0]) / 2.0, low[1], (low[2] + high[2]) / 2.0])
    return C.T @ (footprint + np.asarray(DEFAULT_HAND_OFFSET_MM))


def reach_gain(start: np.ndarray, physical_mm: np.ndarray, virtual_mm: np.ndarray) -> np.ndarray:
    """|virtual − start| / |physical − start| per row: how much longer the seen reach is than
    the felt one."""
    return np.linalg.norm(virtual_mm - start,
                          axis=-1) / np.maximum(np.linalg.norm(physical_mm - start, axis=-1), 1e-9)


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles between rows of a and b (deg), by atan2 of |a x b| and a . b (exact near 0)."""
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.degrees(np.arctan2(cross, np.einsum("...i,...i->...", a, b)))


def redirection(tangible_obj, t_points: np.ndarray, v_points: np.ndarray,
                redirect: Redirect) -> Redirection:
    """The redirection of k pose pairs: ``t_points`` (k, 2, 3) the tangible's contacts in its file
    frame (mm), ``v_points`` (k, 2, 3) the virtual object's in the world, in the matched finger
    order; ``tangible_obj`` the prop (:class:`pinchmatch.grasp.analysis.ObjectAnalysis`: its spec's
    pose and its mesh, for the hand's start). A pair is within the budget when its angle is at most
    the largest and its reach gain within the range."""
    spec = tangible_obj.spec
    R, p = world_pose(spec)
    physical = np.einsum("ij,kfj->kfi", R, np.asarray(t_points, dtype=np.float64)) + p
    virtual = np.asarray(v_points, dtype=np.float64)
    start = hand_start(spec, redirect, tangible_obj.loaded.mesh.vertices)
    pt, vt = physical.mean(axis=1), virtual.mean(axis=1)
    angle = _angle_deg(pt - start, vt - start)
    # the grasp's axis: a pinch's p1 to p2, a tripod's thumb to the middle of its fingers
    turn = _angle_deg(physical[:, 1:].mean(axis=1) - physical[:, 0],
                      virtual[:, 1:].mean(axis=1) - virtual[:, 0])
    gain = reach_gain(start, pt, vt)
    terms = np.stack([(angle / redirect.threshold_deg) ** 2,
                      (turn / redirect.axis_threshold_deg) ** 2], axis=-1)
    low, high = redirect.gain_range
    return Redirection(angle, np.linalg.norm(vt - pt, axis=1), turn, start, pt, vt, terms,
                       (angle <= redirect.max_angle_deg) & (gain >= low) & (gain <= high), gain)


#: the blockwise pass's margins, so that it never drops a pair the exact evaluation allows (deg,
#: relative)
ANGLE_MARGIN_DEG, GAIN_MARGIN = 1e-3, 1e-9


def pair_budget(tangible_obj, t_midpoints: np.ndarray, v_midpoints: np.ndarray, redirect: Redirect):
    """For the search's blockwise pass: a function ``block(start, stop)`` giving, for tangible poses
    start..stop against every virtual pose, (a lower bound of the angle's contribution, whether the
    pair may be within the budget). ``t_midpoints`` (nt, 3) in the prop's file frame,
    ``v_midpoints`` (nv, 3) in the world. The angle comes from a matrix product of unit directions,
    its round-off covered by ``ANGLE_MARGIN_DEG``; the gain from the distances, covered by
    ``GAIN_MARGIN``."""
    R, p = world_pose(tangible_obj.spec)
    start = hand_start(tangible_obj.spec, redirect, tangible_obj.loaded.mesh.vertices)
    pt = np.asarray(t_midpoints, dtype=np.float64) @ R.T + p - start
    vt = np.asarray(v_midpoints, dtype=np.float64) - start
    dt, dv = np.linalg.norm(pt, axis=1), np.linalg.norm(vt, axis=1)
    ut, uv = pt / np.maximum(dt, 1e-300)[:, None], vt / np.maximum(dv, 1e-300)[:, None]
    low, high = redirect.gain_range

    def block(first: int, stop: int):
        cos = np.clip(ut[first:stop] @ uv.T, -1.0, 1.0)
        angle = np.degrees(np.arccos(cos))
        term = (np.maximum(angle - ANGLE_MARGIN_DEG, 0.0) / redirect.threshold_deg) ** 2
        gain = dv[None, :] / np.maximum(dt[first:stop, None], 1e-9)
        ok = (angle <= redirect.max_angle_deg + ANGLE_MARGIN_DEG) & (gain >= low
                                                                     * (1 - GAIN_MARGIN)) \
            & (gain <= high * (1 + GAIN_MARGIN))
        return term, ok

    return block
