"""Refinement after the search: the best pairs followed on both surfaces until the cost settles.

The exact search (:mod:`pinchmatch.match.search`) finds the cheapest pairs among the sampled
poses; a sample is a sample, so another seed finds other pairs. First the targeted step
(:mod:`pinchmatch.match.targeted`) adds the poses each side needs, looked for by their features, and
the search runs over the union. Refinement then takes the ``SEEDS`` best distinct pairs on the best
tangible and the ``OTHER_SEEDS`` best on every other tangible that could serve the virtual object
(its least cost so far within ``CONTENDER_RATIO`` of the best tangible's), both in proportion to the
count above the default (:func:`seed_counts`), and improves each by a pattern search over the four
degrees of freedom of each pinch:

- the contacts move by ``step`` along the object's axis (projected off the pinch line) and
  across it, both ways: each alone, both together (the pinch slides) and both opposite (the
  pinch turns), sixteen moves per pose (a positive spanning set of the contacts' four
  dimensions, twice over), the same on the tangible and on the virtual object;
- a moved contact is put back on the surface where a finger closing along the pinch line
  meets it (a ray towards the other finger); every rule then checks the new pinch as any other
  (:func:`pinchmatch.grasp.pinches.check_pinches`), the hand model last and only for the moves a
  pair would take (below): the hand is tried first along the pose's own approach, then along the
  quick directions only, so a move that only the full search of hand directions would reach is
  not taken;
- every pair of (the pose and its moves) on both objects is evaluated exactly; the pair moves
  to the cheapest whose poses the hand reaches, when that is cheaper by more than
  ``IMPROVEMENT`` (relative), else the step halves; a pair stops when its step falls below
  ``LAST_STEP_MM``. Reach is checked in waves from the cheapest move on (``WAVE`` per pair at a
  time): the hand search is most of a pose's price and most moves are never taken, so only the
  moves found reachable join the candidates.

The moves are built from the pinch itself and the object's principal axis, never from the
file's frame or the seed, so a rotated copy of an object moves alike. The new feasible poses
join the sampled ones, and the search runs again, exactly, over the union: the answer is the
best pair of the refined set, with alternatives, cost row and everything else as before.

A side whose poses were given (``--tangible-poses``, ``--virtual-poses``) is not moved.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..grasp.curvature import tangent_frame
from ..grasp.pinches import PinchSettings, Pinches, check_pinches, check_reach, closing_directions
from ..grasp.spread import other_order
from ..grasp.tripod_rules import Tripods, check_tripods
from .candidates import (REFINED_INDEX, Candidates, extend, felt_table, mass_ratio,  # noqa: F401
                         with_count)
from .cost import CostModel, separable_terms
from .search import Search, cost_row, evaluate_pairs
from .targeted import targeted_poses

#: distinct best pairs refined per tangible, at the default count (in proportion above it:
#: :func:`seed_counts`)
SEEDS = 2
#: on the other contending tangibles, this many
OTHER_SEEDS = 1
#: at most this many on the best tangible (and half as many on the others), however large the count
MAX_SEEDS = 16
#: tangibles whose sampled least cost is at most this times the best tangible's are refined
CONTENDER_RATIO = 1.5
#: the first and the smallest step of a contact (mm)
FIRST_STEP_MM, LAST_STEP_MM = 4.0, 0.5
#: a move is taken when it lowers the pair's cost by more than this share
IMPROVEMENT = 1e-3
#: rounds at most (each either moves a pair or halves its step)
MAX_ROUNDS = 16


@dataclass
class _Grown:
    """One object's candidates with the poses refinement added so far (after the sampled ones)."""

    current: Candidates

    def add(self, pinches: Pinches) -> np.ndarray:
        """Append feasible ``pinches``; their indices in the grown list."""
        start = len(self.current)
        self.current = extend(self.current, pinches)
        return start + np.arange(len(pinches))


