"""The targeted step: the poses a match needs, looked for by their features on the other object.

The exact search (:mod:`pinchmatch.match.search`) chooses among the sampled poses, so a prop whose
sample lacks the one kind of pinch a virtual object needs (the mug's handle for a plate's rim)
loses the match by the luck of the draw, and refinement, a local search, cannot go and find it.
Before refinement, this step looks for it:

- **A feature pool per object**: ``POOL_PER_POSE`` candidates per sampled pose (at least
  ``POOL_MIN``), drawn area-uniformly from a stream of the seed of their own and kept where they
  keep the cheap rules (:func:`pinchmatch.grasp.sampling.cheap_candidates`), each with a key of
  the features the cost compares, in just-noticeable differences: width (:func:`width_jnd`),
  distance from the centre of mass along the axis, tilt, the two normal angles (in either finger
  order) and the lever arm of the centre of mass about the pinch line. A process keeps each
  object's pool while the object lives (a prop serves every virtual object).
- **Both ways**: the virtual object's poses in its ``TARGET_POSES`` best distinct pairs on any
  tangible, and in each tangible's own best; for each distinct one, ``NEAREST`` of every
  tangible's pool candidates, nearest in the key first, get the full check (every rule, the hand's
  reach included). The other way round, each tangible's poses in its best pairs send the virtual
  object's nearest pool candidates to the check. A pool candidate is checked once per process
  however many virtual objects send it (a check does not depend on which others are checked with
  it).
- The feasible ones join the candidates (as refined poses do: they have no place in the sampled
  list) and the exact search runs over the union before the local refinement starts from its best
  pairs (:func:`pinchmatch.match.refine.refined_search`).

The keys leave out the patches' curvatures (a patch fit per candidate would cost what the full
check costs); the check computes them, and the exact search judges by all features. What this step
can still miss: a kind of pinch that none of the pool's draws hits (the pool is a sample too, of
about ten times the count), and one whose key is near the poses looked for only in curvature.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..grasp.pinches import PinchSettings, check_pinches, check_reach, concat_pinches
from ..grasp.features import TripodFeatures, tripod_shape
from ..grasp.sampling import uniform_contacts, cheap_candidates
from ..grasp.tripod_rules import TRIPOD_RULES, Tripods, check_tripods
from ..grasp.tripods import candidate_tripods
from ..grasp.strata import width_jnd
from .candidates import Candidates, extend, memo_of
from .cost import ANGLE_JND_FLOOR_DEG, COM_JND_MM, MASS_JND_FLOOR_MM

#: candidates drawn into an object's feature pool per sampled pose, and at least
POOL_PER_POSE, POOL_MIN = 8, 4000
#: the pool's random stream: another than the sampler's for the same seed
POOL_STREAM = 7
#: best distinct pairs whose poses are looked for on the other objects
TARGET_POSES = 8
#: pool candidates checked per pose looked for
NEAREST = 12

_POOLS: dict[int, tuple] = {}


def pinch_keys(points: np.ndarray, normals: np.ndarray, props) -> np.ndarray:
    """(n, 6) the targeted step's key of pinches ((n, 2, 3) contacts and outward normals): width in
    JND (:func:`width_jnd`), distance of the midpoint from the centre of mass along the axis, tilt,
    the two normal angles (the smaller first, so either finger order gives one key) and the centre
    of mass's lever arm about the pinch line, each over its just-noticeable difference (the floors
    of :mod:`pinchmatch.match.cost`)."""
    seg = points[:, 1] - points[:, 0]
    width = np.linalg.norm(seg, axis=1)
    u = seg / np.maximum(width, 1e-300)[:, None]
    a = props.principal_axis / np.linalg.norm(props.principal_axis)
    mid = points.mean(axis=1)
    com_distance = np.abs((mid - props.com_mm) @ a)
    tilt = np.degrees(np.arcsin(np.clip(np.abs(u @ a), 0.0, 1.0)))
    psi = np.degrees(np.arccos(np.clip(np.abs(np.einsum("nkd,nd->nk", normals, u)), 0.0, 1.0)))
    offset = props.com_mm - mid
    lever = np.linalg.norm(offset - np.einsum("nd,nd->n", offset, u)[:, None] * u, axis=1)
    return _keys(width, com_distance, tilt, psi, lever)


def tripod_keys(points: np.ndarray, normals: np.ndarray, props) -> np.ndarray:
    """(n, 8) the key of tripods ((n, 3, 3) contacts and outward normals): as :func:`pinch_keys`'s,
    the lever arm from the contacts' centroid, and the fingers' spacing in JND of width; the two
    fingers' normal angles smaller first."""
    f = tripod_shape(points, normals, props)
    return _keys(f["width_mm"], f["com_distance_mm"], f["tilt_deg"], f["normal_angle_deg"],
                 f["lever_arm_mm"], f["spacing_mm"])


