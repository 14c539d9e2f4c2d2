"""The felt cost: what a match costs over where a guided pinch's fingers land, not at its targets
alone.

In the headset a pinch counts when each fingertip is within ``radius_mm`` (``--landing-mm``, 5 mm)
of its target and the pinch axis within ``LANDING_AXIS_DEG`` (14°) of the target's. Where, inside
that region, do guided fingers land? Pointing studies give the spread of a guided fingertip's end
point as a roughly isotropic two-dimensional Gaussian around the target; how wide it is depends on
the guidance. The headset's acceptance radius is a tolerance chosen to accept nearly every
deliberate pinch, so we take it as two standard deviations: **each finger lands with an isotropic
Gaussian spread of σ = radius / 2, truncated to the acceptance disc** (a landing outside it is
refused and tried again), the two fingers independently, the pairs kept where the axis is within the
tolerance. This is a documented choice, not a published figure (docs/matching.md); ``--landing-mm``
sets the radius and with it the spread.

Discretisation (:mod:`pinchmatch.match.landing`'s pattern): per finger the target, 8 points on a
ring at r/2 and 16 at r, in the plane perpendicular to the pinch line, each put on the surface where
a finger closing along the pinch line meets it. Each point carries the truncated Gaussian's mass of
the annulus it stands for (0 to r/4, r/4 to 3r/4, 3r/4 to r), shared by its ring's points; a pair of
landing points weighs the product of its fingers' weights, renormalised over the pairs within the
axis tolerance.

**Per pose, once** (:class:`LandingTable`, kept per object by :class:`FeltTables`): its 25 landing
points per finger, their patches (normal, principal curvatures) and the feature rows of all 625
pairs. A tripod's index and middle finger land as one (:func:`landing_combos`): the two fingers
opposite the thumb act as one virtual finger (Arbib, Iberall & Lyons 1985), held side by side by the
hand and guided together, so they share one offset and a tripod pose has 625 landings too, not 25³.
**Per pose pair, no new geometry:** the hand lands on the prop at the prop's own landing points; the
eye sees the corresponding points of the virtual object, the points of its table that the pair's
registration carries nearest to them (each of the virtual object's ring points, turned by the
registration into the prop's frame, is matched to the prop's ring point of the same ring nearest in
angle: within half a ring step, 22.5° or 11.25°). Each landing costs the run's cost of felt
against seen (the mass offset under the match's own placement, a planned redirection as the
match's); a landing where a finger meets no surface on either object is a miss, noticed for certain
(:data:`pinchmatch.match.landing.MISS_JND`).

:func:`felt_costs` gives, per choice, the nominal cost, the expected cost (the weighted mean over
the landings) and the worst; the match ranks by one of them (``--rank``,
:mod:`pinchmatch.match.scene`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..grasp.features import grasp_features
from ..grasp.pinches import closing_directions, patches
from ..grasp.spread import other_order
from .candidates import Candidates, mass_ratio, memo_of, pair_terms, pose_key
from .cost import CRITERIA, WIDTH_JND_FLOOR_MM, WIDTH_JND_FRACTION, CostModel, feature_table
from .landing import LANDING_AXIS_DEG, MISS_JND, RING_POINTS, disc_offsets
from .redirect import seen_turn
from .trust import least, scan_variance, spread_terms
from .refine import close_fingers, move_directions
from .noticed import criterion_table, p_noticed

#: the landing spread's standard deviation, as a share of the acceptance radius
SIGMA_SHARE = 0.5
#: the finest grid of :func:`landing_moments`' shared patches (mm)
MIN_CELL_MM = 0.1


def ring_weights(radius_mm: float, rings=RING_POINTS,
                 sigma_share: float = SIGMA_SHARE) -> np.ndarray:
    """(1 + Σ rings,) the weight of each point of :func:`disc_offsets`: the mass, under an
    isotropic Gaussian of σ = sigma_share · radius truncated to the disc, of the annulus the
    point's ring stands for, shared equally by the ring's points; the weights sum to 1."""
    if radius_mm <= 0:
        return np.ones(1)
    n = len(rings)
    # as shares of the radius: the weights do not depend on its size
    edges = [0.0] + [(i + 0.5) / n for i in range(n)] + [1.0]
    mass = np.diff([1.0 - math.exp(-e * e / (2.0 * sigma_share ** 2)) for e in edges])
    weights = np.concatenate([[mass[0]]]
                             + [np.full(count, mass[i + 1] / count)
                                for i, count in enumerate(rings)])
    return weights / weights.sum()


def landing_combos(n: int, fingers: int) -> np.ndarray:
    """(F, n²) the landing point of each finger in each landing, the first finger's slowest: a
    pinch's two fingers on every pair of their ``n`` points; a tripod's thumb on each of its points
    against its index and middle finger on each of theirs, the two landing as one (the same point of
    their discs). The two fingers opposite the thumb are held side by side by one hand and guided as
    one, so their landings share one offset; the thumb opposes them and lands on its own (module
    notes)."""
    idx = np.indices((n, n)).reshape(2, -1)
    return idx if fingers == 2 else np.concatenate([idx, np.repeat(idx[1:], fingers - 2, axis=0)])


@dataclass(frozen=True)
class LandingTable:
    """One pose's landings (``P = 1 + Σ rings`` points per finger, every one of the ``P²`` pairs):

    - ``points`` (P², 2, 3) mm and ``rows`` (P², 2, 9) the feature-table rows of each pair, in the
      pose's finger order; ``hit`` (P²,) both fingers met a surface;
    - ``weights`` (P²,) the pair's landing weight, 0 where its axis is beyond the tolerance (not
      normalised: a table's hits and misses share them);
    - ``frame`` (2, 3): the directions the rings are laid out along (:func:`move_directions`), and
      ``angles`` (P,) each point's angle in that frame (the target's is 0), ``ring`` (P,) its ring
      (0: the target)."""

    points: np.ndarray
    rows: np.ndarray
    hit: np.ndarray
    weights: np.ndarray
    frame: np.ndarray
    angles: np.ndarray
    ring: np.ndarray


@dataclass(frozen=True)
class _Landed:
    """Where the F fingers of k poses land (n points per finger): ``points`` (F, k, n, 3) mm,
    ``faces`` (F, k, n), -1 where the finger meets nothing (then ``aimed`` (F, k, n, 3) is where it
    was aimed), ``line`` (k, 3) the unit pinch line (a tripod's: from the thumb to its fingers'
    middle), ``frame`` (k, 2, 3) the rings' directions, ``offsets`` (n, 2)."""

    points: np.ndarray
    faces: np.ndarray
    aimed: np.ndarray
    line: np.ndarray
    frame: np.ndarray
    offsets: np.ndarray


