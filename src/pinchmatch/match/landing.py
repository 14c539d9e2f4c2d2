"""Landing tolerance: the landing pattern and its record.

In the headset a pinch counts when each fingertip is within ``LANDING_MM`` of its target and the
pinch axis within ``LANDING_AXIS_DEG`` of the target's (the page's validation). A match whose cost
rises steeply within that tolerance feels different from what was promised. Matches are ranked and
reported by the felt cost of :mod:`pinchmatch.match.felt` (landing tables per pose, no new geometry
per pair; :class:`Landing` is its record); the tests check it against an exact reference
(``tests/landing_reference.py``): the prop's contacts found by closing the fingers along every
landing's own line, each pair's geometry anew (about ten times the time), the landings weighed
alike.

Model (the placement does not move while the hand closes):

- each finger lands on the virtual object's surface within the radius of its target: the
  target, ``RING_POINTS[0]`` points on a ring at half the radius and ``RING_POINTS[1]`` on a ring
  at the radius, in the plane perpendicular to the pinch line, each put on the surface where a
  finger closing along the pinch line meets it (as refinement's moves are: from the pinch and
  the object's axis, never the file's frame);
- every pair of landing points whose axis is within the axis tolerance is a landing;
- there the hand sees the virtual pinch through the landing points, and feels the tangible where
  its fingers stop: closing along the same line, registered into the tangible's frame, each
  finger stops at the first tangible surface facing it. Where a finger meets no tangible surface
  within reach the landing is a *miss*: noticed for certain, it costs as a width difference of
  ``MISS_JND`` (or the worst landing that touched, if that costs more) and counts in the mean and
  the worst;
- the landing's cost is the run's cost of the felt against the seen pinch, with the mass offset
  taken under the match's own registration.

The nominal landing (both on target) costs what the match costs. ``cost_worst`` is the largest
cost over the landings, ``cost_mean`` their mean, ``p_noticed_worst`` the chance that the worst
is noticed; ``criteria_noticeable`` names the criteria that reach 1 JND in some landing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


#: the headset's tolerance: each fingertip within this of its target (mm) ...
LANDING_MM = 5.0
#: ... and the pinch axis within this of the target's (degrees)
LANDING_AXIS_DEG = 14.0
#: landing points per finger besides the target: on a ring at half the radius, and at the radius
RING_POINTS = (8, 16)
#: the largest radius ``--landing-mm`` takes (mm): a fingertip pad is about 16 mm across
MAX_LANDING_MM = 20.0
#: a landing where a finger meets no surface costs as a width difference of this many JND (noticed
#: for certain: 1 - 2^-(3^3.5), over 0.99999), or the worst landing's cost if that is more
MISS_JND = 3.0


@dataclass(frozen=True)
class Landing:
    """A match's cost over its landings (see the module's notes); costs dimensionless, as the
    match's."""

    radius_mm: float
    axis_deg: float
    cost_nominal: float
    cost_mean: float
    cost_worst: float
    p_noticed_worst: float
    criteria_noticeable: tuple
    landings: int
    missed: int

    def as_dict(self) -> dict:
        return {"radius_mm": self.radius_mm, "axis_deg": self.axis_deg,
                "cost_nominal": self.cost_nominal, "cost_mean": self.cost_mean,
                "cost_worst": self.cost_worst, "p_noticed_worst": self.p_noticed_worst,
                "noticeable_worst": bool(self.p_noticed_worst >= 0.5),
                "criteria_noticeable": list(self.criteria_noticeable), "landings": self.landings,
                "missed": self.missed}


def disc_offsets(radius_mm: float, rings=RING_POINTS) -> np.ndarray:
    """(1 + Σ rings, 2) offsets in a disc: the centre, then each ring's points evenly around it,
    the rings at ``radius·(i+1)/len(rings)``."""
    out = [np.zeros((1, 2))]
    for i, count in enumerate(rings):
        angle = 2.0 * np.pi * (np.arange(count) + 0.5 * (i % 2)) / count
        out.append(radius_mm * (i + 1) / len(rings)
                   * np.stack([np.cos(angle), np.sin(angle)], axis=1))
    return np.concatenate(out)
