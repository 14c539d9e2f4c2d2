"""The felt cost: what a match costs over where a guided pinch's fingers land, not at its targets alone.

In the headset a pinch counts when each fingertip is within ``radius_mm`` (``--landing-mm``, 5 mm) of its
target and the pinch axis within ``LANDING_AXIS_DEG`` (14°) of the target's. Where, inside that region,
do guided fingers land? Pointing studies give the spread of a guided fingertip's end point as a roughly
isotropic two-dimensional Gaussian around the target; how wide it is depends on the guidance. The
headset's acceptance radius is a tolerance chosen to accept nearly every deliberate pinch, so we take it
as two standard deviations: **each finger lands with an isotropic Gaussian spread of σ = radius / 2,
truncated to the acceptance disc** (a landing outside it is refused and tried again), the two fingers
independently, the pairs kept where the axis is within the tolerance. This is a documented choice, not a
published figure (docs/matching.md); ``--landing-mm`` sets the radius and with it the spread.

Discretisation (:mod:`pinchmatch.match.landing`'s pattern): per finger the target, 8 points on a ring at
r/2 and 16 at r, in the plane perpendicular to the pinch line, each put on the surface where a finger
closing along the pinch line meets it. Each point carries the truncated Gaussian's mass of the annulus it
stands for (0 to r/4, r/4 to 3r/4, 3r/4 to r), shared by its ring's points; a pair of landing points
weighs the product of its fingers' weights, renormalised over the pairs within the axis tolerance.

**Per pose, once** (:class:`LandingTable`, memoised per object in :class:`FeltTables`): its 25 landing
points per finger, their patches (normal, principal curvatures) and the feature rows of all 625 pairs.
**Per pose pair, no new geometry:** the hand lands on the prop at the prop's own landing points; the eye
sees the corresponding points of the virtual object, the points of its table that the pair's registration
carries nearest to them (each of the virtual object's ring points, turned by the registration into the
prop's frame, is matched to the prop's ring point of the same ring nearest in angle: within half a ring
step, 22.5° or 11.25°). Each landing costs the run's cost of felt against seen (the mass offset under the
match's own placement, a planned redirection as the match's); a landing where a finger meets no surface
on either object is a miss, noticed for certain (:data:`pinchmatch.match.landing.MISS_JND`).

:func:`felt_costs` gives, per choice, the nominal cost, the expected cost (the weighted mean over the
landings) and the worst; the match ranks by one of them (``--rank``, :mod:`pinchmatch.match.scene`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..grasp.features import pinch_features
from ..grasp.pinches import Pinches, patches
from .candidates import Candidates, pair_terms
from .cost import CRITERIA, CostModel, feature_table
from .landing import LANDING_AXIS_DEG, MISS_JND, RING_POINTS, disc_offsets
from .redirect import world_pose
from .refine import close_fingers, move_directions
from .search import criterion_table, p_noticed

#: the landing spread's standard deviation, as a share of the acceptance radius
SIGMA_SHARE = 0.5


def ring_weights(radius_mm: float, rings=RING_POINTS, sigma_share: float = SIGMA_SHARE) -> np.ndarray:
    """(1 + Σ rings,) the weight of each point of :func:`disc_offsets`: the mass, under an isotropic Gaussian of
    σ = sigma_share · radius truncated to the disc, of the annulus the point's ring stands for, shared
    equally by the ring's points; the weights sum to 1."""
    if radius_mm <= 0:
        return np.ones(1)
    n = len(rings)
    edges = [0.0] + [(i + 0.5) / n for i in range(n)] + [1.0]  # as shares of the radius: the weights do not
    mass = np.diff([1.0 - math.exp(-e * e / (2.0 * sigma_share ** 2)) for e in edges])  # depend on its size
    weights = np.concatenate([[mass[0]]] + [np.full(count, mass[i + 1] / count) for i, count in enumerate(rings)])
    return weights / weights.sum()


@dataclass(frozen=True)
class LandingTable:
    """One pose's landings (``P = 1 + Σ rings`` points per finger, every one of the ``P²`` pairs):

    - ``points`` (P², 2, 3) mm and ``rows`` (P², 2, 9) the feature-table rows of each pair, in the pose's
      finger order; ``hit`` (P²,) both fingers met a surface;
    - ``weights`` (P²,) the pair's landing weight, 0 where its axis is beyond the tolerance (not
      normalised: a table's hits and misses share them);
    - ``frame`` (2, 3): the directions the rings are laid out along (:func:`move_directions`), and
      ``angles`` (P,) each point's angle in that frame (the target's is 0), ``ring`` (P,) its ring (0: the
      target)."""

    points: np.ndarray
    rows: np.ndarray
    hit: np.ndarray
    weights: np.ndarray
    frame: np.ndarray
    angles: np.ndarray
    ring: np.ndarray