def _land(candidates: Candidates, poses: np.ndarray, radius_mm: float, axis_deg: float,
          rings) -> _Landed:
    """Each finger of each pose closed onto the surface, aimed at the target and at the rings'
    points around it (:func:`disc_offsets`, in :func:`move_directions`' frame): a pinch's fingers
    along its line, a tripod's thumb towards its fingers' middle and each finger towards the
    thumb."""
    obj = candidates.obj
    k = len(poses)
    p = candidates.pinches.points[poses]  # (k, F, 3)
    f = candidates.pinches.face_index[poses]
    frame = move_directions(p, obj.props.principal_axis)  # (k, 2, 3)
    offsets = disc_offsets(radius_mm, rings)
    n = len(offsets)
    u = p[:, 1:].mean(axis=1) - p[:, 0]
    u = u / np.linalg.norm(u, axis=1, keepdims=True)
    closing = closing_directions(p)  # (k, F, 3)
    back = radius_mm * math.tan(math.radians(axis_deg)) + radius_mm + 1.0
    landed, faces, aimed = [], [], []
    for finger in range(p.shape[1]):
        aimed.append(p[:, finger, None, :] + np.einsum("pa,kad->kpd", offsets, frame))  # (k, n, 3)
        toward = np.broadcast_to(closing[:, finger, None, :], (k, n, 3)).reshape(-1, 3).copy()
        contact, face = close_fingers(obj.context, aimed[-1].reshape(-1, 3), toward, back)
        contact, face = contact.reshape(k, n, 3), face.reshape(k, n)
        contact[:, 0], face[:, 0] = p[:, finger], f[:, finger]  # the target itself
        landed.append(contact)
        faces.append(face)
    return _Landed(np.stack(landed), np.stack(faces), np.stack(aimed), u, frame, offsets)