def move_directions(points: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """(k, 2, 3) unit directions perpendicular to each pinch line (a tripod's: from the thumb to the
    middle of its fingers): along the object's ``axis``
    projected off the line, and across it (the line x that). Where the axis lies along the line,
    any perpendicular pair."""
    u = points[:, 1:].mean(axis=1) - points[:, 0]
    u = u / np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-300)
    along = axis[None, :] - (u @ axis)[:, None] * u
    size = np.linalg.norm(along, axis=1)
    fallback = tangent_frame(u)[0]
    along = np.where((size > 1e-3)[:, None], along / np.maximum(size, 1e-300)[:, None], fallback)
    across = np.cross(u, along)
    return np.stack([along, across], axis=1)


#: the moves of a pose, per contact (p1, p2): which direction (0: e1, 1: e2) and how far in steps.
#: Each contact alone, both together (the pinch slides) and both opposite (the pinch turns),
#: along e1 and e2, both ways: 16 moves
MOVES = np.array([(d, sign * a, sign * b) for a, b in ((1, 0), (0, 1), (1, 1), (1, -1))
                  for d in (0, 1)
                  for sign in (1, -1)], dtype=np.int64)
#: a tripod's (thumb, index, middle): each contact alone, all together (the tripod slides), the
#: thumb against the fingers (it turns about the fingers' middle) and the fingers against each other
#: (they turn about the aperture line), along e1 and e2, both ways: 24 moves
TRIPOD_MOVES = np.array([(d, sign * a, sign * b, sign * c)
                         for a, b, c in ((1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1), (1, -1, -1),
                                         (0, 1, -1))
                         for d in (0, 1) for sign in (1, -1)], dtype=np.int64)