def landing_table(candidates: Candidates, pose: int, radius_mm: float, settings, *,
                  axis_deg: float = LANDING_AXIS_DEG, rings=RING_POINTS) -> LandingTable:
    """The landings of ``pose`` on its own object (see the module notes)."""
    obj = candidates.obj
    p = candidates.pinches.points[pose]
    f = candidates.pinches.face_index[pose]
    frame = move_directions(p[None], obj.props.principal_axis)[0]
    offsets = disc_offsets(radius_mm, rings)
    u = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0])
    back = radius_mm * math.tan(math.radians(axis_deg)) + radius_mm + 1.0
    landed, faces, aimed = [], [], []
    for k, toward in ((0, u), (1, -u)):
        aimed.append(p[k] + offsets @ frame)
        contact, face = close_fingers(obj.context, aimed[-1], np.broadcast_to(toward, (len(offsets), 3)).copy(), back)
        contact[0], face[0] = p[k], f[k]  # the target itself
        landed.append(contact)
        faces.append(face)
    n = len(offsets)
    met = [fc >= 0 for fc in faces]
    # patches once per landing point (a pair's features are made of its two points')
    geom = patches(obj.context, np.concatenate(landed), obj.context.face_normals[np.maximum(np.concatenate(faces), 0)],
                   settings)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    i, j = i.ravel(), j.ravel()
    normal = geom.normal.reshape(2, n, 3)
    kmax, kmin = geom.kappa_max_per_m.reshape(2, n), geom.kappa_min_per_m.reshape(2, n)
    dmax = geom.dir_max.reshape(2, n, 3)
    points = np.stack([landed[0][i], landed[1][j]], axis=1)
    pairs = Pinches(points=points, normals=np.stack([normal[0][i], normal[1][j]], axis=1),
                    face_index=np.stack([faces[0][i], faces[1][j]], axis=1),
                    kappa_max_per_m=np.stack([kmax[0][i], kmax[1][j]], axis=1),
                    kappa_min_per_m=np.stack([kmin[0][i], kmin[1][j]], axis=1),
                    dir_max=np.stack([dmax[0][i], dmax[1][j]], axis=1), feasible=np.ones(n * n, dtype=bool),
                    broken=np.zeros((n * n, 7), dtype=bool), snap_distance_mm=np.zeros((n * n, 2)),
                    approach=np.full((n * n, 3), np.nan), approach_clearance_mm=np.full(n * n, np.nan))
    rows = feature_table(pinch_features(pairs, obj.props))
    hit = met[0][i] & met[1][j]
    # the axis tolerance on where the fingers land; a finger that meets nothing, where it was aimed
    ends = [np.where(m[:, None], c, a) for m, c, a in zip(met, landed, aimed)]
    axis = ends[1][j] - ends[0][i]
    cos = axis @ u / np.maximum(np.linalg.norm(axis, axis=1), 1e-300)
    within = cos >= math.cos(math.radians(axis_deg)) - 1e-12
    within[0] = True  # the nominal landing is the match itself
    w = ring_weights(radius_mm, rings)
    weights = np.where(within, w[i] * w[j], 0.0)
    angles = np.arctan2(offsets[:, 1], offsets[:, 0])
    ring = np.concatenate([[0]] + [np.full(c, k + 1) for k, c in enumerate(rings)])
    return LandingTable(points, rows, hit, weights, frame, np.where(ring == 0, 0.0, angles), ring)


class FeltTables:
    """The landing tables of a match's objects, each pose's computed once (the felt cost needs no new
    geometry per pair)."""

    def __init__(self, radius_mm: float, settings):
        self.radius_mm, self.settings = float(radius_mm), settings
        self._tables: dict[tuple[int, int], tuple[Candidates, LandingTable]] = {}

    def table(self, candidates: Candidates, pose: int) -> LandingTable:
        key = (id(candidates), int(pose))  # the candidates are kept with their tables: an id is never reused
        if key not in self._tables:
            self._tables[key] = (candidates, landing_table(candidates, pose, self.radius_mm, self.settings))
        return self._tables[key][1]


