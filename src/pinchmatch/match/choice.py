"""A choice: one registered pose pair of a virtual object on a tangible, and its two grasps.

The search (:mod:`pinchmatch.match.search`) finds choices, the match ranks them
(:mod:`pinchmatch.match.scene`) and the documents write them (matches.json's ``best`` and
``alternatives``); :func:`pinch_distance` tells two grasps apart whatever their finger order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..grasp.spread import other_order
from .candidates import Candidates


def pinch_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Order-free distance between grasps a (k, F, 3) and b (F, 3): the largest contact
    displacement, in the nearer of the two finger orders
    (:func:`pinchmatch.grasp.spread.other_order`)."""
    direct = np.linalg.norm(a - b, axis=2).max(axis=1)
    crossed = np.linalg.norm(a - b[other_order(len(b))], axis=2).max(axis=1)
    return np.minimum(direct, crossed)


@dataclass(frozen=True)
class Pose:
    """One grasp of a choice, in its object's frame (mm), as matches.json names it: the contacts
    ``contacts_mm`` (F, 3) (a pinch's p1 and p2; a tripod's thumb, index and middle), their outward
    ``normals`` (F, 3), and the hand's ``approach`` (3,) unit direction from the fingertips towards
    the palm (NaN for a pose given without one). A virtual pose is in the tangible's finger order:
    its first contact meets the tangible's first, and so on."""

    contacts_mm: np.ndarray
    normals: np.ndarray
    approach: np.ndarray

    @property
    def p1_mm(self) -> np.ndarray:
        return self.contacts_mm[0]

    @property
    def p2_mm(self) -> np.ndarray:
        return self.contacts_mm[1]

    @property
    def n1(self) -> np.ndarray:
        return self.normals[0]

    @property
    def n2(self) -> np.ndarray:
        return self.normals[1]

    @classmethod
    def of(cls, candidates: Candidates, i: int, swapped: bool = False) -> "Pose":
        p, n = candidates.pinches.points[i], candidates.pinches.normals[i]
        if swapped:
            other = other_order(len(p))
            p, n = p[other], n[other]
        return cls(p.copy(), n.copy(), candidates.pinches.approach[i].copy())


@dataclass(frozen=True)
class Choice:
    """One registered pose pair and its exact evaluation.

    Virtual object ``virtual``'s pose ``v_pose`` placed on tangible ``tangible``'s pose ``t_pose``
    (``int`` indices into the scene's lists and into each object's :class:`Candidates`).

    - ``terms``: ``(8,) float64``, dimensionless, each criterion's contribution (mean over its
      entries of (difference / scale)², in the run's normalisation; with ``jnd``, 1 is just
      noticeable), in the order of :data:`pinchmatch.match.cost.CRITERIA`, computed for every
      criterion (those not in use weigh 0);
    - ``cost``: ``float``, dimensionless, the cost the match ranks by (``--rank``: the expected cost
      over the landings by default, :mod:`pinchmatch.match.felt`); ``cost_nominal`` the cost with
      the fingers on their targets: the terms pooled by the model (:meth:`CostModel.pool`), in JND
      under the default ``quick`` pooling, Σ weight x term under ``sum`` (the search's, exact);
      ``p_noticed`` the chance that the ranked difference is noticed (None as the search finds it);
    - ``swapped``: ``bool``, the virtual pose's p1 lies on the tangible's p2;
    - ``transform``: ``(4, 4) float64``, the rigid transform taking the virtual object's frame (mm)
      to the tangible's, so that the fingertips meet (under ``placement="fixed"``, the hand's warp);
    - ``placement``: ``(4, 4) float64``, where the virtual object is as seen from the tangible: the
      transform, or under ``placement="fixed"`` the level's (world to the prop's frame);
    - ``flipped``: ``bool``, the placement turns the virtual object's up direction more than 90°
      from the tangible's;
    - ``tangible_pose``, ``virtual_pose``: the two pinches (:class:`Pose`), so that a choice carries
      itself (``t_pose`` and ``v_pose`` index the match's candidates, refined ones included);
    - ``mass_delta_mm``: ``(3,) float64``, the centre-of-mass offset from the pinch midpoint as seen
      (virtual, registered, its mass relative to the tangible's) minus as felt (tangible), in the
      tangible's frame, mm;
    - ``tangible_name``, ``virtual_name``: ``str``, the objects' names (a manifest's ``name``, a
      level node's, else the file's);
    - ``redirect_terms``: ``(2,) float64``, the hand redirection's contributions to ``cost`` under
      ``placement="fixed"`` (:mod:`pinchmatch.match.redirect`), else ``None``;
    - ``rest_gap_mm``: the placed virtual object's lowest point over the prop's support, mm
      (negative: sunk into it), or None where it is not shown on a support
      (:mod:`pinchmatch.match.rest`); ``rest_jnd`` what the gap adds to ``cost`` (JND-equivalents; 0
      where nothing is charged);
    - ``approach_elevation_deg``, ``approach_azimuth_deg``: the hand's approach to the tangible
      pinch seen from where the user stands (:mod:`pinchmatch.match.comfort`): above the table's
      horizontal, and away from the direction to the user (0: straight from the user); None where
      the prop is held in the hand or the pose has no approach.
    """

    virtual: int
    tangible: int
    t_pose: int
    v_pose: int
    cost: float
    terms: np.ndarray
    swapped: bool
    transform: np.ndarray
    flipped: bool
    mass_delta_mm: np.ndarray
    tangible_name: str = ""
    virtual_name: str = ""
    redirect_terms: np.ndarray | None = None
    placement: np.ndarray | None = None
    tangible_pose: Pose | None = None
    virtual_pose: Pose | None = None
    cost_nominal: float | None = None
    p_noticed: float | None = None
    rest_gap_mm: float | None = None
    rest_jnd: float = 0.0
    approach_elevation_deg: float | None = None
    approach_azimuth_deg: float | None = None

    def __post_init__(self):
        if self.cost_nominal is None:  # as the search finds it: ranked by its cost on target
            object.__setattr__(self, "cost_nominal", self.cost)
