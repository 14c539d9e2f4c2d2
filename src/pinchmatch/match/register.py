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

from ..mesh.frames import cross_matrices, rotations_between

#: tie-breaker weights of the mass offset and the principal axis against the patch normals
MASS_TIE_WEIGHT = 0.1
AXIS_TIE_WEIGHT = 0.05
#: a normal this close to the pinch line does not take part in choosing the roll
NORMAL_ALONG_LINE_DEG = 5.0
#: a contact's normal counts in the fit of three contacts as a point this far out along it (mm):
#: about a fingertip's radius, so that the pads' facing matters as much as where they are
NORMAL_LEVER_MM = 8.0
#: a registration that turns the virtual object's up direction more than 90° (cosine below this)
#: is ``flipped``
FLIP_COSINE = -1e-6


def _about(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(k, 3, 3) rotations by angle (k,) about unit axes (k, 3)."""
    K = cross_matrices(axis)
    return (np.eye(3) + np.sin(angle)[:, None, None] * K + (1.0 - np.cos(angle))[:, None, None]
            * (K @ K))


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rowwise a x b of (k, 3) arrays: ``np.cross``'s arithmetic, without its general-axis
    set-up."""
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


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

    Parameters
    ----------
    tangible_points, tangible_normals : (k, 2, 3) float64
        The prop's contacts (mm) and patch normals (k, F, 3 for grasps of three or more contacts).
    virtual_points, virtual_normals : (k, 2, 3) float64
        The virtual object's, already in finger order (virtual p1 goes on tangible p1).
    tangible_com, virtual_com : (3,) or (k, 3) float64
        The objects' centres of mass (mm).
    tangible_axis, virtual_axis : (3,) or (k, 3) float64
        The objects' principal axes.

    Returns
    -------
    (k, 4, 4) float64
        The transforms taking each virtual pose onto its tangible pose.

    Examples
    --------
    >>> tangible = np.array([[[-10.0, 0.0, 0.0], [10.0, 0.0, 0.0]]])  # a pinch across X
    >>> virtual = np.array([[[0.0, -10.0, 5.0], [0.0, 10.0, 5.0]]])  # one across Y, 5 mm up
    >>> T = register_poses(tangible, np.sign(tangible), virtual, np.sign(virtual) * [1, 1, 0],
    ...                    tangible_com=np.zeros((1, 3)), virtual_com=np.zeros((1, 3)),
    ...                    tangible_axis=np.array([[0.0, 0.0, 1.0]]),
    ...                    virtual_axis=np.array([[0.0, 0.0, 1.0]]))
    >>> (virtual[0] @ T[0, :3, :3].T + T[0, :3, 3]).round(6) + 0.0  # the virtual contacts, placed
    array([[-10.,   0.,   0.],
           [ 10.,   0.,   0.]])
    """
    if tangible_points.shape[1] > 2:
        return register_contacts(tangible_points, tangible_normals, virtual_points, virtual_normals)
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

    pairs = [(across(moved(virtual_normals[:, j])), across(tangible_normals[:, j]), 1.0)
             for j in range(2)]
    dm_v, dm_t = moved(vc - vm), tc - tm
    has_mass = (np.linalg.norm(perp(dm_v), axis=1) > 1e-9) & (np.linalg.norm(perp(dm_t), axis=1)
                                                              > 1e-9)
    pairs.append((_unit(dm_v), _unit(dm_t), MASS_TIE_WEIGHT * has_mass))
    pairs.append((moved(va), ta, AXIS_TIE_WEIGHT))
    sin_sum, cos_sum = 0.0, 0.0
    for x, y, w in pairs:
        px, py = perp(x), perp(y)
        sin_sum = sin_sum + w * np.einsum("kd,kd->k", _cross(px, py), ut)
        cos_sum = cos_sum + w * np.einsum("kd,kd->k", px, py)
    R = _about(ut, np.arctan2(sin_sum, cos_sum)) @ R1

    T = np.zeros((k, 4, 4))
    T[:, :3, :3] = R
    T[:, :3, 3] = tm - np.einsum("kij,kj->ki", R, vm)
    T[:, 3, 3] = 1.0
    return T


def register_contacts(tangible_points: np.ndarray, tangible_normals: np.ndarray,
                      virtual_points: np.ndarray, virtual_normals: np.ndarray) -> np.ndarray:
    """(k, 4, 4) rigid transforms (mm, det +1) taking k virtual grasps of three or more contacts (k,
    F, 3), the virtual ones in finger order, onto k tangible ones: the least-squares fit (Kabsch
    1976; Umeyama 1991) of the contacts about their centroids, and of the patch normals, each
    counted as a point ``NORMAL_LEVER_MM`` out along it. The centroids coincide; three contacts fix
    every turn, so the centres of mass and axes need no part.

    >>> # a tripod in z = 0, and a copy turned a quarter about z and moved
    >>> tangible = np.array([[[0.0, 0.0, 0.0], [30.0, -10.0, 0.0], [30.0, 10.0, 0.0]]])
    >>> quarter = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    >>> virtual = tangible @ quarter + 5.0
    >>> normals = np.array([[[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]])
    >>> T = register_contacts(tangible, normals, virtual, normals @ quarter)
    >>> np.allclose(virtual[0] @ T[0, :3, :3].T + T[0, :3, 3], tangible[0])
    True
    """
    tm, vm = tangible_points.mean(axis=1), virtual_points.mean(axis=1)
    x = np.concatenate([virtual_points - vm[:, None], NORMAL_LEVER_MM * virtual_normals], axis=1)
    y = np.concatenate([tangible_points - tm[:, None], NORMAL_LEVER_MM * tangible_normals], axis=1)
    U, _, Vt = np.linalg.svd(np.einsum("kni,knj->kij", x, y))
    D = np.zeros((len(x), 3, 3))
    D[:, 0, 0] = D[:, 1, 1] = 1.0
    # ±1: -1 turns a reflection into a rotation
    D[:, 2, 2] = np.linalg.det(np.einsum("kij,kjl->kil", U, Vt))
    R = np.einsum("kji,kjl,kml->kim", Vt, D, U)  # V D Uᵀ
    T = np.zeros((len(x), 4, 4))
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

    Parameters
    ----------
    tangible_points, tangible_normals : (2, 3) float64
        The prop's contacts (mm) and patch normals, [p1, p2].
    virtual_points, virtual_normals : (2, 3) float64
        The virtual object's.
    swapped : bool
        The virtual p1 goes on the tangible p2.
    tangible_com, virtual_com : (3,) float64
        The objects' centres of mass (mm).
    tangible_axis, virtual_axis : (3,) float64
        The objects' principal axes.

    Returns
    -------
    (4, 4) float64
        The transform taking the virtual object onto the prop.

    Examples
    --------
    >>> tangible = np.array([[-10.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    >>> virtual = np.array([[0.0, -10.0, 5.0], [0.0, 10.0, 5.0]])
    >>> z = np.array([0.0, 0.0, 1.0])
    >>> T = register_pose(tangible, np.sign(tangible), virtual, np.sign(virtual) * [1, 1, 0],
    ...                   swapped=True, tangible_com=np.zeros(3), virtual_com=np.zeros(3),
    ...                   tangible_axis=z, virtual_axis=z)
    >>> (virtual @ T[:3, :3].T + T[:3, 3]).round(6) + 0.0  # swapped: p1 meets the tangible's p2
    array([[ 10.,   0.,   0.],
           [-10.,   0.,   0.]])
    """
    vp = virtual_points[::-1] if swapped else virtual_points
    vn = virtual_normals[::-1] if swapped else virtual_normals
    return register_poses(
        np.asarray(tangible_points, float)[None], np.asarray(tangible_normals, float)[None],
        np.asarray(vp, float)[None], np.asarray(vn, float)[None],
        tangible_com=tangible_com, virtual_com=virtual_com, tangible_axis=tangible_axis,
        virtual_axis=virtual_axis,
    )[0]