def feature_keys(c: Candidates) -> np.ndarray:
    """(n, 6) :func:`pinch_keys` of every candidate pose, from its features (of tripods,
    :func:`tripod_keys`)."""
    f = c.features
    if isinstance(f, TripodFeatures):
        return _keys(f.width_mm, f.com_distance_mm, f.tilt_deg, f.normal_angle_deg, f.lever_arm_mm,
                     f.spacing_mm)
    return _keys(f.width_mm, f.com_distance_mm, f.tilt_deg, f.normal_angle_deg, f.mass_perp_mm)


def _keys(width_mm, com_distance_mm, tilt_deg, normal_angle_deg, lever_mm,
          spacing_mm=None) -> np.ndarray:
    """The key's columns, each over its just-noticeable difference (a pinch's normal angles smaller
    first, a tripod's thumb first and its fingers' smaller first)."""
    angles = np.sort(normal_angle_deg, axis=1) if normal_angle_deg.shape[1] == 2 else \
        np.column_stack([normal_angle_deg[:, 0], np.sort(normal_angle_deg[:, 1:], axis=1)])
    columns = [width_jnd(width_mm), com_distance_mm / COM_JND_MM, tilt_deg / ANGLE_JND_FLOOR_DEG,
               angles / ANGLE_JND_FLOOR_DEG, lever_mm / MASS_JND_FLOOR_MM]
    return np.column_stack(columns + ([] if spacing_mm is None else [width_jnd(spacing_mm)]))


class CheckedPool:
    """The full checks of a feature pool's candidates made so far, each candidate's once: ``row``
    (m,) its row in the checked pinches (-1: not checked yet)."""

    def __init__(self, count: int):
        self.row = np.full(count, -1, dtype=np.int64)
        self._checked = None

    def checked(self, idx: np.ndarray, check) -> object:
        """The checked pinches (or tripods) of pool candidates ``idx``, in that order;
        ``check(new)`` checks the candidates ``new`` not checked before."""
        new = np.unique(idx[self.row[idx] < 0])
        if len(new):
            start = 0 if self._checked is None else len(self._checked.feasible)
            part = check(new)
            self._checked = part if self._checked is None else concat_pinches([self._checked, part])
            self.row[new] = start + np.arange(len(new))
        return self._checked.subset(self.row[idx])


def feature_pool(c: Candidates, settings: PinchSettings
                 ) -> tuple[np.ndarray, np.ndarray, cKDTree | None, CheckedPool]:
    """The feature pool of ``c``'s object (module notes): (m, 2, 3) contacts, (m, 2) triangles, a
    KD-tree over their keys (None when no candidate keeps the cheap rules) and the checks made of
    them so far, made once per object."""
    tripods = isinstance(c.pinches, Tripods)
    key = (settings, tripods)  # the checks depend on every setting, not only the seed and the count
    memo = memo_of(_POOLS, c.obj)
    if key not in memo:
        rng = np.random.default_rng([int(settings.seed), POOL_STREAM])
        context, count = c.obj.context, max(POOL_MIN, POOL_PER_POSE * int(settings.count))
        if tripods:
            rejected = dict.fromkeys(TRIPOD_RULES, 0)
            points, faces = candidate_tripods(context, *uniform_contacts(context, count, rng),
                                              settings, rng, rejected)
        else:
            points, faces = cheap_candidates(context, count, settings, rng)
        keep_pool(c, settings, points, faces)
    return memo[key]


