"""Sampling about ``count`` feasible pinches spread over every graspable region.

Candidates: contacts p1 drawn area-uniformly (seeded), a direction drawn
uniformly within the friction cone around -n1, and as p2 every point where
the ray along it leaves the solid within the largest width. The cheap rules
of :mod:`pinches` prune them with triangle normals; a farthest-point order
spreads the survivors; in rounds, the next picks get the reach search,
fitted patches and the full check with patch normals.

Before the rounds, every width of pinch the candidates offer is checked in
its own stratum (:mod:`strata`), so that a rare width (a mug's handle, a
plate's rim) is represented at any count.

When the first picks show that few places are graspable (a bowl's rim, a
mug's handle), later rounds draw new candidates near the contacts of the
feasible pinches found so far and take them first; the spread order keeps
its distances to every earlier pick, so the result stays spread.
"""

from __future__ import annotations

import dataclasses
import logging
import re

import numpy as np

from .curvature import tangent_frame
from ..cores import query_tree
from ..errors import NoFeasiblePinchError
from .pinches import (PREFILTER_MARGIN_DEG, RULES, PinchSettings, Pinches, assemble, check_patch_radius, cheap_broken,
                      concat_pinches, patches, reach_rule, rule_table)
from .spread import Pool
from .strata import stratified_checks
from ..mesh.surface import SurfaceContext

log = logging.getLogger(__name__)

#: candidates drawn per requested pinch in the first, area-uniform round
OVERSAMPLE = 6
#: how many more pinches than requested get the full check in a round
SELECT_MARGIN = 1.05
#: rounds of checking before giving up on reaching the count
MAX_ROUNDS = 12
#: all rounds together draw at most this many candidates per requested pinch
MAX_DRAW_FACTOR = 40
#: the first round checks at most this many picks before judging how graspable the object is
PROBE_PICKS = 256
#: below this share of feasible picks, new candidates are drawn near the feasible ones found
LOCAL_BELOW = 0.5
#: a ray from p1 is followed through at most this many surfaces (exits are candidate p2)
MAX_EXITS = 8
#: local candidates start within this many fingertip radii of a feasible contact
LOCAL_RADIUS_TIPS = 1.5
#: after the first round, reach is searched before the patches only where more than this share of
#: the picks so far had no approach (elsewhere it is searched once, with the patches' normals)
PRECHECK_ABOVE = 0.05
#: a count above this is sampled nested: the sample of half the count first (the default count's)
NESTED_ABOVE = 1000


def cone_directions(normals: np.ndarray, half_angle_deg: float, rng) -> np.ndarray:
    """Unit directions uniform in solid angle within the cone around -normal."""
    n = len(normals)
    cos_t = 1.0 - rng.random(n) * (1.0 - np.cos(np.radians(half_angle_deg)))
    sin_t = np.sqrt(1.0 - cos_t**2)
    phi = rng.random(n) * 2.0 * np.pi
    t1, t2 = tangent_frame(normals)
    return -(cos_t[:, None] * normals + sin_t[:, None] * (np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2))


def _draw(context, p1, face1, settings, rng, rejected):
    """Candidates from contacts p1: exits along directions in the friction cone, cheap rules applied."""
    n1 = context.face_normals[face1]
    d = cone_directions(n1, settings.friction_cone_deg, rng)
    ray, face2, dist = context.exits(p1, d, max_distance=settings.max_width_mm * (1 + 1e-6), max_hits=MAX_EXITS)
    n_rays = len(p1)
    # a ray with no exit within the largest width offers no second contact
    rejected["width"] += int(n_rays - len(np.unique(ray)))
    points = np.stack([p1[ray], p1[ray] + dist[:, None] * d[ray]], axis=1)
    faces = np.stack([face1[ray], face2], axis=1)
    normals = context.face_normals[faces]
    broken = cheap_broken(context, points, normals, settings, settings.friction_cone_deg + PREFILTER_MARGIN_DEG)
    _count_first(broken, rejected)
    keep = ~broken.any(axis=1)
    return points[keep], faces[keep]


