"""Design props for a scene: the search behind ``pinchmatch design``.

The family is :mod:`pinchmatch.mesh.stacks` (coaxial stacks of cylinders, boxes, frusta and
barrels). Every candidate is judged by the real pipeline: its stack is written as an STL, loaded,
sampled for feasible pinches with their features, and searched against every scene object with
``match``'s exact search; its score is the scene's objective on the props (``mean``: the mean of
each object's least cost over the K props; ties by the count of noticeable objects).

**The proxy that guides it.** Where a scene object can be pinched, and how wide, is the first thing
a prop must offer: the first candidates give each part the width of one quantile of the scene's
pinch widths (each object's feasible widths weighted equally), tallest first, in each part kind.
Each candidate is then judged for real.

**The search** is a seeded local search. A step changes one prop of the set: a part's kind, width,
top width or height, a part added, removed or two swapped (each repaired into the limits); the
change is kept when it lowers the objective. The scene's objects are sampled once, at the run's full
count; during the search the props are sampled at ``search_count`` poses (fewer, for speed); the
chosen props are then written and matched at the full count, and those are the costs reported.

**Judging** a candidate costs what does not depend on it once: the scene's poses, features and cost
model are made before the search, and each candidate is ranked on target over its sampled poses (the
felt ranking, with its landing tables and steady search made anew for every candidate's poses, and
refinement are the final match's). With one prop, a candidate's objects are judged hardest first (by
the best candidate's costs), and a candidate is given up as soon as the costs of the objects judged
so far add up to more than the total of the ``FINALISTS``-th best: costs are never negative, so it
cannot be among the finalists.

**Where it starts.** The proxy's candidates, and where a shelf is given (``seeds``), the stacks
fitted to its best props (:mod:`pinchmatch.mesh.stack_fit`), judged first.

**The finalists.** The ``FINALISTS`` best sets on target are then ranked as the run ranks (the felt
cost over where guided fingers land, at the search's count), and the best of them is the design: the
ranking on target chooses where to look, the run's ranking what to keep.

**The budget** is the search's wall time on target: the search stops when one more candidate would
not fit in it. The scene's sampling before it, the finalists' ranking and the final match after it
take what they take (as ``match``'s would); a budget shorter than judging one candidate is refused
after that one.

**Determinism.** For a seed, the candidates and their order are the same on every machine; the
budget decides how many are judged (``evaluations`` fixes the number instead, so that the result
does not depend on the machine's speed). ``-k 2`` designs two props that work together: each step
changes one of them, judged on the pair (each object on its better prop).
"""

from __future__ import annotations

import hashlib
import json
import math
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import ConfigError, InternalError, PinchmatchError
from ..grasp.pinches import PinchSettings
from ..match.candidates import Candidates
from ..config import Config
from ..match.scene import match_one
from ..match.search import MatchSettings, cost_model
from ..mesh.stacks import (
    MIN_PART_HEIGHT_MM,
    MIN_PART_WIDTH_MM,
    PART_KINDS,
    Part,
    Stack,
    stack_mesh,
    stack_problems,
    supported,
)
from ..mesh.manifest import ObjectSpec
from .cache import cached_candidates

#: poses per object and prop while searching (the final props are matched at the run's count)
SEARCH_COUNT = 300
#: relative step of a width or height change
STEP = 0.25
#: the best sets on target ranked again as the run ranks (the felt cost) after the search
FINALISTS = 3


#: the bounds of design's options: a day's budget, a search of a million candidates, 8 props, 1 m
#: tall
MAX_BUDGET_S, MAX_EVALUATIONS, MAX_PROPS, MAX_HEIGHT_MM = 86_400.0, 1_000_000, 8, 1000.0