def keep_pool(c: Candidates, settings: PinchSettings, points: np.ndarray,
              faces: np.ndarray) -> None:
    """Take (``points``, ``faces``) as ``c``'s object's feature pool under ``settings``, as
    :func:`feature_pool` draws it (a run's workers take a tangible's, drawn once with its poses), no
    checks made of it yet."""
    tripods = isinstance(c.pinches, Tripods)
    keys = (tripod_keys if tripods else pinch_keys)(points, c.obj.context.face_normals[faces],
                                                    c.obj.props)
    memo_of(_POOLS, c.obj)[(settings, tripods)] = (points, faces,
                                                   cKDTree(keys) if len(points) else None,
                                                   CheckedPool(len(points)))


def nearest_feasible(c: Candidates, keys: np.ndarray, settings: PinchSettings):
    """The feasible pinches among ``NEAREST`` pool candidates per distinct key of ``keys`` on
    ``c``'s object, every rule checked (None when there are none, or ``c``'s poses were given). The
    candidates are taken nearest first, in turn over the keys: the first nearest of every key, then
    the second, and so on, each once, so that keys near each other share their budget instead of
    checking one place twice."""
    if c.given or not len(keys):
        return None
    points, faces, tree, done = feature_pool(c, settings)
    if tree is None:
        return None
    keys = np.unique(keys, axis=0)
    budget = min(NEAREST * len(keys), tree.n)
    _, idx = tree.query(keys, k=budget)
    idx = np.asarray(idx).reshape(len(keys), budget).T.ravel()  # rank by rank over the keys
    first = np.sort(np.unique(idx, return_index=True)[1])[:budget]
    idx = idx[first]
    context = c.obj.context

    def check(new):
        # every rule, the hand's search (most of a check's price) only where the others hold
        if isinstance(c.pinches, Tripods):
            part = check_tripods(context, points[new], faces[new], settings=settings,
                                 with_reach=False)
        else:
            part = check_pinches(context, points[new, 0], points[new, 1], settings=settings,
                                 faces=faces[new], with_reach=False)
        return check_reach(context, part, settings=settings, rows=np.flatnonzero(part.feasible))

    checked = done.checked(idx, check)
    keep = np.flatnonzero(checked.feasible)
    return checked.subset(keep) if len(keep) else None


def targeted_poses(search, pinch_settings: PinchSettings) -> tuple[list, Candidates]:
    """Every tangible's candidates and the virtual object's (``search.virtuals[0]``), with the
    feasible poses the targeted step found appended (module notes)."""
    tangibles, virtual = search.tangibles, search.virtuals[0]
    reachable = [t for t in range(len(tangibles)) if np.isfinite(search.best_cost(0, t))]
    if not reachable:
        return list(tangibles), virtual
    picks = search.choices(0, reachable, TARGET_POSES)
    for t in reachable:
        picks += search.choices(0, [t], TARGET_POSES)
    v_poses = np.unique([c.v_pose for c in picks])
    v_keys = feature_keys(virtual)[v_poses]
    grown = []
    for t, T in enumerate(tangibles):
        found = nearest_feasible(T, v_keys, pinch_settings) if t in reachable else None
        grown.append(T if found is None else extend(T, found))
    keys = {t: feature_keys(tangibles[t]) for t in {c.tangible for c in picks}}
    t_keys = np.stack([keys[c.tangible][c.t_pose] for c in picks])
    found = nearest_feasible(virtual, np.unique(t_keys, axis=0), pinch_settings)
    return grown, virtual if found is None else extend(virtual, found)