def _count_first(broken, rejected):
    """Count each rejected candidate once, under the first rule it breaks."""
    bad = broken.any(axis=1)
    first = np.argmax(broken, axis=1)
    for j, rule in enumerate(RULES):
        rejected[rule] += int((bad & (first == j)).sum())


def uniform_contacts(context, n, rng):
    mesh = context.mesh
    area = context.contact_area_mm2  # 0 on triangles the object's regions rule out
    faces = rng.choice(len(area), size=n, p=area / area.sum())
    r = rng.random((n, 2))
    flip = r.sum(axis=1) > 1
    r[flip] = 1.0 - r[flip]
    tri = mesh.triangles[faces]
    p1 = tri[:, 0] + r[:, :1] * (tri[:, 1] - tri[:, 0]) + r[:, 1:] * (tri[:, 2] - tri[:, 0])
    return p1, faces


def cheap_candidates(context, n: int, settings: PinchSettings, rng, rejected: dict | None = None):
    """Candidates from ``n`` contacts drawn area-uniformly: (m, 2, 3) points and (m, 2) triangles of
    those that keep the cheap rules (with triangle normals), as the sampler's first round draws them;
    ``rejected`` counts the others per rule."""
    p1, f1 = uniform_contacts(context, n, rng)
    return _draw(context, p1, f1, settings, rng, dict.fromkeys(RULES, 0) if rejected is None else rejected)


