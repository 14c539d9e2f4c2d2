"""The sampler's rounds: one loop that finds about ``count`` feasible grasps of any kind, spread.

Pinches (:mod:`sampling`) and tripods (:mod:`tripods`) are sampled by the same loop; a
:class:`GraspKind` passes in what differs between them: how candidates are drawn from first
contacts, which rules check a pick, and the refusal when none passes.

1. Contacts are drawn area-uniformly (seeded) and made candidates; the cheap rules prune them.
2. Every width stratum is checked first (:mod:`strata`), so a rare width is represented at any
   count.
3. In rounds, the next picks in a farthest-point order (:mod:`spread`) get the full check. Where the
   picks so far show that few places are graspable (a bowl's rim, a mug's handle), new candidates
   are drawn near the contacts of the grasps the rounds found (the strata's while the rounds found
   none), and taken first; the spread order keeps its distances to every earlier pick.
4. A count above ``NESTED_ABOVE`` is sampled nested (:func:`nested_sample`).
"""

from __future__ import annotations

import dataclasses
import logging
from typing import Callable

import numpy as np

from ..cores import query_tree
from ..errors import NoFeasiblePinchError
from ..mesh.surface import SurfaceContext
from .pinches import PinchSettings, check_patch_radius, concat_pinches
from .spread import Pool
from .strata import stratified_checks

log = logging.getLogger(__name__)

#: how many more grasps than requested get the full check in a round
SELECT_MARGIN = 1.05
#: the first round checks at most this many picks before judging how graspable the object is
PROBE_PICKS = 256
#: below this share of feasible picks, new candidates are drawn near the feasible ones found
LOCAL_BELOW = 0.5
#: local candidates start within this many fingertip radii of a feasible contact
LOCAL_RADIUS_TIPS = 1.5
#: after the first round, reach is searched before the patches only where more than this share of
#: the picks so far had no approach (elsewhere it is searched once, with the patches' normals)
PRECHECK_ABOVE = 0.05
#: a count above this is sampled nested: the sample of half the count first (the default count's)
NESTED_ABOVE = 1000


@dataclasses.dataclass(frozen=True)
class GraspKind:
    """What the rounds need of one kind of grasp.

    Parameters
    ----------
    name : str
        ``"pinch"`` or ``"tripod"``, for the log.
    rules : tuple of str
        The rules, in the order a rejected candidate is counted under the first it breaks;
        ``"reach"`` among them (whether the next round searches reach first depends on how many it
        rejected).
    oversample : int
        Candidates' first contacts drawn per requested grasp in the first draw.
    max_draw_factor : int
        All draws together take at most this many first contacts per requested grasp (at least 50).
    max_rounds : int
        Rounds of full checks after the strata.
    stream : tuple of int
        Keys the random stream after the seed (none: the seed's own stream).
    draw : callable
        ``draw(context, contacts (n, 3), faces (n,), settings, rng, rejected)``: the candidates that
        keep the cheap rules, ``(m, F, 3)`` points and ``(m, F)`` triangles; ``rejected`` counts the
        others.
    check : callable
        ``check(context, points, faces, settings, rejected, precheck)``: the feasible grasps among
        picks (every rule; with ``precheck`` the reach search may run first with triangle normals).
    first_contacts : callable
        ``first_contacts(points (m, F, 3))``: the contacts near which local draws start, ``(k, 3)``.
    refusal : callable
        ``refusal(source, drawn, rejected, settings, standing)``: the one-line message when no
        candidate passes.
    """

    name: str
    rules: tuple[str, ...]
    oversample: int
    max_draw_factor: int
    max_rounds: int
    stream: tuple[int, ...]
    draw: Callable
    check: Callable
    first_contacts: Callable
    refusal: Callable


