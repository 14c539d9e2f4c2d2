"""The test spheres along a finger: how far each lies from the object, queried only where a decision
needs it.

The reach rule (:mod:`pinchmatch.grasp.hand`) stands a finger's axis on test spheres of radius ρ at
offsets s from the fingertip's centre. For a direction h, or a cell of directions around h whose
test centres move by at most s·δ, a row (one direction of one pinch, all its fingers) is

- **ruled out** when one sphere has d + s·δ < ρ (no direction in the cell clears);
- **fitting** when every sphere has d ≥ ρ (the centre clears, and its clearance is the least d);
- otherwise **open**, with the bound min(d + s·δ) by which the search ranks its cells, and the
  sphere that attains it first, which the next level queries first.

:func:`axis_distances` returns distances that decide all of these as the exact ones would, and
queries the KD-tree as little as it can:

1. The surface's coarse distance field (:mod:`pinchmatch.mesh.distance_field`) gives sure bounds of
   every sphere: one whose upper bound rules its row out decides without a query, and so does one
   sure to lie beyond the cap (on a 262k-face scanned mug, about 4 in 10 queries are spared).
2. A hinted sphere (the one that bounded the parent cell tightest) is queried next: most cells that
   can be dropped are dropped by it.
3. A gate, where the caller gives one, refuses rows that fail whatever their fingers meet (the hand
   behind them is stuck): they are not queried at all.
4. The rest are queried a pair at a time, coarse to fine along the finger, those whose s·δ is
   below ρ first (only they can rule a cell out), each pair only for the rows no earlier sphere
   ruled out. Once a row is known not to fit (some sphere is surely closer than ρ), a sphere
   whose s·δ alone exceeds a sure upper bound on the row's least d + s·δ is not queried: its
   term exceeds the bound, so it changes neither the bound nor the sphere that attains it.
"""

from __future__ import annotations

import numpy as np

from ..cores import query_tree

#: test spheres per finger queried together, each batch only where the earlier ones clear
STAGE_SPHERES = 2
#: how far under its threshold a distance field's bound must lie to stand for the query (mm):
#: rounding aside
DECIDED_BELOW_MM = 1e-6


def _coarse_to_fine(count: int) -> list[int]:
    """0 … count-1 ordered so that each prefix is spread along the finger: 0, the far end,
    then halving the gaps (a finger pushed into the object is usually caught early)."""
    order, seen, step = [], set(), 1 << max(count - 1, 1).bit_length()
    while step:
        for i in range(0, count, step):
            if i not in seen:
                seen.add(i)
                order.append(i)
        step //= 2
    return order


def _obstacle_distances(context, centres, cap, below, bounds):
    """(k,) distance from each centre to the nearest surface sample or to the half-space below the
    object's support (0 inside it), capped at ``cap``: both are 1-Lipschitz, as the bounds need.

    Where the surface's distance field already decides, no KD-tree query is made: a centre sure to
    lie at least ``cap`` from every sample reads ``cap`` (as the query would), and one sure to lie
    closer than its ``below`` (k,) reads the field's upper bound, which is also below it: the
    callers compare each distance with its ``below`` only, so every decision is the query's.
    ``bounds``: the field's (lower, upper) of these centres."""
    lower, upper = bounds
    q = np.where(lower >= cap, cap, upper)
    ask = np.flatnonzero((lower < cap) & (upper >= np.asarray(below) - DECIDED_BELOW_MM))
    if len(ask):
        exact, _ = query_tree(context.tree, centres[ask], k=1, distance_upper_bound=cap,
                              work=len(ask))
        q[ask] = exact
    q = np.minimum(q, cap)
    if context.support is not None:
        q = np.minimum(q, np.maximum(context.support.heights(centres), 0.0))
    return q