def moved_poses(c: Candidates, poses: np.ndarray,
                steps: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The moves of each pose (``MOVES``): (m, 2, 3) contacts, (m, 2) triangles and (m,) which
    pose each came from, for the moves whose moved contacts a closing finger meets.

    A contact moves by its pose's step along e1 or e2 (:func:`move_directions`); its finger then
    closes along the new pinch line from its own side, from ``2·step + 1`` mm back, and the
    contact is the first surface the finger meets facing it. A contact that does not move stays."""
    points = c.pinches.points[poses]
    fingers = points.shape[1]
    dirs = move_directions(points, c.obj.props.principal_axis)  # (k, 2, 3)
    table = MOVES if fingers == 2 else TRIPOD_MOVES
    k, n_moves = len(poses), len(table)
    which = np.repeat(np.arange(k), n_moves)
    move = np.tile(table, (k, 1))
    step = steps[which]
    offset = dirs[which, move[:, 0]]  # (m, 3)
    new = points[which] + (move[:, 1:, None] * step[:, None, None]) * offset[:, None, :]
    faces = c.pinches.face_index[poses][which].copy()
    toward = closing_directions(new)
    back = 2.0 * step + 1.0
    ok = np.ones(len(which), dtype=bool)
    for contact in range(fingers):
        rows = np.flatnonzero(move[:, 1 + contact] != 0)
        point, face = close_fingers(c.obj.context, new[rows, contact], toward[rows, contact],
                                    back[rows])
        met = face >= 0
        ok[rows[~met]] = False
        new[rows[met], contact] = point[met]
        faces[rows[met], contact] = face[met]
    return new[ok], faces[ok], which[ok]


def close_fingers(context, points: np.ndarray, toward: np.ndarray,
                  back_mm) -> tuple[np.ndarray, np.ndarray]:
    """Where fingers closing along ``toward`` from ``back_mm`` (a number, or one per point) behind
    ``points`` first meet a surface facing them, within twice that: (n, 3) contacts and (n,)
    triangles, -1 where they meet none."""
    back = np.broadcast_to(np.asarray(back_mm, dtype=np.float64), (len(points),))
    origin = points - back[:, None] * toward
    face, dist = context.first_hit(origin, toward)
    met = (face >= 0) & (dist <= 2.0 * back)
    # met from outside
    met[met] = np.einsum("ij,ij->i", context.face_normals[face[met]], toward[met]) < 0
    contact = origin + np.where(np.isfinite(dist), dist, 0.0)[:, None] * toward
    return contact, np.where(met, face, -1)


@dataclass
class _Moves:
    """One object's moves in a round, every rule but ``reach`` checked.

    Move k has the index ``base + k`` in the round's extended candidates (the grown list, then the
    moves); ``which`` says which of the round's poses it came from, ``approach`` is that pose's
    (tried first when reach is checked), and ``reached`` is 1 once reach holds, -1 once it does not,
    0 before.
    """

    pinches: Pinches | None
    which: np.ndarray
    approach: np.ndarray
    base: int

    def __post_init__(self):
        self.reached = np.zeros(len(self.which), dtype=np.int8)


def propose(grown: "_Grown", poses: list[int], steps: list[float], settings: PinchSettings, *,
            fixed: bool) -> _Moves:
    """The moves of ``poses`` (their ``steps``) on ``grown``'s object that keep every rule but
    reach."""
    base = len(grown.current)
    if fixed or not poses:
        return _Moves(None, np.zeros(0, dtype=np.int64), np.zeros((0, 3)), base)
    c = grown.current
    poses = np.asarray(poses, dtype=np.int64)
    points, faces, which = moved_poses(c, poses, np.asarray(steps, dtype=np.float64))
    if not len(points):
        return _Moves(None, which, np.zeros((0, 3)), base)
    if isinstance(c.pinches, Tripods):
        checked = check_tripods(c.obj.context, points, faces, settings=settings, with_reach=False)
    else:
        checked = check_pinches(c.obj.context, points[:, 0], points[:, 1], settings=settings,
                                faces=faces, with_reach=False)
    keep = np.flatnonzero(checked.feasible)
    return _Moves(checked.subset(keep), which[keep], c.pinches.approach[poses][which[keep]], base)


def _confirm(context, moves: _Moves, rows: np.ndarray, settings: PinchSettings) -> None:
    """Check reach for the moves ``rows`` (those not checked yet), the quick directions only, each
    move's parent's approach first."""
    rows = np.unique(rows)
    rows = rows[moves.reached[rows] == 0]
    if not len(rows):
        return
    moves.pinches = check_reach(context, moves.pinches, settings=settings,
                                approach=moves.approach[rows], thorough=False, rows=rows)
    moves.reached[rows] = np.where(moves.pinches.feasible[rows], 1, -1)


@dataclass
class _Pair:
    """One refined pair: its tangible, its poses in the grown lists, its cost and step."""

    tangible: int
    t_pose: int
    v_pose: int
    cost: float
    step: float


#: each verification wave checks reach for up to this many of a pair's cheapest remaining moves
WAVE = 2


def refine(tangibles: list[Candidates], virtual: Candidates,
           seeds: list[tuple[int, int, int, float]], model: CostModel, *, keep_upright: bool,
           settings: PinchSettings, redirect=None, user_mm=None) -> tuple[list, Candidates]:
    """Pattern search from ``seeds`` (tangible, tangible pose, virtual pose, cost); returns every
    tangible's candidates and the virtual object's, with the feasible poses the search visited
    (``redirect``, ``user_mm``: the hand's redirection and where the user stands, as
    :func:`pinchmatch.match.search.evaluate_pairs` takes them).

    Each round, every move keeping the rules but reach is costed against the other side's moves;
    a pair then takes its cheapest improving move whose poses reach holds for, checked in waves
    from the cheapest on (the hand search is most of a pose's price, and most moves are never
    taken). The moves found reachable join the candidates; the others are forgotten."""
    grown_t = [_Grown(t) for t in tangibles]
    grown_v = _Grown(virtual)
    pairs = [_Pair(t, it, iv, cost, FIRST_STEP_MM) for t, it, iv, cost in seeds]
    for _ in range(MAX_ROUNDS):
        live = [p for p in pairs if p.step >= LAST_STEP_MM]
        if not live:
            break
        t_moves = {t: propose(grown_t[t], [p.t_pose for p in live if p.tangible == t],
                              [p.step for p in live if p.tangible == t], settings,
                              fixed=tangibles[t].given)
                   for t in sorted({p.tangible for p in live})}
        v_moves = propose(grown_v, [p.v_pose for p in live], [p.step for p in live], settings,
                          fixed=virtual.given)
        V = grown_v.current if v_moves.pinches is None else extend(grown_v.current, v_moves.pinches)
        # live pair -> its improving (tangible pose, virtual pose, cost), cheapest first
        options = {}
        for t, moves in t_moves.items():
            T = grown_t[t].current if moves.pinches is None else extend(grown_t[t].current,
                                                                        moves.pinches)
            mine = [(i, p) for i, p in enumerate(live) if p.tangible == t]
            its, ivs, owner = [], [], []
            for k, (i, p) in enumerate(mine):
                ts = np.concatenate([[p.t_pose], moves.base + np.flatnonzero(moves.which == k)])
                vs = np.concatenate([[p.v_pose], v_moves.base + np.flatnonzero(v_moves.which == i)])
                its.append(np.repeat(ts, len(vs)))
                ivs.append(np.tile(vs, len(ts)))
                owner.append(np.full(len(ts) * len(vs), k))
            it, iv, owner = np.concatenate(its), np.concatenate(ivs), np.concatenate(owner)
            # exactly evaluated only where the separable bound leaves room for an improvement: a
            # pair left out costs at least its bound, so it could not have been taken
            needed = np.array([p.cost for _, p in mine])[owner] * (1.0 - IMPROVEMENT)
            # round-off
            bound = model.bound_from_separable(separable_sums(T, V, it, iv, model)) * (1.0 - 1e-9)
            ask = np.flatnonzero(bound < needed)
            cost = np.full(len(it), np.inf)
            if len(ask):
                cost[ask] = evaluate_pairs(T, V, it[ask], iv[ask], model=model,
                                           keep_upright=keep_upright, redirect=redirect,
                                           user_mm=user_mm).cost
            for k, (i, p) in enumerate(mine):
                rows = np.flatnonzero((owner == k) & (cost < p.cost * (1.0 - IMPROVEMENT)))
                rows = rows[np.argsort(cost[rows], kind="stable")]
                options[i] = (it[rows], iv[rows], cost[rows])
        taken = _take_reachable(live, options, t_moves, v_moves, grown_t, grown_v, settings)
        t_index = {t: _keep_reached(grown_t[t], moves) for t, moves in t_moves.items()}
        v_index = _keep_reached(grown_v, v_moves)
        for i, p in enumerate(live):
            if i in taken:
                it, iv, cost = taken[i]
                p.t_pose, p.v_pose, p.cost = (int(t_index[p.tangible][it]), int(v_index[iv]),
                                              float(cost))
            else:
                p.step /= 2.0
    return [g.current for g in grown_t], grown_v.current


def _take_reachable(live, options, t_moves, v_moves, grown_t, grown_v, settings) -> dict:
    """Per live pair, its cheapest option whose moved poses reach holds for: {pair: (t, v, cost)},
    in the round's extended indices. Reach is checked in waves, ``WAVE`` options per pair at a
    time."""
    first = {i: 0 for i, (it, _, _) in options.items() if len(it)}
    taken = {}

    def state(moves, index):
        return 1 if index < moves.base else int(moves.reached[index - moves.base])

    while first:
        ask_t, ask_v = {}, []
        for i, start in first.items():
            it, iv, _ = options[i]
            moves = t_moves[live[i].tangible]
            looked = 0
            for r in range(start, len(it)):
                if looked >= WAVE:
                    break
                a, b = state(moves, it[r]), state(v_moves, iv[r])
                if a < 0 or b < 0:
                    continue
                looked += 1
                if a == 0:
                    ask_t.setdefault(live[i].tangible, []).append(it[r] - moves.base)
                if b == 0:
                    ask_v.append(iv[r] - v_moves.base)
        for t, rows in sorted(ask_t.items()):
            _confirm(grown_t[t].current.obj.context, t_moves[t], np.array(rows), settings)
        if ask_v:
            _confirm(grown_v.current.obj.context, v_moves, np.array(ask_v), settings)
        for i in sorted(first):
            it, iv, cost = options[i]
            moves = t_moves[live[i].tangible]
            r = first[i]
            while r < len(it) and (state(moves, it[r]) < 0 or state(v_moves, iv[r]) < 0):
                r += 1
            if r == len(it):
                del first[i]
            elif state(moves, it[r]) > 0 and state(v_moves, iv[r]) > 0:
                taken[i] = (it[r], iv[r], cost[r])
                del first[i]
            else:
                first[i] = r
    return taken


def _keep_reached(grown: _Grown, moves: _Moves) -> np.ndarray:
    """Add the moves reach holds for to ``grown``; the map from the round's extended indices to the
    grown list's (-1 for moves not kept)."""
    index = np.concatenate([np.arange(moves.base), np.full(len(moves.which), -1)])
    ok = np.flatnonzero(moves.reached > 0)
    if len(ok):
        index[moves.base + ok] = grown.add(moves.pinches.subset(ok))
    return index