@dataclass(frozen=True)
class _Patches:
    """The patch of each landing point, as :class:`pinchmatch.grasp.curvature.PatchGeometry` names
    it."""

    normal: np.ndarray
    kappa_max_per_m: np.ndarray
    kappa_min_per_m: np.ndarray
    dir_max: np.ndarray


_PATCH_FIELDS = tuple(f.name for f in dataclasses.fields(_Patches))


def _field_patches(candidates: Candidates, poses: np.ndarray, landed: _Landed, settings,
                   spacing_mm: float | None) -> _Patches:
    """The patch at each landing point of ``poses`` (``landed``, in its (F, k, n) order, flattened):
    fitted at each one (``spacing_mm`` None), or once per cell of a grid of that spacing and of the
    faces' normals and shared by the cell's points. A target's patch is its candidate's own (fitted
    the same way when the candidate was checked); a cell holding a target takes its first target's,
    any other cell is fitted at its first point."""
    context = candidates.obj.context
    points, faces = landed.points.reshape(-1, 3), landed.faces.reshape(-1)
    fingers, k, n = landed.points.shape[:3]
    target = np.zeros((fingers, k, n), dtype=bool)
    target[:, :, 0] = True
    target = target.ravel()
    own = {f: np.swapaxes(getattr(candidates.pinches, "normals" if f == "normal" else f)[poses], 0,
                          1)
           for f in _PATCH_FIELDS}  # (F, k, ...) each target's, in the landing order
    normals = context.face_normals[np.maximum(faces, 0)]
    if spacing_mm is None or not spacing_mm >= MIN_CELL_MM:
        # a grid finer than that fits every point anyway
        inverse = np.arange(len(points))
    else:
        # a cell per place and facing (normals binned about 30 degrees wide): across an edge, each
        # face its own
        cells = np.concatenate([np.floor(points / spacing_mm), np.round(2.0 * normals)],
                               axis=1).astype(np.int64)
        inverse = np.unique(cells, axis=0, return_inverse=True)[1].ravel()
    # per cell: its targets first, then in order
    order = np.lexsort((np.arange(len(points)), ~target, inverse))
    first = order[np.r_[0, np.flatnonzero(np.diff(inverse[order])) + 1]] if len(order) else order
    fit = first[~target[first]]
    geom = patches(context, points[fit], normals[fit], settings)
    out = {}
    for f in _PATCH_FIELDS:
        values = np.empty((len(points),) + own[f].shape[2:])
        values[target] = own[f].reshape((-1,) + own[f].shape[2:])
        values[fit] = getattr(geom, f)
        out[f] = values[first][inverse]  # the cells come in order: cell c's first point is first[c]
    return _Patches(**out)


