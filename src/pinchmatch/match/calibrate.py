"""Criterion weights fitted to ratings: ``pinchmatch calibrate``.

The method weighs its criteria equally and says the weights "can (and should) be adjusted according
to their perceptual importance". Given rated pose pairs, where each pair's difference per criterion
is known in just-noticeable differences (``<criterion>_jnd``, as ``matches.json`` reports it under
``criteria``) and each rating says how well the prop corresponded to the virtual object (higher:
better, the study's 7-point scale), calibrate fits the model the cost itself uses
(:mod:`pinchmatch.match.cost`): the probability that the difference is noticed,

    P = 1 - 2^(-Σ_c w_c x_c^β)          (β = 3.5 for ``quick`` pooling, 2 for ``sum``)

and a rating that falls with it, ``rating = a - b·P`` (``a``: the rating of a perfect match, ``b``:
how much a surely noticed difference costs on the scale). The weights are absolute: w_c = 1 keeps
the literature's JND of criterion c, w_c = 2^β would halve it; a criterion not fitted (no column,
or left out of ``criteria``) keeps its default, 1 for the default criteria and 0 for ``com``. The
fit is nonlinear least squares (scipy's ``least_squares``, analytic Jacobian, w ≥ 0 and b ≥ 0)
started from several points.

**Held-out agreement.** Rows that rate the same placement are kept together: the folds of the
cross-validation split whole groups, a group joining the rows of one ``pair`` (else ``object`` and
``pose_source``) and the rows whose differences are identical (one placement reached from two pairs
is one placement; nothing in the table tells them apart). ``hold_out="object"`` instead leaves one
virtual object (``object`` column) out at a time. Each row's held-out prediction comes from the
weights fitted without its group; the report is Spearman's rank correlation between the held-out
predicted drop (b·P) and the rating (negative: costlier pairs are rated lower; -1 is perfect),
beside the same correlation for the default weights (all 1, whose ranking needs no fit).

**Kept defaults.** When the fitted weights rank the held-out rows worse than the defaults do, the
default weights are written (the fitted ones reported beside them) unless ``force``.

**Which criteria.** ``calibrate`` fits ``r.criteria``; :func:`fittable_criteria` gives those of a
table whose weights it can determine (what the command line fits when no criteria are named).

**Refused** (:class:`~pinchmatch.errors.ConfigError`): fewer rows than criteria + 3, fewer than 3
groups, ratings that never change, a criterion whose column never changes, reaches
:data:`SMALLEST_FITTED_JND` in fewer than two groups, or is a combination of the others (its weight
cannot be told apart), and criteria that do not predict the ratings (no fitted
weight above 0, or a held-out rank correlation that is not negative).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import spearmanr

from ..errors import ConfigError
from .cost import DEFAULT_CRITERIA, PAPER_CRITERIA, complete_weights
from .ratings import (Ratings, exponent_of, placement_groups, read_ratings,  # noqa: F401
                      read_weights_file)

#: folds of the cross-validation by placement (fewer when there are fewer groups)
FOLDS = 5
#: a column whose spread is below this (JND^β) does not change
CONSTANT_TOLERANCE = 1e-9
#: a criterion whose differences stay below this (JND) everywhere in the table is never near
#: noticeable there: its weight would be a guess (and a huge one fits as well as any)
SMALLEST_FITTED_JND = 0.1
#: where the fit starts: every weight at each of these (the best end is kept)
STARTS = (1.0, 0.25, 4.0)
#: a fitted weight or rating drop at most this is taken as 0 (the optimiser's bound, reached)
ZERO_FIT = 1e-9
#: ways of holding rows out
HOLD_OUTS = ("placement", "object")
#: resamples of the placements (with replacement) that give each fitted weight its interval
BOOTSTRAP = 100
#: the interval: these quantiles of the resampled weights (a 90 % interval)
INTERVAL = (0.05, 0.95)
#: a weight whose interval's ends differ by more than this factor is not determined by the table: it
#: keeps its default (within a factor of 2 either side of the estimate, a weight says something)
DETERMINED_RATIO = 4.0


@dataclass(frozen=True)
class Calibration:
    # every criterion of CRITERIA: the fitted ones, and the defaults for the others (1 for the
    # default criteria: the literature's JND, about which the table says nothing; 0 for com)
    weights: dict
    fitted_weights: dict  # what the fit found, kept or not
    kept: str  # "fitted" or "defaults"
    pooling: str
    intercept: float  # a: the rating of a match with nothing noticed
    drop: float  # b: how far a surely noticed difference lowers the rating
    held_out_spearman: float
    default_spearman: float
    folds: int
    hold_out: str
    rows: int
    pairs: int
    # {criterion: (low, high)}: each fitted weight's 90 % bootstrap interval
    intervals: dict = None
    # the fitted weights whose interval is too wide: kept at their defaults
    undetermined: tuple = ()

    @property
    def criteria(self) -> str:
        """The criteria set the weights are for: ``paper`` when they weigh ``com`` (the paper's
        seven, ``mass`` not in use), else ``default``."""
        return "paper" if self.weights.get("com", 0.0) > 0 else "default"

    def as_dict(self, source: str) -> dict:
        in_use = PAPER_CRITERIA if self.criteria == "paper" else DEFAULT_CRITERIA
        return {"schema": "pinchmatch.weights/1", "source": source, "pooling": self.pooling,
                "exponent": exponent_of(self.pooling), "criteria": self.criteria,
                "weights": {c: round(w, 6) if c in in_use else 0.0
                            for c, w in self.weights.items()},
                "fit": {"rows": self.rows, "placements": self.pairs, "folds": self.folds,
                        "hold_out": self.hold_out, "intercept_rating": round(self.intercept, 6),
                        "rating_drop_when_noticed": round(self.drop, 6),
                        "held_out_spearman_fitted": round(self.held_out_spearman, 4),
                        "held_out_spearman_default": round(self.default_spearman, 4),
                        "kept": self.kept,
                        "fitted_weights": {c: round(w, 6) for c, w in self.fitted_weights.items()},
                        "weight_intervals_90": {c: [round(lo, 6), round(hi, 6)]
                                                for c, (lo, hi) in (self.intervals or {}).items()},
                        "undetermined": list(self.undetermined)}}


#: why a criterion's weight cannot be determined, said of one criterion and of several
PLURAL = {"never changes": "never change",
          f"never differs by {SMALLEST_FITTED_JND} JND or more": "never differ by "
                                                                 f"{SMALLEST_FITTED_JND} JND or "
                                                                 "more",
          f"differs by {SMALLEST_FITTED_JND} JND or more in one placement only":
          f"differ by {SMALLEST_FITTED_JND} JND or more in one placement only"}


def undetermined(r: Ratings, beta: float) -> dict[str, str]:
    """{criterion: why} for the criteria of ``r`` whose weight the table cannot determine: a column
    that never changes, or whose differences reach :data:`SMALLEST_FITTED_JND` in fewer than two
    placements (one placement's rating fixes any weight, and leaving it out of the fit leaves
    nothing to fix it)."""
    x = r.jnd ** beta
    out = {}
    for k, c in enumerate(r.criteria):
        reached = len(np.unique(r.pair[r.jnd[:, k] >= SMALLEST_FITTED_JND]))
        if not len(x) or np.abs(x[:, k] - x[:, k].mean()).max() < CONSTANT_TOLERANCE:
            out[c] = "never changes"
        elif reached < 2:
            out[c] = (f"never differs by {SMALLEST_FITTED_JND} JND or more" if not reached else
                      f"differs by {SMALLEST_FITTED_JND} JND or more in one placement only")
    return out


def fittable_criteria(r: Ratings, *, pooling: str = "quick") -> tuple[tuple, dict]:
    """What ``calibrate`` fits when no criteria are named: the table's columns among the default
    cost's criteria whose weights it can determine, and {criterion left out: why} for the table's
    others (they keep their defaults). ``com`` is fitted only when named: fitted beside ``mass`` it
    would take part of the lever arm that the default cost charges to ``mass`` alone.

    Parameters
    ----------
    r : Ratings
        The rated pairs.
    pooling : {"quick", "sum"}
        The pooling the weights are to be fitted for.

    Returns
    -------
    (tuple of str, dict)
        The criteria that can be fitted, and {criterion left out: why}.

    Examples
    --------
    >>> r = read_ratings("pair,width_jnd,tilt_jnd,com_jnd,kmax_jnd,rating\\n1,0.2,0,0.3,0.1,6\\n"
    ...                  "2,1.5,0,0.1,0.3,3\\n3,0.7,0,0.2,2.0,2\\n", "ratings.csv")
    >>> fittable_criteria(r)
    (('width', 'kmax'), {'com': 'is not a default criterion (name it with --criteria)',
                         'tilt': 'never changes'})
    """
    why = undetermined(r, exponent_of(pooling))
    for c in r.criteria:
        if c not in DEFAULT_CRITERIA and c not in why:
            why[c] = "is not a default criterion (name it with --criteria)"
    return tuple(c for c in r.criteria if c not in why), {c: why[c] for c in r.criteria if c in why}


def _check(r: Ratings, beta: float) -> None:
    n, m = r.jnd.shape
    if n < m + 3:
        raise ConfigError(f"{r.source}: {n} rated rows cannot fix {m} weights and the rating "
                          "scale; "
                          f"rate at least {m + 3} trials, or fit fewer criteria with --criteria")
    if r.pair.max() + 1 < 3:
        raise ConfigError(f"{r.source}: {r.pair.max() + 1} distinct placements; rate at least 3 to "
                          "fit and check the weights")
    if np.ptp(r.rating) == 0:
        raise ConfigError(f"{r.source}: every rating is {r.rating[0]:g}, so they say nothing about "
                          "the criteria; rate pairs that differ")
    unknown = undetermined(r, beta)
    if unknown:
        named = {reason: [c for c in unknown if unknown[c] == reason]
                 for reason in unknown.values()}
        why = "; ".join(f"{', '.join(cs)} {reason if len(cs) == 1 else PLURAL[reason]}"
                        for reason, cs in named.items())
        if len(unknown) == len(r.criteria):
            raise ConfigError(f"{r.source}: {why} in the table, so no weight can be determined; "
                              "rate placements that differ in them")
        its = "its weight" if len(unknown) == 1 else "their weights"
        raise ConfigError(f"{r.source}: {why} in the table, so {its} cannot be determined; leave "
                          f"{'it' if len(unknown) == 1 else 'them'} out with --criteria "
                          f"{','.join(c for c in r.criteria if c not in unknown)}")
    x = r.jnd ** beta
    xc = x - x.mean(axis=0)
    scaled = xc / np.linalg.norm(xc, axis=0)
    if np.linalg.matrix_rank(scaled, tol=1e-8) < m:
        _, _, vt = np.linalg.svd(scaled, full_matrices=False)
        tied = [c for c, v in zip(r.criteria, vt[-1]) if abs(v) > 0.1]
        raise ConfigError(f"{r.source}: the differences in {', '.join(tied)} move together in "
                          "every row, so their "
                          "weights cannot be told apart; rate pairs where they differ, or leave "
                          "one out with --criteria")


def noticed(x_beta: np.ndarray, w: np.ndarray) -> np.ndarray:
    """P = 1 - 2^(-Σ w x^β) for rows of x^β."""
    return -np.expm1(-math.log(2.0) * (x_beta @ w))


def rating_model(theta: np.ndarray, x_beta: np.ndarray) -> np.ndarray:
    """The predicted ratings a - b·P(w) of rows x^β, theta = (a, b, w...)."""
    return theta[0] - theta[1] * noticed(x_beta, theta[2:])


def rating_jacobian(theta: np.ndarray, x_beta: np.ndarray) -> np.ndarray:
    """(n, 2 + m): the derivatives of :func:`rating_model` by a, b and each w (analytic)."""
    survive = np.exp(-math.log(2.0) * (x_beta @ theta[2:]))
    return np.column_stack([np.ones(len(x_beta)), -(1.0 - survive),
                            -theta[1] * math.log(2.0) * survive[:, None] * x_beta])


def _fit(x_beta: np.ndarray, rating: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Weights w >= 0, intercept a and drop b >= 0 minimising |rating - (a - b·P(w))|²."""
    m = x_beta.shape[1]

    def residual(theta):
        return rating_model(theta, x_beta) - rating

    def jacobian(theta):
        return rating_jacobian(theta, x_beta)

    lower = np.r_[-np.inf, 0.0, np.zeros(m)]
    best = None
    for start in STARTS:
        theta0 = np.r_[rating.max(), max(np.ptp(rating), 1e-3), np.full(m, start)]
        found = least_squares(residual, theta0, jac=jacobian, bounds=(lower, np.inf), xtol=1e-15,
                              ftol=1e-15, gtol=1e-15, max_nfev=2000)
        if best is None or found.cost < best.cost - 1e-15:
            best = found
    theta = best.x
    return theta[2:], float(theta[0]), float(theta[1])