def uniform_contacts(context: SurfaceContext, n: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """``n`` contacts drawn area-uniformly over the contact regions: (n, 3) points and (n,)
    triangles."""
    area = context.contact_area_mm2  # 0 on triangles the object's regions rule out
    faces = rng.choice(len(area), size=n, p=area / area.sum())
    r = rng.random((n, 2))
    flip = r.sum(axis=1) > 1
    r[flip] = 1.0 - r[flip]
    tri = context.mesh.triangles[faces]
    p1 = tri[:, 0] + r[:, :1] * (tri[:, 1] - tri[:, 0]) + r[:, 1:] * (tri[:, 2] - tri[:, 0])
    return p1, faces


def local_contacts(context: SurfaceContext, seeds: np.ndarray, n: int, radius: float, rng):
    """``n`` contacts near ``seeds`` (contacts of feasible grasps): random dense-sample points
    within ``radius``: (m, 3) points and (m,) triangles, m <= n."""
    sample = context.sample
    k = int(min(64, len(sample.points)))
    which = rng.integers(0, len(seeds), size=n)
    dist, idx = query_tree(
        context.tree, seeds, k=k, distance_upper_bound=radius, work=len(seeds) * k // 16
    )
    dist, idx = dist.reshape(len(seeds), k), idx.reshape(len(seeds), k)
    valid = np.isfinite(dist)
    counts = valid.sum(axis=1)  # at least 1: the seed's own nearest sample
    pick = np.minimum((rng.random(n) * counts[which]).astype(np.int64), counts[which] - 1)
    chosen = idx[which, pick]
    ok = np.isfinite(dist[which, pick])
    chosen = chosen[ok]
    return sample.points[chosen], sample.face_index[chosen]


def round_plan(
    need: int, n_feasible: int, n_checked: int, round_: int, rounds: tuple[int, int] = (0, 0)
) -> tuple[int, bool]:
    """How many picks a round checks to find ``need`` more grasps, and whether it draws near the
    feasible ones (local mode: few picks were feasible). Both are judged by the feasible share of
    the rounds' own picks, ``rounds`` (found, checked), once there are any, else of all
    ``n_checked`` so far: the width strata check the rare widths hard, where the hand reaches few,
    and their share would have the spread's rounds check far more than they need (and draw locally
    where the object is graspable all over). The first round probes at most ``PROBE_PICKS``."""
    found, checked = rounds if rounds[1] else (n_feasible, n_checked)
    share = found / checked if checked else 1.0
    want = int(np.ceil(SELECT_MARGIN * need / max(share, 0.05)))
    want = min(want, PROBE_PICKS) if round_ == 0 else min(want, 4 * need + PROBE_PICKS)
    return want, checked > 0 and n_feasible > 0 and share < LOCAL_BELOW


def pick_round(
    uniform: Pool, local: Pool, want: int, local_mode: bool
) -> tuple[np.ndarray, np.ndarray]:
    """A round's ``want`` picks from both pools in their spread orders, the local pool's first in
    local mode, each pool's spread counting the other's picks: (points, faces)."""
    first, second = (local, uniform) if local_mode else (uniform, local)
    a = first.pick(want)
    second.saw(first.points[a])
    b = second.pick(want - len(a))
    first.saw(second.points[b])
    return np.concatenate([first.points[a], second.points[b]]), np.concatenate(
        [first.faces[a], second.faces[b]]
    )


def sample_rounds(
    kind: GraspKind,
    context: SurfaceContext,
    settings: PinchSettings,
    source: str,
    seen: np.ndarray | None = None,
    stream: tuple = (),
):
    """About ``settings.count`` feasible grasps of ``kind`` (module notes), in one piece.

    ``seen`` (m, F, 3): grasps of an earlier piece that the spread counts as picked; ``stream`` keys
    the random stream after ``kind.stream``. The strata's grasps come first, then the rounds' in
    spread order, so the first ``count`` are evenly spread.

    Raises
    ------
    NoFeasiblePinchError
        No candidate passes (``kind.refusal``), or the regions leave no surface to touch.
    """
    check_patch_radius(context, settings)
    if not context.contact_area_mm2.any():
        raise NoFeasiblePinchError(
            f"{source}: the object's contact regions leave no surface to touch (every "
            "triangle is in an exclude region or outside the only regions); check "
            "the regions against the file's frame and units"
        )
    keys = (*kind.stream, *stream)
    rng = np.random.default_rng([settings.seed, *keys] if keys else settings.seed)
    count = settings.count
    standing = context.support is not None
    rejected = dict.fromkeys(kind.rules, 0)
    drawn = max(kind.oversample * count, 2000)
    budget = kind.max_draw_factor * max(count, 50)
    points, faces = kind.draw(
        context, *uniform_contacts(context, drawn, rng), settings, rng, rejected
    )
    if len(points) == 0:
        raise NoFeasiblePinchError(kind.refusal(source, drawn, rejected, settings, standing))
    seen = np.zeros((0, points.shape[1], 3)) if seen is None else seen
    uniform, local = Pool.of(points, faces, seen), Pool.empty(points.shape[1])

    def check(p, f, precheck=True):
        return kind.check(context, p, f, settings, rejected, precheck)

    # every width stratum first; the rounds go on from what the strata found
    parts, picked = stratified_checks(uniform, count, check)
    n_feasible, n_checked = sum(len(p) for p in parts), len(picked)
    n_strata, strata_found, strata_checked = len(parts), n_feasible, n_checked
    picked = np.concatenate(
        [seen, picked]
    )  # an earlier piece's grasps count as picks for the spread
    for round_ in range(kind.max_rounds):
        need = count - n_feasible
        if need <= 0:
            break
        want, local_mode = round_plan(
            need,
            n_feasible,
            n_checked,
            round_,
            (n_feasible - strata_found, n_checked - strata_checked),
        )
        short = int((uniform.nearest >= 0).sum() + (local.nearest >= 0).sum()) < want
        if (local_mode or short) and drawn < budget:
            # more candidates: near the feasible contacts found so far, or anywhere while none is
            n_more = int(min(budget - drawn, kind.oversample * want))
            if n_feasible:
                # the rounds' own finds are spread as the feasible grasps are; the strata's lean to
                # rare widths
                seeds = np.concatenate(
                    [kind.first_contacts(p.points) for p in (parts[n_strata:] or parts)]
                )
                contacts = local_contacts(
                    context, seeds, n_more, LOCAL_RADIUS_TIPS * settings.fingertip_radius_mm, rng
                )
            else:
                contacts = uniform_contacts(context, n_more, rng)
            drawn += n_more
            new_points, new_faces = kind.draw(context, *contacts, settings, rng, rejected)
            (local if n_feasible else uniform).add(new_points, new_faces, picked)
        chosen, chosen_f = pick_round(uniform, local, want, local_mode)
        if len(chosen) == 0:
            break
        picked = np.concatenate([picked, chosen])
        # the reach pre-check pays where the probe found picks no hand gets to
        part = check(
            chosen, chosen_f, round_ == 0 or rejected["reach"] > PRECHECK_ABOVE * n_checked
        )
        n_checked += len(chosen)
        parts.append(part)
        n_feasible += len(part)
    if n_feasible == 0:
        raise NoFeasiblePinchError(kind.refusal(source, drawn, rejected, settings, standing))
    result = concat_pinches(parts, rejected).subset(np.arange(min(count, n_feasible)))
    log.info("%s: %d feasible %ss from %d candidates", source, len(result), kind.name, drawn)
    return result


def nested_sample(sample, context, settings: PinchSettings, source: str):
    """``sample(context, settings, source, seen, stream)`` made nested: a count up to
    ``NESTED_ABOVE`` is sampled in one piece; a larger count is the nested sample of half the count
    (rounded up), then as many more as it lacks, drawn from a random stream of their own
    (``stream``: the count) and spread away from the first part's (``seen``: its grasps' points
    count as picks of the spread order). So a count's sample starts with the sample of half of it,
    and of a quarter, down to ``NESTED_ABOVE``: four times the default count holds the default's
    sample, and the exact search over it sees every pose the smaller one offers. Where the rest
    finds nothing feasible, the first part is the sample."""
    count = settings.count
    if count <= NESTED_ABOVE:
        return sample(context, settings, source)
    inner = nested_sample(
        sample, context, dataclasses.replace(settings, count=(count + 1) // 2), source
    )
    more = count - len(inner)
    if more <= 0:
        return inner
    try:
        outer = sample(
            context,
            dataclasses.replace(settings, count=more),
            source,
            seen=inner.points,
            stream=(count,),
        )
    except NoFeasiblePinchError:
        return inner
    rejected = {
        rule: inner.rejected.get(rule, 0) + outer.rejected.get(rule, 0) for rule in outer.rejected
    }
    return concat_pinches([inner, outer], rejected)
