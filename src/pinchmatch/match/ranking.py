"""The one ranking of a virtual object's choices, from the searches' candidates to the answer.

One search (:class:`~pinchmatch.match.search.Search`, one virtual object against the props) is
ranked once, by :func:`rank`, and everything a match reports is read from that one ranking:

- the choices felt: unless the match ranks on target (``--rank nominal``, or a landing radius of
  0), the ``RANKED_CHOICES`` distinct best pairs on target among the allowed props (or top_k + 1,
  if more; more above the default count: :func:`ranked_choices`), the steady search's
  ``STEADY_CHOICES`` distinct best by their expected cost, and per prop ``ROW_CHOICES`` of each
  kind, each felt exactly (:mod:`pinchmatch.match.felt`) and ranked by ``--rank``'s cost; ties by
  the cost on target, then prop and poses;
- that one list is put in the answer's order: the choices within the equivalence band of the best
  in comfort order (:func:`comfort_first`), the rest by cost;
- the row (what ``select`` and ``design`` rank props by, and the cost matrix): each prop's first
  choice in that order: its cheapest, unless it has choices in the band (then the most comfortable
  of them), so that the best prop's entry is the answer's cost and a prop chosen from the row is
  served at the cost the row promised;
- the answer: the choices on the allowed props in that order, none a near duplicate of an earlier
  one.

Ranked on target, the search's own least cost is the row and its distinct best choices the answer
(nothing is felt beyond their nominal cost).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..grasp.pinches import PinchSettings
from .candidates import with_count
from .choice import Choice, pinch_distance
from .comfort import comfort_score
from .felt import FeltTables, felt_cost
from .noticed import p_noticed
from .search import Search, cost_row
from .steady import STEADY_CHOICES, SteadySearch

#: unless ``--rank nominal``, this many distinct best choices on target (or top_k + 1, if more) and
#: the steady search's ``STEADY_CHOICES`` are ranked by their cost over the landings. The pair that
#: feels best is often far down the order on target (a scanned marker's on a mustard bottle: between
#: the 97th and the 128th), and a felt pair costs little beside the search, so the set is wide
RANKED_CHOICES = 128
#: above the default count, the set on target grows in proportion, up to this many: a denser sample
#: holds more knife edges, distinct but each barely better on target, that push the pairs that feel
#: best out of a set of fixed size (the YCB scissors on the mustard bottle: 2.76 JND at four times
#: the count with 128, 2.31 with 512,
#: 2.40 at the default count)
MAX_RANKED_CHOICES = 1024
#: and per tangible, for its row of the cost matrix (what select and design rank props by), this
#: many of each
ROW_CHOICES = 3
#: another prop is equivalent to the best when its ranked cost is within this much of the best's, in
#: JND, or within this share of it, whichever is larger
EQUIVALENT_JND, EQUIVALENT_SHARE = 0.1, 0.05


@dataclass(frozen=True)
class Ranking:
    """One search's choices, ranked once.

    - ``answer``: up to ``count`` (choice, felt) on the allowed props, best first (the match's best
      and alternatives);
    - ``row``: ``(n,) float64``, each prop's ranked cost (inf where no registration is allowed);
    - ``noticed``: ``(n,) bool``, whether that choice is noticed at least half of the time (True
      where none is allowed).
    """

    answer: list
    row: np.ndarray
    noticed: np.ndarray


def ranked_choices(count: int) -> int:
    """How many distinct best pairs on target the match feels at a sampling count of ``count`` poses
    per object: ``RANKED_CHOICES`` up to the default count, in proportion above it, at most
    ``MAX_RANKED_CHOICES``."""
    return with_count(RANKED_CHOICES, count, MAX_RANKED_CHOICES)


def rank(search: Search, steady: SteadySearch | None, tables: FeltTables, allowed: list[int],
         count: int) -> Ranking:
    """The one ranking of virtual object 0 of ``search`` (module notes): up to ``count`` choices
    among the ``allowed`` tangibles, and the row over every tangible.

    ``steady`` is the steady search beside ``search``, None where the match ranks on target;
    ``tables`` the landing tables and felt costs of the run (read and added to)."""
    exact = cost_row(search, 0)
    finite = [int(t) for t in np.flatnonzero(np.isfinite(exact))]
    if steady is None:
        answer = comfort_first(search, _felt(search, search.choices(0, allowed, count), tables),
                               tables.settings) if allowed else []
        return Ranking(answer, exact, _noticed_on_target(search, exact, finite))
    nominal = max(count, ranked_choices(steady.pinch_settings.count))
    picks = []
    if allowed:
        picks += search.choices(0, allowed, nominal) + steady.choices(allowed,
                                                                      max(count, STEADY_CHOICES))
    for t in finite:
        picks += search.choices(0, [t], ROW_CHOICES) + steady.choices([t], ROW_CHOICES)
    felt = sorted(_felt(search, _unique(picks), tables),
                  key=lambda pf: (pf[0].cost, pf[0].cost_nominal, pf[0].tangible, pf[0].t_pose,
                                  pf[0].v_pose))
    ranked = comfort_first(search, felt, tables.settings)
    row, noticed = np.full(len(exact), np.inf), np.ones(len(exact), dtype=bool)
    for choice, _ in reversed(ranked):  # the first of each tangible, written last
        row[choice.tangible], noticed[choice.tangible] = choice.cost, choice.p_noticed >= 0.5
    mine = set(allowed)
    answer: list = []
    for choice, f in (pf for pf in ranked if pf[0].tangible in mine):
        if len(answer) >= count:
            break
        if not any(_near(choice, other, search.settings.distinct_mm) for other, _ in answer):
            answer.append((choice, f))
    return Ranking(answer, row, noticed)


def _noticed_on_target(search: Search, row: np.ndarray, finite: list) -> np.ndarray:
    """(n,) whether each tangible's best choice on target is noticed at least half of the time."""
    loud = np.ones(len(row), dtype=bool)
    for t in finite:
        best = search.choices(0, [t], 1)[0]
        loud[t] = p_noticed(search.tangibles[t], search.virtuals[0], best, search.model) >= 0.5
    return loud