def _matched_points(t: LandingTable, v: LandingTable, R: np.ndarray) -> np.ndarray:
    """(P,) for each of the virtual table's points, the prop's point of the same ring nearest in angle once
    the registration ``R`` turns the virtual frame into the prop's."""
    turned = (np.cos(v.angles)[:, None] * (R @ v.frame[0]) + np.sin(v.angles)[:, None] * (R @ v.frame[1]))
    theta = np.arctan2(turned @ t.frame[1], turned @ t.frame[0])
    gap = np.abs(np.angle(np.exp(1j * (theta[:, None] - t.angles[None, :]))))
    gap = np.where(v.ring[:, None] == t.ring[None, :], gap, np.inf)
    return np.argmin(gap, axis=1)


@dataclass(frozen=True)
class Felt:
    """A choice's costs over its landings (the run's units): ``nominal``, ``expected`` (weighted mean),
    ``worst``; the chance that it is noticed on target, on average over the landings and at the worst;
    the criteria that reach 1 JND in some landing; ``landings`` and ``missed`` (pairs of landing points)."""

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
        """The chance that the ranked cost's difference is noticed: on target, for a landing drawn from the
        distribution, or at the worst landing."""
        return {"nominal": self.p_noticed_nominal, "expected": self.p_noticed_expected,
                "worst": self.p_noticed_worst}[rank]


def felt_cost(tangible: Candidates, virtual: Candidates, choice, model: CostModel, tables: FeltTables) -> Felt:
    """What ``choice`` costs over its landings (see the module notes)."""
    nominal = float(choice.cost_nominal)
    if tables.radius_mm == 0:
        p = p_noticed(tangible, virtual, choice, model)
        loud = tuple(c for c, row in criterion_table(tangible, virtual, choice, model).items() if row["noticeable"])
        return Felt(nominal, nominal, nominal, p, p, p, loud, 1, 0)
    t = tables.table(tangible, choice.t_pose)
    v = tables.table(virtual, choice.v_pose)
    R = choice.transform[:3, :3]
    n = len(v.angles)
    match = _matched_points(t, v, R)
    i, j = np.divmod(np.arange(n * n), n)
    # the virtual pair (i, j) in the prop's finger order, and the prop's points the fingers land on
    if choice.swapped:
        t_pair = match[j] * n + match[i]
        v_rows = v.rows[:, ::-1]
    else:
        t_pair = match[i] * n + match[j]
        v_rows = v.rows
    keep = np.flatnonzero(v.weights > 0)
    t_pair = t_pair[keep]
    hit = v.hit[keep] & t.hit[t_pair]
    weights = v.weights[keep] / v.weights[keep].sum()
    R_mass = R if choice.redirect_terms is None else world_pose(tangible.obj.spec)[0].T
    terms, _ = pair_terms(tangible, virtual, t.rows[t_pair], v_rows[keep], model, R=R_mass,
                          t_points=t.points[t_pair], v_points=v.points[keep])
    cost = np.asarray(model.pool(terms, choice.redirect_terms), dtype=np.float64)
    cost[0] = nominal  # the nominal landing is the match itself, to the last bit
    miss = float(model.pool(np.full((1, len(CRITERIA)), MISS_JND ** 2) * (np.arange(len(CRITERIA)) == 0))[0])
    cost = np.where(hit, cost, max(miss, float(cost[hit].max()) if hit.any() else miss))
    jnd = model.as_jnd()
    jnd_all = CostModel(normalize="jnd", criteria=CRITERIA, weights=dict.fromkeys(CRITERIA, 1.0))
    jnd_terms, _ = pair_terms(tangible, virtual, t.rows[t_pair], v_rows[keep], jnd_all, R=R_mass,
                              t_points=t.points[t_pair], v_points=v.points[keep])
    loud = tuple(c for k, c in enumerate(CRITERIA)
                 if c in model.criteria and (jnd_terms[hit, k] >= 1.0).any())
    chance = np.where(hit, jnd.p_noticed(jnd.pool(jnd_terms, choice.redirect_terms)), 1.0)  # a miss is noticed
    chance[0] = p_noticed(tangible, virtual, choice, model)
    worst = int(np.argmax(cost))
    return Felt(nominal, float(weights @ cost), float(cost[worst]), float(chance[0]), float(weights @ chance),
                float(chance[worst]), loud, int(len(keep)), int((~hit).sum()))