def _tables(candidates: Candidates, landed: _Landed, geom, radius_mm: float, axis_deg: float,
            rings) -> LandingTable:
    """The :class:`LandingTable` s of the poses ``landed`` holds, their landing points' patches
    ``geom`` (arrays of F·k·n, in ``landed.points``' order): every combination of one landing
    point per finger."""
    fingers, k, n, _ = landed.points.shape
    normal = geom.normal.reshape(fingers, k, n, 3)
    kmax, kmin = geom.kappa_max_per_m.reshape(fingers, k, n), geom.kappa_min_per_m.reshape(fingers,
                                                                                           k, n)
    dmax = geom.dir_max.reshape(fingers, k, n, 3)
    idx = landing_combos(n, fingers)
    combos = idx.shape[1]
    m = k * combos

    def pair(a: np.ndarray) -> np.ndarray:  # (F, k, n, ...) per finger -> (k·n^F, F, ...)
        return np.stack([a[f][:, idx[f]] for f in range(fingers)],
                        axis=2).reshape((m, fingers) + a.shape[3:])

    points = pair(landed.points)
    kind = type(candidates.pinches)
    pairs = kind(points=points, normals=pair(normal), face_index=pair(landed.faces),
                 kappa_max_per_m=pair(kmax), kappa_min_per_m=pair(kmin),
                 dir_max=pair(dmax), feasible=np.ones(m, dtype=bool),
                 broken=np.zeros((m, len(kind.rules)), dtype=bool),
                 snap_distance_mm=np.zeros((m, fingers)), approach=np.full((m, 3), np.nan),
                 approach_clearance_mm=np.full(m, np.nan))
    rows = feature_table(grasp_features(pairs, candidates.obj.props)).reshape(k, combos, fingers,
                                                                              -1)
    met = landed.faces >= 0
    hit = np.logical_and.reduce([met[f][:, idx[f]] for f in range(fingers)])
    # the axis tolerance on where the fingers land; a finger that meets nothing, where it was aimed
    ends = np.where(met[..., None], landed.points, landed.aimed)
    # (k, n^F, 3)
    axis = np.mean([ends[f][:, idx[f]] for f in range(1, fingers)], axis=0) - ends[0][:, idx[0]]
    cos = np.einsum("kpd,kd->kp", axis, landed.line) / np.maximum(np.linalg.norm(axis, axis=2),
                                                                  1e-300)
    within = cos >= math.cos(math.radians(axis_deg)) - 1e-12
    within[:, 0] = True  # the nominal landing is the match itself
    w = ring_weights(radius_mm, rings)
    # a tripod's two fingers land as one
    weights = np.where(within, (w[idx[0]] * w[idx[1]])[None], 0.0)
    angles = np.arctan2(landed.offsets[:, 1], landed.offsets[:, 0])
    ring = np.concatenate([[0]] + [np.full(c, r + 1) for r, c in enumerate(rings)])
    angles = np.where(ring == 0, 0.0, angles)
    return LandingTable(points.reshape(k, combos, fingers, 3), rows, hit, weights, landed.frame,
                        np.broadcast_to(angles, (k, n)), np.broadcast_to(ring, (k, n)))


def landing_tables(candidates: Candidates, poses, radius_mm: float, settings, *,
                   axis_deg: float = LANDING_AXIS_DEG, rings=RING_POINTS) -> LandingTable:
    """The landings of each of ``poses`` (k,) on its own object (see the module notes), stacked:
    every field of :class:`LandingTable` with a leading axis of k; vectorised over the poses."""
    landed = _land(candidates, np.asarray(poses, dtype=np.int64), radius_mm, axis_deg, rings)
    geom = _field_patches(candidates, np.asarray(poses, dtype=np.int64), landed, settings, None)
    return _tables(candidates, landed, geom, radius_mm, axis_deg, rings)


def landing_table(candidates: Candidates, pose: int, radius_mm: float, settings, *,
                  axis_deg: float = LANDING_AXIS_DEG, rings=RING_POINTS) -> LandingTable:
    """The landings of ``pose`` on its own object (see the module notes)."""
    stacked = landing_tables(candidates, [pose], radius_mm, settings, axis_deg=axis_deg,
                             rings=rings)
    return _one_table(stacked, 0)