def axis_distances(context, tips, h, offsets, cap, rho, delta=None, first=None, gate=None):
    """The distances of a batch of finger directions, as far as their decisions need them: ``(d,
    refused)``.

    tips : (m, F, 3) fingertip centres (F fingers of one hand); h : (m, F, 3) each finger's
    direction; offsets : (P,) the spheres' s; delta : (m, F) how far, per mm along the finger, a
    test centre can move within the cell of directions around h (default 0: h alone); first : (m,)
    one sphere per row to query before the others (finger-major: finger · P + sphere; -1 none);
    gate : row indices -> bool, the rows still open that may be queried (default: all).

    d : (m, F, P) each sphere's distance to the nearest sample (or the support), capped at ``cap``,
    where a decision needs it; a sphere not queried reads its field bound where that is below ρ,
    else ``cap``. refused : (m,) bool, the rows the gate refused. Every other row's d decides what
    the exact distances would: ruled out, fitting (then d is exact), or open with the same bound and
    the same sphere attaining it first."""
    m, fingers = len(h), tips.shape[1]
    delta = np.zeros((m, fingers)) if delta is None else delta
    shape = (m, fingers, len(offsets))
    centres = tips[:, :, None, :] + offsets[None, None, :, None] * h[:, :, None, :]
    lower, upper = (b.reshape(shape) for b in context.distance_field.bounds(centres.reshape(-1, 3)))
    sure = (upper if context.support is None
            else np.minimum(upper, np.maximum(context.support.heights(centres), 0.0)))
    term = sure + offsets * delta[:, :, None]
    ruled = (term < rho - DECIDED_BELOW_MM).any(axis=(1, 2))
    close = sure < rho  # surely closer than ρ
    # such a sphere reads its upper bound until it is queried, any other ``cap``
    d = np.where(close, sure, cap)
    rows = np.flatnonzero(~ruled)
    # per row, a sure upper bound on its least d + offset·δ, and whether some sphere is surely
    # closer than ρ: then the centre does not fit, and a sphere whose offset·δ alone exceeds that
    # least decides nothing
    least = term.min(axis=(1, 2))
    blocked = close.any(axis=(1, 2))
    if first is not None and len(rows):
        hinted = rows[first[rows] >= 0]
        f, j = np.divmod(first[hinted], len(offsets))
        slack = offsets[j] * delta[hinted, f]
        q = _obstacle_distances(context, centres[hinted, f, j], cap, rho - slack,
                                (lower[hinted, f, j], upper[hinted, f, j]))
        d[hinted, f, j] = q
        least[hinted] = np.minimum(least[hinted], q + slack)
        blocked[hinted] |= q < rho
        rows = np.setdiff1d(rows, hinted[q + slack < rho], assume_unique=True)
    refused = np.zeros(m, dtype=bool)
    if gate is not None and len(rows):
        passed = gate(rows)
        refused[rows[~passed]] = True
        rows = rows[passed]
    # the spheres that can rule a row out first (offset·δ < ρ), coarse to fine, then those that
    # cannot
    order = _coarse_to_fine(len(offsets))
    reach_out = offsets * delta.max(initial=0.0) < rho
    order = [j for j in order if reach_out[j]] + [j for j in order if not reach_out[j]]
    for start in range(0, len(order), STAGE_SPHERES):
        if not len(rows):
            break
        stage = np.array(order[start:start + STAGE_SPHERES])
        slack = offsets[stage][None, None, :] * delta[rows, :, None]
        need = ~blocked[rows, None, None] | (slack <= least[rows, None, None])
        if first is not None:  # the hinted sphere was queried already
            need &= (np.arange(fingers)[:, None] * len(offsets)
                     + stage)[None] != first[rows, None, None]
        at = np.nonzero(need)
        r, f, j = rows[at[0]], at[1], stage[at[2]]
        # a sphere not asked decides nothing here, and keeps what it reads
        q = np.full(need.shape, cap)
        q[need] = d[r, f, j] = _obstacle_distances(context, centres[r, f, j], cap,
                                                   rho - slack[need],
                                                   (lower[r, f, j], upper[r, f, j]))
        least[rows] = np.minimum(least[rows], (q + slack).min(axis=(1, 2)))
        blocked[rows] |= (q < rho).any(axis=(1, 2))
        rows = rows[(q + slack >= rho).all(axis=(1, 2))]
    return d, refused
