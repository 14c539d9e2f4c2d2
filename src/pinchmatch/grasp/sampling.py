"""Sampling about ``count`` feasible pinches spread over every graspable region.

Candidates: contacts p1 drawn area-uniformly (seeded), a direction drawn
uniformly within the friction cone around -n1, and as p2 every point where
the ray along it leaves the solid within the largest width. The cheap rules
of :mod:`pinches` prune them with triangle normals; in rounds, the next picks
in a spread order get the reach search, fitted patches and the full check
with patch normals.

The rounds themselves, the width strata before them and the local draws where few places are
graspable, are the loop every grasp shares (:mod:`rounds`); this module gives it a pinch's draw,
check and refusal (:data:`PINCH`).
"""

from __future__ import annotations

import logging
import re

import numpy as np

from .curvature import tangent_frame
from .pinches import (PREFILTER_MARGIN_DEG, RULES, PinchSettings, Pinches, assemble, cheap_broken,
                      patches, reach_rule, rule_table)
from .rounds import GraspKind, nested_sample, sample_rounds, uniform_contacts
from ..mesh.surface import SurfaceContext

log = logging.getLogger(__name__)

#: candidates drawn per requested pinch in the first, area-uniform round
OVERSAMPLE = 6
#: rounds of checking before giving up on reaching the count
MAX_ROUNDS = 12
#: all rounds together draw at most this many candidates per requested pinch
MAX_DRAW_FACTOR = 40
#: a ray from p1 is followed through at most this many surfaces (exits are candidate p2)
MAX_EXITS = 8


def cone_directions(normals: np.ndarray, half_angle_deg: float, rng) -> np.ndarray:
    """Unit directions uniform in solid angle within the cone around -normal."""
    n = len(normals)
    cos_t = 1.0 - rng.random(n) * (1.0 - np.cos(np.radians(half_angle_deg)))
    sin_t = np.sqrt(1.0 - cos_t**2)
    phi = rng.random(n) * 2.0 * np.pi
    t1, t2 = tangent_frame(normals)
    return -(cos_t[:, None] * normals + sin_t[:, None]
             * (np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2))


def _draw(context, p1, face1, settings, rng, rejected):
    """Candidates from contacts p1: exits along directions in the friction cone, cheap rules
    applied."""
    n1 = context.face_normals[face1]
    d = cone_directions(n1, settings.friction_cone_deg, rng)
    ray, face2, dist = context.exits(p1, d, max_distance=settings.max_width_mm * (1 + 1e-6),
                                     max_hits=MAX_EXITS)
    n_rays = len(p1)
    # a ray with no exit within the largest width offers no second contact
    rejected["width"] += int(n_rays - len(np.unique(ray)))
    points = np.stack([p1[ray], p1[ray] + dist[:, None] * d[ray]], axis=1)
    faces = np.stack([face1[ray], face2], axis=1)
    normals = context.face_normals[faces]
    broken = cheap_broken(context, points, normals, settings,
                          settings.friction_cone_deg + PREFILTER_MARGIN_DEG)
    _count_first(broken, rejected)
    keep = ~broken.any(axis=1)
    return points[keep], faces[keep]


def _count_first(broken, rejected):
    """Count each rejected candidate once, under the first rule it breaks."""
    bad = broken.any(axis=1)
    first = np.argmax(broken, axis=1)
    for j, rule in enumerate(RULES):
        rejected[rule] += int((bad & (first == j)).sum())


def _contacts(points: np.ndarray) -> np.ndarray:
    """Both contacts of each pinch start local draws."""
    return points.reshape(-1, 3)


def cheap_candidates(context, n: int, settings: PinchSettings, rng, rejected: dict | None = None):
    """Candidates from ``n`` contacts drawn area-uniformly: (m, 2, 3) points and (m, 2) triangles of
    those that keep the cheap rules (with triangle normals), as the sampler's first round draws
    them; ``rejected`` counts the others per rule."""
    p1, f1 = uniform_contacts(context, n, rng)
    return _draw(context, p1, f1, settings, rng, dict.fromkeys(RULES, 0) if rejected is None
                 else rejected)