def local_contacts(context, seeds, n, radius, rng):
    """n contacts near ``seeds`` (contacts of feasible pinches): random dense-sample points within ``radius``."""
    sample = context.sample
    k = int(min(64, len(sample.points)))
    which = rng.integers(0, len(seeds), size=n)
    dist, idx = query_tree(context.tree, seeds, k=k, distance_upper_bound=radius,
                           work=len(seeds) * k // 16)
    dist, idx = dist.reshape(len(seeds), k), idx.reshape(len(seeds), k)
    valid = np.isfinite(dist)
    counts = valid.sum(axis=1)  # at least 1: the seed's own nearest sample
    pick = np.minimum((rng.random(n) * counts[which]).astype(np.int64), counts[which] - 1)
    chosen = idx[which, pick]
    ok = np.isfinite(dist[which, pick])
    chosen = chosen[ok]
    return sample.points[chosen], sample.face_index[chosen]


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

    A count above ``NESTED_ABOVE`` is sampled nested (:func:`nested_sample`): its first pinches are the
    sample of half the count, so a larger count's sample holds a smaller one's.

    Raises
    ------
    NoFeasiblePinchError
        No candidate passes; the message says how many each rule rejected.

    >>> from pinchmatch import analyze_object
    >>> obj = analyze_object(box_stl)
    >>> pinches = sample_pinches(obj.context, settings=PinchSettings(count=50, seed=0))
    >>> len(pinches), bool(pinches.feasible.all())
    (50, True)
    """
    return nested_sample(_sample_pinches, context, settings, source)


def nested_sample(sample, context, settings: PinchSettings, source: str):
    """``sample(context, settings, source, seen, stream)`` made nested: a count up to ``NESTED_ABOVE`` is
    sampled in one piece; a larger count is the nested sample of half the count (rounded up), then as many
    more as it lacks, drawn from a random stream of their own (``stream``: the count) and spread away from
    the first part's (``seen``: its grasps' points count as picks of the spread order). So a count's
    sample starts with the sample of half of it, and of a quarter, down to ``NESTED_ABOVE``: four times
    the default count holds the default's sample, and the exact search over it sees every pose the smaller
    one offers. Where the rest finds nothing feasible, the first part is the sample."""
    count = settings.count
    if count <= NESTED_ABOVE:
        return sample(context, settings, source)
    inner = nested_sample(sample, context, dataclasses.replace(settings, count=(count + 1) // 2), source)
    more = count - len(inner)
    if more <= 0:
        return inner
    try:
        outer = sample(context, dataclasses.replace(settings, count=more), source, seen=inner.points, stream=(count,))
    except NoFeasiblePinchError:
        return inner
    rejected = {rule: inner.rejected.get(rule, 0) + outer.rejected.get(rule, 0) for rule in outer.rejected}
    return concat_pinches([inner, outer], rejected)


def _sample_pinches(context: SurfaceContext, settings: PinchSettings, source: str, seen: np.ndarray | None = None,
                    stream: tuple = ()) -> Pinches:
    """One piece of :func:`sample_pinches`: ``seen`` (m, 2, 3), pinches of an earlier piece that the spread
    counts as picked; ``stream`` keys the random stream (none: the seed's own)."""
    check_patch_radius(context, settings)
    if not context.contact_area_mm2.any():
        raise NoFeasiblePinchError(f"{source}: the object's contact regions leave no surface to touch (every "
                                   "triangle is in an exclude region or outside the only regions); check "
                                   "the regions against the file's frame and units")
    rng = np.random.default_rng([settings.seed, *stream] if stream else settings.seed)
    seen = np.zeros((0, 2, 3)) if seen is None else seen
    count = settings.count
    rejected = dict.fromkeys(RULES, 0)
    n_first = max(OVERSAMPLE * count, 2000)
    budget = MAX_DRAW_FACTOR * max(count, 50)
    points, faces = cheap_candidates(context, n_first, settings, rng, rejected)
    drawn = n_first
    if len(points) == 0:
        raise NoFeasiblePinchError(_no_pinch_message(source, drawn, rejected, settings, context.support is not None))
    uniform = Pool.of(points, faces, seen)
    local = Pool.empty()

    # every width stratum first; the rounds go on from what the strata found
    parts, picked = stratified_checks(uniform, count, lambda p, f: _check_picks(context, p, f, settings, rejected))
    n_feasible, n_checked = sum(len(p) for p in parts), len(picked)
    n_strata, strata_found, strata_checked = len(parts), n_feasible, n_checked
    picked = np.concatenate([seen, picked])  # an earlier piece's pinches count as picks for the spread
    local_radius = LOCAL_RADIUS_TIPS * settings.fingertip_radius_mm
    for round_ in range(MAX_ROUNDS):
        need = count - n_feasible
        if need <= 0:
            break
        want, local_mode = round_plan(need, n_feasible, n_checked, round_, (n_feasible - strata_found,
                                                                           n_checked - strata_checked))
        short = int((uniform.nearest >= 0).sum() + (local.nearest >= 0).sum()) < want
        if (local_mode or short) and drawn < budget:
            # more candidates: near the feasible contacts found so far, or anywhere while none is
            n_more = int(min(budget - drawn, OVERSAMPLE * want))
            if n_feasible:
                # the rounds' own finds are spread as the feasible pinches are; the strata's lean to rare widths
                seeds = np.concatenate([p.points.reshape(-1, 3) for p in (parts[n_strata:] or parts)])
                more_p, more_f = local_contacts(context, seeds, n_more, local_radius, rng)
            else:
                more_p, more_f = uniform_contacts(context, n_more, rng)
            drawn += n_more
            new_points, new_faces = _draw(context, more_p, more_f, settings, rng, rejected)
            (local if n_feasible else uniform).add(new_points, new_faces, picked)
        chosen, chosen_f = pick_round(uniform, local, want, local_mode)
        if len(chosen) == 0:
            break
        picked = np.concatenate([picked, chosen])
        # the reach pre-check pays where the probe found picks no hand gets to
        precheck = round_ == 0 or rejected["reach"] > PRECHECK_ABOVE * n_checked
        part = _check_picks(context, chosen, chosen_f, settings, rejected, precheck=precheck)
        n_checked += len(chosen)
        parts.append(part)
        n_feasible += len(part)
    if n_feasible == 0:
        raise NoFeasiblePinchError(_no_pinch_message(source, drawn, rejected, settings, context.support is not None))
    # the strata's first, then the rounds' in spread order, so the first `count` are evenly spread
    result = concat_pinches(parts, rejected).subset(np.arange(min(count, n_feasible)))
    log.info("%s: %d feasible pinches from %d candidates", source, len(result), drawn)
    return result


def round_plan(need: int, n_feasible: int, n_checked: int, round_: int,
               rounds: tuple[int, int] = (0, 0)) -> tuple[int, bool]:
    """How many picks a round checks to find ``need`` more grasps, and whether it draws near the feasible ones
    (local mode: few picks were feasible). Both are judged by the feasible share of the rounds' own picks,
    ``rounds`` (found, checked), once there are any, else of all ``n_checked`` so far: the width strata check
    the rare widths hard, where the hand reaches few, and their share would have the spread's rounds check
    far more than they need (and draw locally where the object is graspable all over). The first round
    probes at most ``PROBE_PICKS``."""
    found, checked = rounds if rounds[1] else (n_feasible, n_checked)
    share = found / checked if checked else 1.0
    want = int(np.ceil(SELECT_MARGIN * need / max(share, 0.05)))
    want = min(want, PROBE_PICKS) if round_ == 0 else min(want, 4 * need + PROBE_PICKS)
    return want, checked > 0 and n_feasible > 0 and share < LOCAL_BELOW


def pick_round(uniform: Pool, local: Pool, want: int, local_mode: bool) -> tuple[np.ndarray, np.ndarray]:
    """A round's ``want`` picks from both pools in their spread orders, the local pool's first in local mode,
    each pool's spread counting the other's picks: (points, faces)."""
    first, second = (local, uniform) if local_mode else (uniform, local)
    a = first.pick(want)
    second.saw(first.points[a])
    b = second.pick(want - len(a))
    first.saw(second.points[b])
    return np.concatenate([first.points[a], second.points[b]]), np.concatenate([first.faces[a], second.faces[b]])


def _check_picks(context, points, faces, settings, rejected, *, precheck: bool = True) -> Pinches:
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
    "region": "few contacts fall where the object's regions allow: check exclude and only in its manifest",
    "width": "the object may be too wide or thin for the width limits: check --min-width-mm/--max-width-mm and --units",
    "antipodal": "no opposite surfaces face each other: try a wider --friction-cone-deg",
    "clearance": "a fingertip does not fit: try a smaller --fingertip-radius-mm",
    "reach": "no approach lets both fingers get to the contacts: try a shorter --finger-length-mm, a thinner "
             "--finger-radius-mm, or a larger --approach-tilt-deg or --finger-splay-deg",
    "patch": "too little surface around the contacts: try a smaller --patch-radius-mm",
    "surface": "the points are far from the surface",
}


