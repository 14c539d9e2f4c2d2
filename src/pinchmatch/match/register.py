"""Place the virtual object on the tangible so that the fingers meet.

The rigid transform maps the virtual object's frame to the tangible's:

1. the pinch midpoints coincide;
2. the pinch lines are parallel, with the chosen finger order;
3. the remaining rotation about the pinch line best aligns the patch
   normals (closed form), with the centres of mass and the principal axes
   as tie-breakers where the normals run along the pinch line.

A normal within ``NORMAL_ALONG_LINE_DEG`` of the pinch line says nothing
about the roll (its part across the line is fitting noise) and is left out
of step 3; the masses then decide, which keeps the felt and seen masses on
the same side of the fingers.
"""

from __future__ import annotations

import numpy as np

#: tie-breaker weights of the mass offset and the principal axis against the patch normals
MASS_TIE_WEIGHT = 0.1
AXIS_TIE_WEIGHT = 0.05
#: a normal this close to the pinch line does not take part in choosing the roll
NORMAL_ALONG_LINE_DEG = 5.0
#: a registration that turns the virtual object's up direction more than 90° (cosine below this)
#: is ``flipped``
FLIP_COSINE = -1e-6


def _skew(v: np.ndarray) -> np.ndarray:
    """(k, 3) -> (k, 3, 3) cross-product matrices."""
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return K


def rotations_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(k, 3, 3) smallest rotations taking unit vectors a (k, 3) onto b (k, 3)."""
    c = np.einsum("kd,kd->k", a, b)
    K = _skew(np.cross(a, b))
    R = np.eye(3) + K + (K @ K) / np.maximum(1.0 + c, 1e-300)[:, None, None]
    opposite = c < -1.0 + 1e-12
    if opposite.any():  # a half turn about any perpendicular axis
        ao = a[opposite]
        perp = np.cross(ao, [1.0, 0.0, 0.0])
        small = np.linalg.norm(perp, axis=1) < 1e-6
        perp[small] = np.cross(ao[small], [0.0, 1.0, 0.0])
        perp /= np.linalg.norm(perp, axis=1, keepdims=True)
        R[opposite] = 2.0 * perp[:, :, None] * perp[:, None, :] - np.eye(3)
    return R


def _about(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(k, 3, 3) rotations by angle (k,) about unit axes (k, 3)."""
    K = _skew(axis)
    return np.eye(3) + np.sin(angle)[:, None, None] * K + (1.0 - np.cos(angle))[:, None, None] * (K @ K)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def register_poses(
    tangible_points: np.ndarray,
    tangible_normals: np.ndarray,
    virtual_points: np.ndarray,
    virtual_normals: np.ndarray,
    *,
    tangible_com: np.ndarray,
    virtual_com: np.ndarray,
    tangible_axis: np.ndarray,
    virtual_axis: np.ndarray,
) -> np.ndarray:
    """(k, 4, 4) rigid transforms (mm, det +1) taking k virtual poses onto k tangible poses.

    points, normals : (k, 2, 3), the virtual ones already in finger order (virtual p1 goes on
    tangible p1). com and axis : (3,) or (k, 3).
    """
    k = len(tangible_points)
    tc, vc = np.broadcast_to(tangible_com, (k, 3)), np.broadcast_to(virtual_com, (k, 3))
    ta, va = np.broadcast_to(tangible_axis, (k, 3)), np.broadcast_to(virtual_axis, (k, 3))
    tm, vm = tangible_points.mean(axis=1), virtual_points.mean(axis=1)
    ut = _unit(tangible_points[:, 1] - tangible_points[:, 0])
    uv = _unit(virtual_points[:, 1] - virtual_points[:, 0])
    R1 = rotations_between(uv, ut)

    def moved(x):
        return np.einsum("kij,kj->ki", R1, x)

    def perp(x):
        return x - np.einsum("kd,kd->k", x, ut)[:, None] * ut

    # (moved virtual direction, tangible direction, weight): aligned by a roll about the line
    def across(x):  # the part of a unit normal across the line, 0 when it runs along the line
        p = perp(x)
        return p * (np.linalg.norm(p, axis=1) > np.sin(np.radians(NORMAL_ALONG_LINE_DEG)))[:, None]

    pairs = [(across(moved(virtual_normals[:, j])), across(tangible_normals[:, j]), 1.0) for j in range(2)]
    dm_v, dm_t = moved(vc - vm), tc - tm
    has_mass = (np.linalg.norm(perp(dm_v), axis=1) > 1e-9) & (np.linalg.norm(perp(dm_t), axis=1) > 1e-9)
    pairs.append((_unit(dm_v), _unit(dm_t), MASS_TIE_WEIGHT * has_mass))
    pairs.append((moved(va), ta, AXIS_TIE_WEIGHT))
    sin_sum = sum(w * np.einsum("kd,kd->k", np.cross(perp(x), perp(y)), ut) for x, y, w in pairs)
    cos_sum = sum(w * np.einsum("kd,kd->k", perp(x), perp(y)) for x, y, w in pairs)
    R = _about(ut, np.arctan2(sin_sum, cos_sum)) @ R1

    T = np.zeros((k, 4, 4))
    T[:, :3, :3] = R
    T[:, :3, 3] = tm - np.einsum("kij,kj->ki", R, vm)
    T[:, 3, 3] = 1.0
    return T


def register_pose(
    tangible_points: np.ndarray,
    tangible_normals: np.ndarray,
    virtual_points: np.ndarray,
    virtual_normals: np.ndarray,
    *,
    swapped: bool,
    tangible_com: np.ndarray,
    virtual_com: np.ndarray,
    tangible_axis: np.ndarray,
    virtual_axis: np.ndarray,
) -> np.ndarray:
    """4x4 rigid transform (mm, det +1) taking one virtual pose onto one tangible pose.

    points, normals : (2, 3) per object, [p1, p2]. ``swapped``: the virtual p1
    goes on the tangible p2.
    """
    vp = virtual_points[::-1] if swapped else virtual_points
    vn = virtual_normals[::-1] if swapped else virtual_normals
    return register_poses(
        np.asarray(tangible_points, float)[None], np.asarray(tangible_normals, float)[None],
        np.asarray(vp, float)[None], np.asarray(vn, float)[None],
        tangible_com=tangible_com, virtual_com=virtual_com, tangible_axis=tangible_axis, virtual_axis=virtual_axis,
    )[0]