def _spearman(cost: np.ndarray, rating: np.ndarray) -> float:
    if np.ptp(cost) == 0:
        return 0.0  # a cost that ranks nothing
    return float(spearmanr(cost, rating).statistic)


def _folds(r: Ratings, hold_out: str, seed: int) -> tuple[np.ndarray, int]:
    """(n,) fold of each row, and the number of folds."""
    if hold_out == "object":
        if r.obj is None:
            raise ConfigError(f"{r.source}: no 'object' column, so no virtual object can be held "
                              "out; use --hold-out placement")
        groups = int(r.obj.max()) + 1
        if groups < 3:
            raise ConfigError(f"{r.source}: {groups} virtual objects; hold out by object needs at "
                              "least 3")
        return r.obj, groups
    pairs = int(r.pair.max() + 1)
    folds = min(FOLDS, pairs)
    return (np.random.default_rng(seed).permutation(pairs) % folds)[r.pair], folds


def calibrate(r: Ratings, *, pooling: str = "quick", seed: int = 0, hold_out: str = "placement",
              force: bool = False) -> Calibration:
    """Fit the weights of ``r.criteria`` under ``pooling`` and cross-validate them (module notes).

    Parameters
    ----------
    r : Ratings
        The rated pairs (:func:`read_ratings`).
    pooling : {"quick", "sum"}
        How the criteria's differences are pooled into one cost.
    seed : int
        Seeds the bootstrap of the weights' intervals and the folds.
    hold_out : {"placement", "pair"}
        What a cross-validation fold holds out together.
    force : bool
        Fit even where the table is too small to determine a weight.

    Returns
    -------
    Calibration
        The fitted weights, their intervals, the held-out rank correlations against the defaults'.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> jnd = rng.uniform(0.0, 2.0, size=(24, 2))  # 24 rated pairs: width and kmax differences
    >>> noticed = 1 - 2.0 ** -(jnd ** 3.5 @ [1.0, 0.5])  # who weigh kmax half as much as width
    >>> rows = ["pair,width_jnd,kmax_jnd,rating"] + [
    ...     f"{k},{w:.4f},{c:.4f},{6.5 - 4 * p:.4f}"
    ...     for k, ((w, c), p) in enumerate(zip(jnd, noticed))]
    >>> fit = calibrate(read_ratings("\\n".join(rows), "ratings.csv"))
    >>> w = fit.weights
    >>> round(w["width"], 2), round(w["kmax"], 2), round(fit.intercept, 2), round(fit.drop, 2)
    (1.0, 0.5, 6.5, 4.0)
    """
    if hold_out not in HOLD_OUTS:
        raise ConfigError(f"--hold-out: unknown {hold_out!r}; use placement or object")
    if not isinstance(seed, int) or seed < 0:
        raise ConfigError(f"--seed: {seed!r} must be a whole number of 0 or more")
    if "com" in r.criteria and "mass" in r.criteria:
        raise ConfigError("--criteria: com and mass both charge the lever arm, and no criteria set "
                          "weighs both; fit "
                          "com (for --criteria paper) or mass (the default), not both")
    beta = exponent_of(pooling)
    _check(r, beta)
    x = r.jnd ** beta
    default_rho = _spearman(x.sum(axis=1), r.rating)
    defaults = complete_weights({})
    w, intercept, drop = _fit(x, r.rating)
    fold, folds = _folds(r, hold_out, seed)
    common = dict(pooling=pooling, intercept=intercept, drop=drop, default_spearman=default_rho,
                  folds=folds, hold_out=hold_out, rows=len(r.rating), pairs=int(r.pair.max() + 1))
    # the optimiser stops a hair above its bounds: a weight or a drop this small is none
    if not (w > ZERO_FIT).any() or drop <= ZERO_FIT * max(1.0, float(np.ptp(r.rating))):
        if default_rho < 0 and not force:  # the defaults rank the table: keep them, as below
            return Calibration(weights=defaults,
                               fitted_weights=defaults | dict(zip(r.criteria, map(float, w))),
                               kept="defaults", held_out_spearman=0.0, **common)
        raise ConfigError(_unpredictive(r, default_rho, "no weight above 0 fits them"))
    held_out = np.empty(len(r.rating))
    for f in range(folds):
        test = fold == f
        if not test.any():
            continue
        wf, _, bf = _fit(x[~test], r.rating[~test])
        held_out[test] = bf * noticed(x[test], wf)
    held = _spearman(held_out, r.rating)
    if not held < 0 and not (default_rho < 0 and not force):
        raise ConfigError(_unpredictive(r, default_rho,
                                        f"held out, the fitted cost does not fall with the rating "
                                                        f"(rank correlation {held:+.2f})"))
    intervals = _intervals(x, r, seed)
    loose = tuple(c for c, (lo, hi) in intervals.items() if not hi <= DETERMINED_RATIO * lo)
    fitted = defaults | {c: float(v) for c, v in zip(r.criteria, w)}
    kept = "fitted" if force or (held < 0 and held <= default_rho) else "defaults"
    weights = (fitted | {c: defaults[c] for c in loose
                         if not force}) if kept == "fitted" else defaults
    return Calibration(weights=weights, fitted_weights=fitted, kept=kept, held_out_spearman=held,
                       intervals=intervals, undetermined=loose if kept == "fitted" and not force
                       else (), **common)


