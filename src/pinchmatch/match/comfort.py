"""Where the user stands: a pinch on a prop is reached from the user's side, and from above.

A prop that stands on a table is reached by a hand that comes from the person in front of it. The
hand model (:mod:`pinchmatch.grasp.hand`) finds, for each pinch, an approach h (the unit direction
from the fingertips toward the hand) along which the fingers and the hand clear the prop and its
table; this module judges that approach from where the user stands.

**The user.** A point in the level's frame (mm, y up): ``--user-at`` (``user_mm``); by default where
the hand starts its reach (:func:`pinchmatch.match.redirect.hand_start`: 150 mm above the prop's
table and 300 mm toward the level's +Z, the side a glTF scene faces). Seen from the prop (its
``pose``), per pinch:

- ``approach_elevation_deg``: the angle of h above the table's horizontal (90: straight from above);
- ``approach_azimuth_deg``: the angle between h's horizontal part and the horizontal direction from
  the pinch to the user (0: the hand comes straight from the user; 180: from behind the prop).
  Undefined (NaN) for a hand straight from above.

**The rule.** An approach is *comfortable* when it comes from the user's half (azimuth at most 90°)
or from above, at least ``FAR_SIDE_MIN_ELEVATION_DEG`` (35°) over the horizontal. A hand that comes
from the far half lower than that must wrap round the prop with the forearm coming from the user:
the wrist would be bent back or turned beyond its functional range (about 40° of flexion and
extension and of forearm rotation short of its limits: Ryu et al. 1991, Functional ranges of motion
of the wrist joint), or the user walks round the table. Steeper, the hand tips over the top of the
prop, as people reach over an object to take something behind it. 35° is a choice within that
reasoning, not a measured threshold.

Only a prop that stands on a table is judged (a prop held in the hand turns with it). The match
allows only comfortable pinches of a prop, unless the prop has none (a prop whose every pinch faces
the wall): then every pinch is allowed and the run says so. Among choices that cost the same within
the match's equivalence band (0.1 JND or 5 %), :func:`comfort_score` decides
(:mod:`pinchmatch.match.scene`).
"""

from __future__ import annotations

import numpy as np

from ..config import FAR_SIDE_MIN_ELEVATION_DEG, Redirect
from ..mesh.support import level_up
from .candidates import memo_of
from .redirect import hand_start, world_pose

#: the approach a person finds easiest, for the score: from the user's side, this far above the
#: horizontal
EASIEST_ELEVATION_DEG = 45.0
#: fingertips lower than this over the table (mm, the lowest point of their pads) start to scrape it
TABLE_MARGIN_MM = 10.0

_COMFORT: dict[int, dict] = {}
_USERS: dict[int, dict] = {}


def user_in_prop(tangible_obj, user_mm) -> np.ndarray:
    """(3,) where the user stands, in the prop's file frame (mm): ``user_mm`` (the level's frame),
    else the hand's default start for that prop. Worked out once per prop and user while the prop
    lives (the default start reads every vertex of the prop), read-only."""
    key = None if user_mm is None else tuple(np.asarray(user_mm, dtype=np.float64).tolist())
    memo = memo_of(_USERS, tangible_obj)
    if key not in memo:
        user = _user_in_prop(tangible_obj, user_mm)
        user.setflags(write=False)
        memo[key] = user
    return memo[key]


def _user_in_prop(tangible_obj, user_mm) -> np.ndarray:
    spec = tangible_obj.spec
    if user_mm is None:
        user = hand_start(spec, Redirect(), tangible_obj.loaded.mesh.vertices)
    else:
        user = np.asarray(user_mm, dtype=np.float64)
    R, p = world_pose(spec)
    return R.T @ (user - p)


def prop_up(tangible_obj) -> np.ndarray:
    """(3,) the up of the prop's table in its file frame: its support's normal, else the level's up
    as its pose turns it, else its own up."""
    support = tangible_obj.context.support
    if support is not None:
        return np.asarray(support.normal, dtype=np.float64)
    spec = tangible_obj.spec
    if getattr(spec, "pose", None) is not None:
        return world_pose(spec)[0].T @ level_up(spec)
    return np.asarray(tangible_obj.loaded.up, dtype=np.float64)