def _one_table(stacked: LandingTable, k: int) -> LandingTable:
    """Pose ``k``'s table of tables stacked by :func:`landing_tables`."""
    return LandingTable(*(getattr(stacked, f.name)[k] for f in dataclasses.fields(LandingTable)))


#: poses whose landings are made at once by :func:`landing_moments` (memory: about 0.2 MB a pose)
MOMENT_CHUNK = 128


def landing_moments(candidates: Candidates, radius_mm: float, settings, *, poses=None,
                    axis_deg: float = LANDING_AXIS_DEG, rings=RING_POINTS,
                    patch_spacing_mm: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """What each pose's landings feel like on its own object, as the mean and the variance of their
    feature-table rows: (k, 2, 9) each, weighed by the landing weights (:class:`LandingTable`) over
    the landings that touch, NaN entries (undefined ρ) left out. A landing where a finger meets
    nothing adds, in proportion to its weight, a spread of :data:`MISS_JND` JNDs of width to both
    patches. Over ``poses`` (default every one), ``MOMENT_CHUNK`` at a time. With
    ``patch_spacing_mm`` the landing points' patches are fitted once per cell of a grid of that
    spacing (shared by the cell's points, over every pose), not at each point."""
    poses = np.arange(len(candidates)) if poses is None else np.asarray(poses, dtype=np.int64)
    landed = _land(candidates, poses, radius_mm, axis_deg, rings)
    geom = _field_patches(candidates, poses, landed, settings, patch_spacing_mm)
    fingers, n = landed.points.shape[0], landed.points.shape[2]
    per_point = {f: getattr(geom, f).reshape((fingers, len(poses), n) + getattr(geom, f).shape[1:])
                 for f in _PATCH_FIELDS}
    mean = np.empty((len(poses), fingers, candidates.table.shape[-1]))
    var = np.empty_like(mean)
    for start in range(0, len(poses), MOMENT_CHUNK):
        sl = slice(start, start + MOMENT_CHUNK)
        part = poses[sl]
        chunk = _Landed(landed.points[:, sl], landed.faces[:, sl], landed.aimed[:, sl],
                        landed.line[sl], landed.frame[sl], landed.offsets)
        per_chunk = {f: per_point[f][:, sl].reshape((-1,) + per_point[f].shape[3:])
                     for f in _PATCH_FIELDS}
        chunk_geom = dataclasses.replace(geom, **per_chunk)
        t = _tables(candidates, chunk, chunk_geom, radius_mm, axis_deg, rings)
        w_all = t.weights / t.weights.sum(axis=1, keepdims=True)
        w = np.where(t.hit, w_all, 0.0)[:, :, None, None] * ~np.isnan(t.rows)  # (k, n², 2, 9)
        total = w.sum(axis=1)
        safe = np.where(total > 0, total, 1.0)
        rows = np.nan_to_num(t.rows)
        m = (w * rows).sum(axis=1) / safe
        v = (w * (rows - m[:, None]) ** 2).sum(axis=1) / safe
        target = candidates.table[part]
        m = np.where(total > 0, m, target)
        v = np.where(total > 0, v, 0.0)
        missed = (w_all * ~t.hit).sum(axis=1)  # (k,)
        width_jnd = np.maximum(WIDTH_JND_FRACTION * np.abs(m[:, :, 0]), WIDTH_JND_FLOOR_MM)
        v[:, :, 0] += missed[:, None] * (MISS_JND * width_jnd) ** 2
        mean[start:start + len(part)], var[start:start + len(part)] = m, v
    return mean, var


_LANDINGS: dict[int, tuple] = {}
#: landing tables an object keeps (about 0.13 MB each)
LANDING_MEMO_POSES = 2048


class FeltTables:
    """The landing tables of a match's objects. A table depends on its object and its pose's
    contacts alone, so each is made once per process (kept with its object, :func:`memo_of`)
    whichever match, search or grown list of candidates asks for it; the felt cost needs no new
    geometry per pair."""

    def __init__(self, radius_mm: float, settings):
        self.radius_mm, self.settings = float(radius_mm), settings
        #: the :class:`Felt` of choices felt already, by their search (kept alive by the caller) and
        #: pose pair
        self.felt: dict[tuple, Felt] = {}

    def _store(self, candidates: Candidates) -> dict:
        """The tables of ``candidates``' object for this radius and these settings, by
        :func:`~pinchmatch.match.candidates.pose_key`."""
        return memo_of(_LANDINGS, candidates.obj).setdefault(
            (self.radius_mm, self.settings, type(candidates.pinches).__name__), {})

    def table(self, candidates: Candidates, pose: int) -> LandingTable:
        store = self._store(candidates)
        key = pose_key(candidates.pinches, int(pose))
        if key not in store:
            self.prefetch(candidates, [pose])
        return store[key]

    def prefetch(self, candidates: Candidates, poses) -> None:
        """Make the tables of ``poses`` of ``candidates`` that are not made yet, at once (a table
        does not depend on which others are made with it); an object keeps its
        ``LANDING_MEMO_POSES`` newest."""
        store = self._store(candidates)
        missing = sorted({int(p) for p in poses
                          if pose_key(candidates.pinches, int(p)) not in store})
        if not missing:
            return
        stacked = landing_tables(candidates, missing, self.radius_mm, self.settings)
        for k, pose in enumerate(missing):
            store[pose_key(candidates.pinches, pose)] = _one_table(stacked, k)
        for key in list(store)[:max(len(store) - LANDING_MEMO_POSES, 0)]:  # the oldest first
            del store[key]


def _matched_points(t: LandingTable, v: LandingTable, R: np.ndarray) -> np.ndarray:
    """(P,) for each of the virtual table's points, the prop's point of the same ring nearest in
    angle once the registration ``R`` turns the virtual frame into the prop's."""
    turned = (np.cos(v.angles)[:, None] * (R @ v.frame[0]) + np.sin(v.angles)[:, None]
              * (R @ v.frame[1]))
    theta = np.arctan2(turned @ t.frame[1], turned @ t.frame[0])
    gap = np.abs(np.angle(np.exp(1j * (theta[:, None] - t.angles[None, :]))))
    gap = np.where(v.ring[:, None] == t.ring[None, :], gap, np.inf)
    return np.argmin(gap, axis=1)


@dataclass(frozen=True)
class Felt:
    """A choice's costs over its landings (the run's units): ``nominal``, ``expected`` (weighted
    mean), ``worst``; the chance that it is noticed on target, on average over the landings and at
    the worst; the criteria that reach 1 JND in some landing; ``landings`` and ``missed`` (pairs of
    landing points)."""

    nominal: float
    expected: float
    worst: float
    p_noticed_nominal: float
    p_noticed_expected: float
    p_noticed_worst: float
    criteria_noticeable: tuple
    landings: int
    missed: int

    def ranked(self, rank: str) -> float:
        """The cost ``--rank`` ranks by."""
        return {"nominal": self.nominal, "expected": self.expected, "worst": self.worst}[rank]

    def ranked_p_noticed(self, rank: str) -> float:
        """The chance that the ranked cost's difference is noticed: on target, for a landing drawn
        from the distribution, or at the worst landing."""
        return {"nominal": self.p_noticed_nominal, "expected": self.p_noticed_expected,
                "worst": self.p_noticed_worst}[rank]


def felt_cost(tangible: Candidates, virtual: Candidates, choice, model: CostModel,
              tables: FeltTables) -> Felt:
    """What ``choice`` costs over its landings (see the module notes)."""
    nominal = float(choice.cost_nominal)
    if tables.radius_mm == 0:
        p = p_noticed(tangible, virtual, choice, model)
        loud = tuple(c for c, row in criterion_table(tangible, virtual, choice, model).items()
                     if row["noticeable"])
        return Felt(nominal, nominal, nominal, p, p, p, loud, 1, 0)
    t = tables.table(tangible, choice.t_pose)
    v = tables.table(virtual, choice.v_pose)
    R = choice.transform[:3, :3]
    n, fingers = len(v.angles), v.points.shape[-2]
    match = _matched_points(t, v, R)
    idx = landing_combos(n, fingers)
    # each virtual landing in the prop's finger order, and the prop's points the fingers land on
    order = other_order(fingers) if choice.swapped else list(range(fingers))
    t_pair = np.ravel_multi_index((match[idx[order[0]]], match[idx[order[1]]]), (n, n))
    v_rows = v.rows[:, order]
    keep = np.flatnonzero(v.weights > 0)
    t_pair = t_pair[keep]
    hit = v.hit[keep] & t.hit[t_pair]
    weights = v.weights[keep] / v.weights[keep].sum()
    R_mass = seen_turn(tangible.obj, R, choice.redirect_terms is not None)
    terms, _ = pair_terms(tangible, virtual, t.rows[t_pair], v_rows[keep], model, R=R_mass,
                          t_points=t.points[t_pair], v_points=v.points[keep])
    scan = _scan_spread(tangible, virtual, choice, model) if model.scan_trust else None
    if scan is not None:
        terms = terms + scan  # the scans' spread: the same at every landing
    cost = np.asarray(model.pool(terms, extra=choice.redirect_terms, rest=choice.rest_jnd),
                      dtype=np.float64)
    if scan is None or not scan.any():
        cost[0] = nominal  # the nominal landing is the match itself, to the last bit
    miss = float(model.pool(np.full((1, len(CRITERIA)), MISS_JND ** 2)
                            * (np.arange(len(CRITERIA)) == 0))[0])
    cost = np.where(hit, cost, max(miss, float(cost[hit].max()) if hit.any() else miss))
    jnd = model.as_jnd()
    jnd_all = CostModel(normalize="jnd", criteria=CRITERIA, weights=dict.fromkeys(CRITERIA, 1.0))
    # the terms depend on the scales alone
    jnd_terms = terms if model.normalize == "jnd" else pair_terms(
        tangible, virtual, t.rows[t_pair], v_rows[keep], jnd_all, R=R_mass,
        t_points=t.points[t_pair], v_points=v.points[keep])[0] + (
        _scan_spread(tangible, virtual, choice, jnd_all) if model.scan_trust else 0.0)
    loud = tuple(c for k, c in enumerate(CRITERIA)
                 if c in model.criteria and (jnd_terms[hit, k] >= 1.0).any())
    # a miss is noticed
    chance = np.where(hit, jnd.p_noticed(jnd.pool(jnd_terms, extra=choice.redirect_terms)), 1.0)
    chance[0] = p_noticed(tangible, virtual, choice, model)
    worst = int(np.argmax(cost))
    return Felt(nominal, float(weights @ cost), float(cost[worst]), float(chance[0]),
                float(weights @ chance), float(chance[worst]), loud, int(len(keep)),
                int((~hit).sum()))


def _scan_spread(tangible: Candidates, virtual: Candidates, choice, model: CostModel) -> np.ndarray:
    """(8,) the contribution of both poses' spread at their objects' scan error, under
    ``--scan-trust`` (:mod:`pinchmatch.match.trust`; 0 where neither object is from a scan)."""
    t_var = scan_variance(tangible, [choice.t_pose])
    v_var = scan_variance(virtual, [choice.v_pose])
    if choice.swapped:
        v_var = v_var[:, other_order(v_var.shape[1])]
    return spread_terms(least(tangible.table[[choice.t_pose]], t_var), t_var, v_var,
                        mass_ratio(tangible, virtual), model)[0]