def _intervals(x: np.ndarray, r: Ratings, seed: int) -> dict:
    """{criterion: (low, high)}: the ``INTERVAL`` quantiles of each weight refitted to ``BOOTSTRAP``
    resamples of the placements (with replacement, each placement's rows together), seeded."""
    rng = np.random.default_rng([seed, 1])
    pairs = int(r.pair.max() + 1)
    members = [np.flatnonzero(r.pair == k) for k in range(pairs)]
    found = np.empty((BOOTSTRAP, x.shape[1]))
    for b in range(BOOTSTRAP):
        rows = np.concatenate([members[k] for k in rng.integers(0, pairs, pairs)])
        found[b] = _fit(x[rows], r.rating[rows])[0]
    low, high = np.quantile(found, INTERVAL, axis=0)
    return {c: (float(lo), float(hi)) for c, lo, hi in zip(r.criteria, low, high)}


def _unpredictive(r: Ratings, default_rho: float, why: str) -> str:
    if default_rho > 0.3:
        return (f"{r.source}: the ratings rise as the differences grow (rank correlation "
                f"{default_rho:+.2f}); "
                "check the rating scale (higher: the prop corresponds better)")
    return (f"{r.source}: these criteria do not predict the ratings ({why}); rate more placements "
            "that differ in them, or fit other criteria with --criteria")