def separable_sums(T: Candidates, V: Candidates, it: np.ndarray, iv: np.ndarray,
                   model: CostModel) -> np.ndarray:
    """(k,) S = Σ w·t of each pair in its better finger order, with the ``mass`` term's lower
    bound: what the blockwise pass computes (:func:`pinchmatch.match.cost.pair_cost_blocks`), for
    given pairs."""
    t_rows = T.table[it]
    v_rows = felt_table(V.table[iv], mass_ratio(T, V))
    w = model.weight_vector()
    other = other_order(v_rows.shape[1])
    return np.minimum(separable_terms(t_rows, v_rows, model) @ w,
                      separable_terms(t_rows, v_rows[:, other], model) @ w)


def seed_counts(count: int) -> tuple[int, int]:
    """How many distinct best pairs refinement starts from on the best tangible and on each other
    contender at a sampling count of ``count`` poses per object: ``SEEDS`` and ``OTHER_SEEDS`` up to
    the default count, in proportion above it. A denser sample holds more pairs near each good one
    on target, so the few best of a smaller sample (whose poses a nested larger sample holds) lie
    further down its order: starting from as many in proportion, refinement still climbs the basins
    the smaller sample's starts did."""
    return with_count(SEEDS, count, MAX_SEEDS), with_count(OTHER_SEEDS, count, MAX_SEEDS // 2)


def refined_search(tangibles: list[Candidates], virtual: Candidates, model: CostModel, settings, *,
                   pinch_settings: PinchSettings) -> Search:
    """The exact search of one virtual object against every tangible, over the sampled poses and,
    unless ``settings.refine`` is off, the poses the targeted step
    (:mod:`pinchmatch.match.targeted`) and then refinement found (see the module's notes).

    Which tangibles are refined depends on the costs before refinement alone, not on which tangibles
    the object may use in the end (``--one-to-one``), so a cost row and a result agree."""
    search = Search(tangibles, [virtual], model, settings)
    if not settings.refine or (virtual.given and all(t.given for t in tangibles)):
        return search
    row = cost_row(search, 0)
    finite = np.isfinite(row)
    if not finite.any():
        return search
    grown_t, grown_v = targeted_poses(search, pinch_settings)
    search = search.grown(grown_t, [grown_v])
    row = cost_row(search, 0)
    finite = np.isfinite(row)
    best = float(row[finite].min())
    on_best, on_other = seed_counts(pinch_settings.count)
    seeds = [(int(t), c.t_pose, c.v_pose, c.cost)
             for t in np.flatnonzero(finite & (row <= CONTENDER_RATIO * best))
             for c in search.choices(0, [int(t)], on_best if row[t] == best else on_other)]
    grown_t, grown_v = refine(search.tangibles, search.virtuals[0], seeds, model,
                              keep_upright=settings.keep_upright, settings=pinch_settings,
                              redirect=settings.redirect, user_mm=settings.user_mm)
    return search.grown(grown_t, [grown_v])