@dataclass(frozen=True)
class DesignSettings:
    """Options of :func:`design_props` (``pinchmatch design``'s flags; see the module notes).

    ``k`` props designed together, each a stack of at most ``max_parts`` parts within
    ``max_height_mm`` and ``max_width_mm``; ``budget_s`` seconds of wall time, or exactly
    ``evaluations`` candidates judged (then the result does not depend on the machine's speed);
    ``seed`` the search's; ``search_count`` poses sampled per candidate prop during the search;
    ``supports`` False keeps every candidate printable without supports; ``stand`` judges each prop
    standing on a table (its support, :mod:`pinchmatch.mesh.support`), False as held in the hand;
    ``anneal`` the starting temperature of the acceptance rule (relative cost; 0 takes only
    improvements).
    """

    k: int = 1
    max_parts: int = 4
    max_height_mm: float = 200.0
    max_width_mm: float = 100.0
    budget_s: float = 120.0
    seed: int = 0
    evaluations: int | None = None
    search_count: int = SEARCH_COUNT
    # False: every candidate printable standing on its base without supports
    supports: bool = True
    # starting temperature of the acceptance rule (relative cost); 0: only improvements
    anneal: float = 0.0
    stand: bool = True  # the props stand on a table: no hand reaches below their lowest point

    def check(self) -> None:
        """Raise ConfigError for limits no stack of the family can meet, or a bad option."""
        if self.k < 1:
            raise ConfigError(f"-k {self.k}: design 1 prop or more")
        if not 1 <= self.max_parts <= 4:
            raise ConfigError(f"--max-parts {self.max_parts}: give 1 to 4")
        if not math.isfinite(self.max_height_mm) or self.max_height_mm < MIN_PART_HEIGHT_MM:
            raise ConfigError(f"--max-height-mm {self.max_height_mm:g}: no part of the family is "
                              "that low "
                              f"(a part is at least {MIN_PART_HEIGHT_MM:g} mm tall); give more")
        if self.max_width_mm < MIN_PART_WIDTH_MM:
            raise ConfigError(f"--max-width-mm {self.max_width_mm:g}: no part of the family is "
                              "that narrow "
                              f"(a part is at least {MIN_PART_WIDTH_MM:g} mm wide); give more")
        if not 0 < self.budget_s <= MAX_BUDGET_S:
            raise ConfigError(f"--budget-s {self.budget_s:g}: give a time in seconds, more than 0 "
                              f"and at most {MAX_BUDGET_S:g} (a day)")
        if self.evaluations is not None and not 1 <= self.evaluations <= MAX_EVALUATIONS:
            raise ConfigError(f"--evaluations {self.evaluations}: give 1 to {MAX_EVALUATIONS}")
        if self.k > MAX_PROPS:
            raise ConfigError(f"-k {self.k}: design at most {MAX_PROPS} props at once")
        if self.max_height_mm > MAX_HEIGHT_MM:
            raise ConfigError(f"--max-height-mm {self.max_height_mm:g}: a prop held in one hand is "
                              f"at most {MAX_HEIGHT_MM:g} mm tall; give less")


def _repair(stack: Stack, s: DesignSettings) -> Stack:
    """The stack moved into the limits: widths and heights clipped and rounded to 0.1 mm (what a
    printer resolves, and what ``design.json`` states), heights scaled to the height limit; without
    supports, reshaped so that nothing hangs over (:func:`pinchmatch.mesh.stacks.supported`)."""
    parts = []
    for p in stack.parts[:s.max_parts]:
        cap = s.max_width_mm / (math.sqrt(2.0) if p.kind == "box" else 1.0)
        width = float(np.clip(p.width_mm, MIN_PART_WIDTH_MM, cap))
        top = None
        if p.kind == "frustum":
            top = float(np.clip(p.top_width_mm if p.top_width_mm else width / 2, MIN_PART_WIDTH_MM,
                                cap))
        elif p.kind == "barrel":
            top = min(max(p.top_width_mm if p.top_width_mm else 0.6 * width, MIN_PART_WIDTH_MM),
                      0.9 * width)
            if top < MIN_PART_WIDTH_MM:  # too narrow to bulge: a cylinder
                p, top = replace(p, kind="cylinder"), None
        depth = None
        if p.kind == "box" and p.depth_mm is not None:
            # an oblong box: its diagonal within the width limit
            shrink = min(1.0, s.max_width_mm / math.hypot(p.width_mm, p.depth_mm))
            width = max(p.width_mm * shrink, MIN_PART_WIDTH_MM)
            depth = round(max(p.depth_mm * shrink, MIN_PART_WIDTH_MM), 1)
        parts.append(Part(p.kind, round(max(p.height_mm, MIN_PART_HEIGHT_MM), 1), round(width, 1),
                          None if top is None else round(top, 1), round(p.turn_deg, 1) if p.kind
                          == "box" else 0.0,
                          depth))
    total = sum(p.height_mm for p in parts)
    if total > s.max_height_mm:
        scale = s.max_height_mm / total
        parts = [replace(p,
                         height_mm=max(MIN_PART_HEIGHT_MM, math.floor(p.height_mm * scale * 10)
                                       / 10)) for p in parts]
        while sum(p.height_mm for p in parts) > s.max_height_mm + 1e-9 and len(parts) > 1:
            parts.pop()
    return Stack(tuple(parts)) if s.supports else supported(Stack(tuple(parts)))