def sample_pinches(
    context: SurfaceContext,
    *,
    settings: PinchSettings = PinchSettings(),
    source: str = "mesh",
) -> Pinches:
    """About ``settings.count`` feasible pinches spread over every graspable region.

    Candidates: contacts p1 drawn area-uniformly (seeded), a direction drawn
    uniformly within the friction cone around -n1, and as p2 every point
    where the ray along it leaves the solid within the largest width. The
    cheap rules prune them with triangle normals; a farthest-point order
    spreads the survivors; in rounds, the next picks get the reach search,
    fitted patches and the full check with patch normals.

    When the first picks show that few places are graspable (a bowl's rim, a
    mug's handle), later rounds draw new candidates near the contacts of the
    feasible pinches found so far, and the spread order, which keeps its
    distances to every earlier pick, takes them in turn. All rounds together
    draw at most ``MAX_DRAW_FACTOR`` candidates per requested pinch.

    A count above ``NESTED_ABOVE`` is sampled nested (:func:`nested_sample`): its first pinches are
    the sample of half the count, so a larger count's sample holds a smaller one's.

    Parameters
    ----------
    context : SurfaceContext
        The object's surface.
    settings : PinchSettings
        The count, the seed and the rules a pinch must pass.
    source : str
        What messages call the object (its file).

    Returns
    -------
    Pinches
        About ``settings.count`` feasible pinches, spread, with their patches.

    Raises
    ------
    NoFeasiblePinchError
        No candidate passes; the message says how many each rule rejected.

    Examples
    --------
    >>> from pinchmatch import analyze_object
    >>> obj = analyze_object(box_stl)
    >>> pinches = sample_pinches(obj.context, settings=PinchSettings(count=50, seed=0))
    >>> len(pinches), bool(pinches.feasible.all())
    (50, True)
    """
    return nested_sample(_sample_pinches, context, settings, source)


def _sample_pinches(context, settings, source, seen=None, stream=()) -> Pinches:
    return sample_rounds(PINCH, context, settings, source, seen, stream)


def _check_picks(context, points, faces, settings, rejected, precheck: bool = True) -> Pinches:
    """The feasible ones among spread picks: every rule with the normals of fitted patches.

    With ``precheck``, the reach search runs first with triangle normals, so that picks no hand
    gets to are not fitted (the final check then only confirms the approach found)."""
    approach = None
    if precheck:
        early = reach_rule(context, points, context.face_normals[faces], settings)
        rejected["reach"] += int((~early.ok).sum())
        points, faces, approach = points[early.ok], faces[early.ok], early.approach[early.ok]
    geom = patches(context, points, context.face_normals[faces], settings)
    broken, found = rule_table(context, points, geom.normal.reshape(-1, 2, 3), geom.valid, settings,
                               approach=approach)
    _count_first(broken, rejected)
    part = assemble(points, faces, geom, broken, found, rejected)
    return part.subset(part.feasible)


_RULE_HINTS = {
    "region": "few contacts fall where the object's regions allow: check exclude and only in its "
              "manifest",
    "width": "the object may be too wide or thin for the width limits: check "
             "--min-width-mm/--max-width-mm and --units",
    "antipodal": "no opposite surfaces face each other: try a wider --friction-cone-deg",
    "clearance": "a fingertip does not fit: try a smaller --fingertip-radius-mm",
    "reach": "no approach lets both fingers get to the contacts: try a shorter --finger-length-mm, "
             "a thinner --finger-radius-mm, or a larger --approach-tilt-deg or --finger-splay-deg",
    "patch": "too little surface around the contacts: try a smaller --patch-radius-mm",
    "surface": "the points are far from the surface",
}


#: where an object stands on a support, what its hint says when the fingers cannot get to it
_STANDING_HINTS = {
    "clearance": "it stands too low on its table for a fingertip to get beside it (thinner than "
                 "two fingertips): "
                 "if it is held in the hand, give support = \"none\" in its manifest or --support "
                 "none",
    "reach": "no approach from above its table lets both fingers get to the contacts: if it is "
             "held in the hand, give support = \"none\" in its manifest or --support none",
}


def _no_pinch_message(source, n_cand, rejected, settings, standing: bool = False) -> str:
    parts = [f"{rule} {count}" for rule, count in rejected.items() if count]
    worst = max(rejected, key=rejected.get)
    hint = _STANDING_HINTS.get(worst, _RULE_HINTS[worst]) if standing else _RULE_HINTS[worst]
    # a level's node (:func:`pinchmatch.grasp.analysis`'s source)
    node = re.search(r" \(node (.+)\)$", str(source))
    if standing and node and worst in _STANDING_HINTS:
        hint = (f"{hint.split(': if it is held')[0]}: if it is not an object to pick up (a table, "
                f"a shelf, a wall), leave it out with --skip-nodes '{node.group(1)}'")
    return (
        f"{source}: no feasible pinch among {n_cand} candidates (rejected by "
        f"{', '.join(parts) or 'nothing'}); {hint}"
    )


#: what the rounds (:mod:`rounds`) sample as a pinch
PINCH = GraspKind(name="pinch", rules=RULES, oversample=OVERSAMPLE, max_draw_factor=MAX_DRAW_FACTOR,
                  max_rounds=MAX_ROUNDS, stream=(), draw=_draw, check=_check_picks,
                  first_contacts=_contacts, refusal=_no_pinch_message)