def _unique(picks: list) -> list:
    """``picks`` without repeats (the same tangible, poses and finger order), the first kept."""
    seen, out = set(), []
    for p in picks:
        key = (p.tangible, p.t_pose, p.v_pose, p.swapped)
        if key not in seen:
            seen.add(key)
            out.append(p)
    return out


def _felt(search: Search, picks: list, tables: FeltTables) -> list:
    """[(choice, felt)]: the picks with their ranked cost and its chance of being noticed
    (``--rank``), the landing kept."""
    rank_by, out = search.settings.rank, []
    if tables.radius_mm > 0:  # the landing tables of every pick at once
        for t in sorted({p.tangible for p in picks}):
            tables.prefetch(search.tangibles[t], [p.t_pose for p in picks if p.tangible == t])
        tables.prefetch(search.virtuals[0], [p.v_pose for p in picks])
    for p in picks:
        key = (id(search), p.tangible, p.t_pose, p.v_pose, p.swapped)
        if key not in tables.felt:
            tables.felt[key] = felt_cost(search.tangibles[p.tangible], search.virtuals[0], p,
                                         search.model, tables)
        felt = tables.felt[key]
        out.append((dataclasses.replace(p, cost=felt.ranked(rank_by),
                                        p_noticed=felt.ranked_p_noticed(rank_by)), felt))
    return out


def comfort_first(search: Search, felt: list, pinch: PinchSettings) -> list:
    """``felt`` [(choice, felt)], ranked by cost, with the choices that cost the same as the best
    (within ``EQUIVALENT_JND`` or ``EQUIVALENT_SHARE`` of it, as
    :func:`~pinchmatch.match.scene.equivalent_tangibles` judges props) put in the order of their
    :func:`~pinchmatch.match.comfort.comfort_score`, most comfortable first (ties by cost): among
    choices a person cannot tell apart by feel, the one reached most easily."""
    if len(felt) < 2:
        return felt
    best = felt[0][0].cost
    limit = best + max(EQUIVALENT_JND, EQUIVALENT_SHARE * best)
    band = [pf for pf in felt if pf[0].cost <= limit]
    scores = [comfort_score(search.tangibles[c.tangible], c.t_pose, search.settings.user_mm,
                            pinch.fingertip_radius_mm)
              for c, _ in band]
    order = sorted(range(len(band)), key=lambda k: (-round(scores[k], 9), k))
    return [band[k] for k in order] + felt[len(band):]


def _near(a: Choice, b: Choice, distinct_mm: float) -> bool:
    """Is ``a`` a near duplicate of ``b`` (the same tangible, both grasps within
    ``distinct_mm``)?"""
    return a.tangible == b.tangible and all(
        float(pinch_distance(x.contacts_mm[None], y.contacts_mm)[0]) < distinct_mm
        for x, y in ((a.tangible_pose, b.tangible_pose), (a.virtual_pose, b.virtual_pose)))