def _key(stack: Stack) -> str:
    return hashlib.sha256(json.dumps(stack.as_dict(), sort_keys=True).encode()).hexdigest()[:16]


def initial_stacks(virtuals: list[Candidates], s: DesignSettings) -> list[Stack]:
    """The first candidates: part widths at the quantiles of the scene's pinch widths (the
    proxy)."""
    widths = np.concatenate([v.features.width_mm for v in virtuals])
    weights = np.concatenate([np.full(len(v), 1.0 / max(len(v), 1)) for v in virtuals])
    order = np.argsort(widths, kind="stable")
    cdf = np.cumsum(weights[order]) / weights.sum()
    out = []
    for n in range(1, s.max_parts + 1):
        at = [float(widths[order][np.searchsorted(cdf, (i + 0.5) / n)]) for i in range(n)]
        height = min(max(s.max_height_mm / n, MIN_PART_HEIGHT_MM), 50.0)
        for kind in PART_KINDS:
            parts = [Part(kind, height, w + 2.0, 0.6 * (w + 2.0) if kind in ("frustum", "barrel")
                          else None)
                     # widest at the bottom: no overhang between parts
                     for w in sorted(at, reverse=True)]
            out.append(_repair(Stack(tuple(parts)), s))
    unique = {}
    for st in out:
        unique.setdefault(_key(st), st)
    return list(unique.values())


def mutate(stack: Stack, rng: np.random.Generator, s: DesignSettings) -> Stack:
    """One seeded change of a stack (see the module notes), repaired into the limits."""
    parts = list(stack.parts)
    i = int(rng.integers(len(parts)))
    move = rng.choice(["kind", "width", "top", "height", "add", "remove", "swap", "turn"])
    p = parts[i]
    if move == "kind":
        kind = str(rng.choice([k for k in PART_KINDS if k != p.kind]))
        parts[i] = Part(kind, p.height_mm, p.width_mm, p.top_width_mm or 0.6 * p.width_mm if kind in
                        ("frustum", "barrel") else None)
    elif move == "width":
        parts[i] = replace(p, width_mm=p.width_mm * (1.0 + STEP * rng.uniform(-1, 1)))
    elif move == "top" and p.top_width_mm is not None:
        parts[i] = replace(p, top_width_mm=p.top_width_mm * (1.0 + STEP * rng.uniform(-1, 1)))
    elif move == "height":
        parts[i] = replace(p, height_mm=p.height_mm * (1.0 + STEP * rng.uniform(-1, 1)))
    elif move == "add" and len(parts) < s.max_parts:
        parts.insert(i + 1,
                     replace(p, kind=str(rng.choice(PART_KINDS)),
                             width_mm=p.width_mm * rng.uniform(0.5, 1.2),
                                    top_width_mm=0.6 * p.width_mm))
    elif move == "remove" and len(parts) > 1:
        parts.pop(i)
    elif move == "swap" and len(parts) > 1:
        j = (i + 1) % len(parts)
        parts[i], parts[j] = parts[j], parts[i]
    elif move == "turn" and p.kind == "box":
        parts[i] = replace(p, turn_deg=float((p.turn_deg + rng.uniform(10, 80)) % 90.0))
    else:
        parts[i] = replace(p, width_mm=p.width_mm * (1.0 + STEP * rng.uniform(-1, 1)))
    return _repair(Stack(tuple(parts)), s)


def _accept(new: float, old: float, temperature: float, rng: np.random.Generator) -> bool:
    """Simulated annealing's rule on the mean cost: better is kept; worse by a relative r with
    probability exp(-r / temperature), the temperature falling to 0 over the search (one draw per
    step either way, so the sequence of changes does not depend on the costs' values)."""
    draw = rng.random()
    if new <= old:
        return True
    if not np.isfinite(new) or temperature <= 0:
        return False
    return draw < math.exp(-(new - old) / max(old, 1e-12) / temperature)