#: where an object stands on a support, what its hint says when the fingers cannot get to it
_STANDING_HINTS = {
    "clearance": "it stands too low on its table for a fingertip to get beside it (thinner than two fingertips): "
                 "if it is held in the hand, give support = \"none\" in its manifest or --support none",
    "reach": "no approach from above its table lets both fingers get to the contacts: if it is held in the hand, "
             "give support = \"none\" in its manifest or --support none",
}


def _no_pinch_message(source, n_cand, rejected, settings, standing: bool = False) -> str:
    parts = [f"{rule} {count}" for rule, count in rejected.items() if count]
    worst = max(rejected, key=rejected.get)
    hint = _STANDING_HINTS.get(worst, _RULE_HINTS[worst]) if standing else _RULE_HINTS[worst]
    node = re.search(r" \(node (.+)\)$", str(source))  # a level's node (:func:`pinchmatch.grasp.analysis`'s source)
    if standing and node and worst in _STANDING_HINTS:
        hint = (f"{hint.split(': if it is held')[0]}: if it is not an object to pick up (a table, a shelf, a wall), "
                f"leave it out with --skip-nodes '{node.group(1)}'")
    return (
        f"{source}: no feasible pinch among {n_cand} candidates (rejected by "
        f"{', '.join(parts) or 'nothing'}); {hint}"
    )
