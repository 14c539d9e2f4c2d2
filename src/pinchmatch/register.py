"""Place the virtual object on the tangible so that the fingers meet (issue 3, registration).

The rigid transform maps the virtual object's frame to the tangible's:

1. the pinch midpoints coincide;
2. the pinch lines are parallel, with the chosen finger order;
3. the remaining rotation about the pinch line best aligns the patch
   normals (closed form), with the centres of mass and the principal axes
   as tie-breakers where the normals run along the pinch line.
"""

from __future__ import annotations

import numpy as np

#: tie-breaker weights of the mass offset and the principal axis against the patch normals
MASS_TIE_WEIGHT = 0.1
AXIS_TIE_WEIGHT = 0.05


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking unit vector a onto unit vector b."""
    v = np.cross(a, b)
    c = float(a @ b)
    if c < -1.0 + 1e-12:  # opposite: half turn about any perpendicular axis
        perp = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(perp) < 1e-6:
            perp = np.cross(a, [0.0, 1.0, 0.0])
        perp /= np.linalg.norm(perp)
        return 2.0 * np.outer(perp, perp) - np.eye(3)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def _about(axis: np.ndarray, angle: float) -> np.ndarray:
    x, y, z = axis
    K = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * K @ K


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
    """4x4 rigid transform (mm, det +1) taking the virtual pose onto the tangible pose.

    points, normals : (2, 3) per object, [p1, p2]. ``swapped``: the virtual p1
    goes on the tangible p2.
    """
    vp = virtual_points[::-1] if swapped else virtual_points
    vn = virtual_normals[::-1] if swapped else virtual_normals
    tm, vm = tangible_points.mean(axis=0), vp.mean(axis=0)
    ut = tangible_points[1] - tangible_points[0]
    uv = vp[1] - vp[0]
    ut, uv = ut / np.linalg.norm(ut), uv / np.linalg.norm(uv)
    R1 = _rotation_between(uv, ut)

    def perp(x):
        return x - (x @ ut) * ut

    # pairs (moved virtual direction, tangible direction, weight) to align about the line
    pairs = [(R1 @ vn[k], tangible_normals[k], 1.0) for k in range(2)]
    dm_v, dm_t = R1 @ (virtual_com - vm), tangible_com - tm
    if np.linalg.norm(perp(dm_v)) > 1e-9 and np.linalg.norm(perp(dm_t)) > 1e-9:
        pairs.append((dm_v / np.linalg.norm(dm_v), dm_t / np.linalg.norm(dm_t), MASS_TIE_WEIGHT))
    pairs.append((R1 @ virtual_axis, tangible_axis, AXIS_TIE_WEIGHT))
    sin_sum = sum(w * float(np.cross(perp(x), perp(y)) @ ut) for x, y, w in pairs)
    cos_sum = sum(w * float(perp(x) @ perp(y)) for x, y, w in pairs)
    R = _about(ut, np.arctan2(sin_sum, cos_sum)) @ R1

    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = tm - R @ vm
    return T