@dataclass
class Judged:
    stacks: tuple
    cost: np.ndarray  # (m, K) each object's least cost on each prop
    noticeable: np.ndarray  # (m, K)

    @property
    def score(self) -> tuple[float, int]:
        best = self.cost.min(axis=1)
        pick = self.cost.argmin(axis=1)
        loud = int(self.noticeable[np.arange(len(pick)), pick].sum())
        return (float(best.mean()) if np.isfinite(best).all() else math.inf, loud)


class Judge:
    """Judges props by the real pipeline, each stack once (written, loaded, sampled, searched)."""

    def __init__(self, virtuals: list[Candidates], match: MatchSettings, pinch: PinchSettings,
                 folder: Path, *, stand: bool = True, ranked: bool = False):
        self.virtuals, self.match, self.pinch, self.folder = virtuals, match, pinch, folder
        self.support = "auto" if stand else "none"
        # candidate props are ranked on target over their sampled poses (the felt ranking's landing
        # tables and steady search are made anew for every candidate's poses); ``ranked``: as the
        # run ranks (the finalists)
        self.config = Config(pinch,
                             replace(match, refine=False, rank=match.rank if ranked else "nominal"))
        self.model = cost_model(match, virtuals)
        self.rows: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self.evaluations = 0
        self.pruned = 0  # candidates given up before every object was judged
        self.judged: list[Judged] = []  # every set judged, in order

    def prop_rows(self, stack: Stack, bound: float = math.inf,
                  order: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(m,) each scene object's least cost on ``stack`` and (m,) whether it is noticed. The
        objects are judged in ``order`` (default: as given) and the judging stops once their costs
        add up to more than ``bound``: the objects left cost inf (the candidate cannot beat the one
        that set the bound)."""
        key = _key(stack)
        if key not in self.rows:
            path = self.folder / f"{key}.stl"
            path.write_bytes(stack_mesh(stack).export(file_type="stl"))
            m = len(self.virtuals)
            cost, loud = np.full(m, np.inf), np.ones(m, bool)
            try:
                prop = cached_candidates(ObjectSpec(str(path), support=self.support), cache=None,
                                         settings=self.pinch)
            except PinchmatchError:  # a prop with no feasible pinch serves nothing
                prop = None
            total = 0.0
            for j in (range(m) if order is None else order) if prop is not None else ():
                vm = match_one([prop], self.virtuals[j], self.config, model=self.model,
                               details=False)
                cost[j], loud[j] = vm.row[0], vm.row_noticed[0]
                total += cost[j]
                if total > bound:
                    self.pruned += 1
                    break
            self.rows[key] = (cost, loud)
            self.evaluations += 1
        return self.rows[key]

    def judge(self, stacks: tuple, prune: bool = False) -> Judged:
        """``stacks`` judged. With ``prune`` (one prop), given up early (:meth:`prop_rows`) once it
        cannot be among the ``FINALISTS`` best sets judged so far: its objects judged hardest first
        (by the best set's costs), the bound the total of the last of those."""
        whole = sorted((j for j in self.judged if np.isfinite(j.score[0])), key=lambda j: j.score)
        if prune and len(stacks) == 1 and len(whole) >= FINALISTS:
            rows = [self.prop_rows(stacks[0], float(whole[FINALISTS - 1].cost[:, 0].sum()),
                                   np.argsort(-whole[0].cost[:, 0], kind="stable"))]
        else:
            rows = [self.prop_rows(st) for st in stacks]
        judged = Judged(stacks, np.column_stack([r[0] for r in rows]),
                        np.column_stack([r[1] for r in rows]))
        self.judged.append(judged)
        return judged


@dataclass
class DesignResult:
    best: Judged
    history: list  # (evaluations, seconds, mean cost) after each improvement
    evaluations: int
    seconds: float
    first_evaluation_s: float
    pruned: int = 0  # candidates given up before every object was judged


def design_props(virtuals: list[Candidates], s: DesignSettings, *, match: MatchSettings,
                 pinch: PinchSettings, seeds: tuple = (), progress=None) -> DesignResult:
    """The best set of ``s.k`` stacks found for the scene (see the module notes).

    Parameters
    ----------
    virtuals : list of Candidates
        The scene's objects, sampled at the run's count.
    s : DesignSettings
        The design's options; ``s.budget_s`` is the search's own wall time.
    match, pinch : MatchSettings, PinchSettings
        The run's settings (the candidates are sampled at ``s.search_count`` poses).
    seeds : tuple of Stack
        Stacks judged before the proxy's (those fitted to a shelf's best props).
    progress : callable, optional
        ``progress(done, total, note)``, called after each judged candidate.

    Returns
    -------
    DesignResult

    Examples
    --------
    >>> from pinchmatch import MatchSettings, PinchSettings, analyze_object, candidate_poses
    >>> settings = PinchSettings(count=100, seed=0)
    >>> can = candidate_poses(analyze_object(can_obj, units="m"), settings=settings)
    >>> result = design_props([can], DesignSettings(evaluations=3, search_count=100),
    ...                       match=MatchSettings(refine=False), pinch=settings)
    >>> result.evaluations, [part.kind for part in result.best.stacks[0].parts]
    (3, ['cylinder'])
    """
    rng = np.random.default_rng(s.seed)
    search_pinch = replace(pinch, count=min(pinch.count, s.search_count))
    t0 = time.perf_counter()

    with tempfile.TemporaryDirectory(prefix="pinchmatch-design-") as folder:
        judge = Judge(virtuals, match, search_pinch, Path(folder), stand=s.stand)
        starts = list(dict.fromkeys([_repair(st, s) for st in seeds] + initial_stacks(virtuals, s)))
        judge.judge((starts[0],))
        first_s = time.perf_counter() - t0
        if first_s > s.budget_s and s.evaluations is None:
            raise ConfigError(f"--budget-s {s.budget_s:g}: judging one candidate takes "
                              f"{first_s:.1f} s here, more than the whole search may; give more")
        total = s.evaluations or max(1, int(s.budget_s / max(first_s, 1e-3)))

        def left() -> bool:
            if s.evaluations is not None:
                return judge.evaluations < s.evaluations
            spent = time.perf_counter() - t0
            return spent + spent / max(judge.evaluations, 1) < s.budget_s

        # the proxy's candidates, one prop at a time; for k > 1 the best ones side by side
        singles = []
        prune = s.k == 1 and s.anneal == 0.0
        for st in starts:
            if not left():
                break
            judged = judge.judge((st,), prune)
            singles.append((judged.score, len(singles), st, judged))
            if progress:
                progress(judge.evaluations, total, "proxy candidates")
        singles.sort(key=lambda x: (x[0], x[1]))
        chosen = tuple(st for _, _, st, _ in singles[:s.k]) if singles else (starts[0],)
        while len(chosen) < s.k:
            chosen += (mutate(chosen[-1], rng, s),)
        best = current = judge.judge(chosen)
        history = [(judge.evaluations, time.perf_counter() - t0, best.score[0])]
        while left():
            which = int(rng.integers(s.k))
            trial = list(current.stacks)
            trial[which] = mutate(trial[which], rng, s)
            judged = judge.judge(tuple(trial), prune)
            if _accept(judged.score[0], current.score[0],
                       s.anneal * (1.0 - judge.evaluations / total), rng):
                current = judged
            if judged.score < best.score:
                best = judged
                history.append((judge.evaluations, time.perf_counter() - t0, best.score[0]))
            if progress:
                progress(judge.evaluations, total, f"mean cost {best.score[0]:.3g}")
        # the finalists: the best few sets on target, ranked as the run ranks (the felt cost), the
        # best kept
        seen = sorted({judged.stacks: judged for judged in judge.judged}.values(),
                      key=lambda j: j.score)
        finalists = [j.stacks for j in seen[:FINALISTS] if np.isfinite(j.score[0])]
        if len(finalists) > 1 and match.rank != "nominal":
            ranker = Judge(virtuals, match, search_pinch, Path(folder), stand=s.stand, ranked=True)
            ranked = [ranker.judge(stacks) for stacks in finalists]
            best = min(ranked, key=lambda j: j.score)
            history.append((judge.evaluations, time.perf_counter() - t0, best.score[0]))
        for st in best.stacks:  # the repair keeps every candidate in the limits
            problems = stack_problems(st, max_height_mm=s.max_height_mm,
                                      max_width_mm=s.max_width_mm)
            if problems:
                raise InternalError(f"a designed stack is out of the limits: {'; '.join(problems)}")
        return DesignResult(best, history, judge.evaluations, time.perf_counter() - t0, first_s,
                            judge.pruned)