def approach_angles(tangible_obj, points: np.ndarray, approach: np.ndarray,
                    user_mm=None) -> tuple[np.ndarray, np.ndarray]:
    """(elevation_deg, azimuth_deg), each (k,), of k approaches ``approach`` (k, 3) to grasps whose
    contacts are ``points`` (k, F, 3), all in the prop's file frame (module notes). NaN where the
    approach is unknown; the azimuth is NaN for an approach within 1e-6 of vertical."""
    up = prop_up(tangible_obj)
    user = user_in_prop(tangible_obj, user_mm)
    h = np.asarray(approach, dtype=np.float64)
    to_user = user - np.asarray(points, dtype=np.float64).mean(axis=1)
    to_user = to_user - (to_user @ up)[:, None] * up
    flat = h - (h @ up)[:, None] * up
    elevation = np.degrees(np.arcsin(np.clip(h @ up, -1.0, 1.0)))
    cos = np.einsum("kd,kd->k", flat, to_user)
    sin = np.linalg.norm(np.cross(flat, to_user), axis=1)
    azimuth = np.degrees(np.arctan2(sin, cos))
    vertical = np.linalg.norm(flat, axis=1) < 1e-6
    return elevation, np.where(vertical | (np.linalg.norm(to_user, axis=1) < 1e-9), np.nan, azimuth)


def comfortable(elevation_deg: np.ndarray, azimuth_deg: np.ndarray) -> np.ndarray:
    """(k,) bool: from the user's half, or from above at least ``FAR_SIDE_MIN_ELEVATION_DEG``; True
    where the approach is unknown (a given pose) or straight from above.

    >>> elevation = np.array([0.0, 10.0, 40.0, np.nan])
    >>> azimuth = np.array([80.0, 170.0, 170.0, np.nan])
    >>> comfortable(elevation, azimuth).tolist()
    [True, False, True, True]
    """
    elevation, azimuth = np.asarray(elevation_deg, float), np.asarray(azimuth_deg, float)
    return (np.isnan(elevation) | np.isnan(azimuth) | (azimuth <= 90.0)
            | (elevation >= FAR_SIDE_MIN_ELEVATION_DEG))


def comfortable_poses(tangible, user_mm) -> np.ndarray | None:
    """(n,) bool: which poses of ``tangible`` (:class:`~pinchmatch.match.candidates.Candidates`) the
    match may use, or None when every one may: a prop held in the hand, or one none of whose poses
    is comfortable (then nothing else is feasible, and every pose is allowed). Made once per
    candidates and user."""
    if tangible.obj.context.support is None:
        return None
    memo = memo_of(_COMFORT, tangible)
    key = None if user_mm is None else tuple(float(c) for c in user_mm)
    if key not in memo:
        ok = comfortable(*approach_angles(tangible.obj, tangible.pinches.points,
                                          tangible.pinches.approach, user_mm))
        memo[key] = None if ok.all() or not ok.any() else ok
    return memo[key]


def comfort_score(tangible, t_pose: int, user_mm=None, fingertip_radius_mm: float = 8.0) -> float:
    """How easily a person makes pose ``t_pose`` of ``tangible``, higher better, for choices that
    cost the same: the approach's alignment with the easiest one (from the user's side,
    ``EASIEST_ELEVATION_DEG`` up: 1 when it is that, about 0.7 straight from above or level from the
    front, -0.7 level from behind), plus up to 0.5 for fingertips at least ``TABLE_MARGIN_MM`` above
    the table, plus up to 0.25 for a hand with the model's full clearance from the prop (the palm
    clear of it). 0 for a prop held in the hand."""
    obj, pinches = tangible.obj, tangible.pinches
    support = obj.context.support
    h = pinches.approach[t_pose]
    if support is None or not np.isfinite(h).all():
        return 0.0
    up = prop_up(obj)
    points = pinches.points[t_pose]
    to_user = user_in_prop(obj, user_mm) - points.mean(axis=0)
    to_user = to_user - (to_user @ up) * up
    norm = np.linalg.norm(to_user)
    front = to_user / norm if norm > 1e-9 else np.zeros(3)
    rise = np.radians(EASIEST_ELEVATION_DEG)
    easiest = np.cos(rise) * front + np.sin(rise) * up
    easiest = easiest / np.linalg.norm(easiest)
    tips = support.heights(points + fingertip_radius_mm
                           * pinches.normals[t_pose]) - fingertip_radius_mm
    clearance = pinches.approach_clearance_mm[t_pose]
    return float(h @ easiest + 0.5 * np.clip(tips.min() / TABLE_MARGIN_MM, 0.0, 1.0)
                 + 0.25 * (np.clip(clearance, 0.0, 1.0) if np.isfinite(clearance) else 0.0))
