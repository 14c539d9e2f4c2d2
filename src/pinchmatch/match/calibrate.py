"""Criterion weights fitted to ratings: ``pinchmatch calibrate``.

The method weighs its criteria equally and says the weights "can (and should) be adjusted according
to their perceptual importance". Given rated pose pairs, where each pair's difference per criterion
is known in just-noticeable differences (``<criterion>_jnd``, as ``matches.json`` reports it under
``criteria``) and each rating says how well the prop corresponded to the virtual object (higher:
better, the study's 7-point scale), the cost of a pair is

    cost = sum over criteria of  w_c * jnd_c**2          (the cost of ``--normalize jnd``)

and the fit is the least-squares line ``rating = a - cost`` with every ``w_c >= 0`` (scipy's
non-negative least squares on the centred table, so the intercept ``a`` is free). The weights are
then scaled so that they add up to the number of fitted criteria, as the defaults (all 1) do: costs
keep their size, and the ranking of pose pairs, all a match needs, is unchanged by the scale.

**Held-out agreement.** Pairs rated several times (repetitions, participants) are kept together:
the folds of the cross-validation split whole pairs (``pair`` column, else ``object`` and
``pose_source``, else each row is its own pair), so no pair is fitted and scored at once. Each
pair's held-out cost comes from the weights fitted without it; the report is Spearman's rank
correlation between held-out cost and rating (negative: costlier pairs are rated lower; -1 is
perfect), beside the same correlation for the default weights on the same rows.

**Refused** (:class:`~pinchmatch.errors.ConfigError`): fewer rows than criteria + 2, fewer than 3
pairs, ratings that never change, a criterion whose column never changes or is a combination of
the others (its weight cannot be told apart), and data where no criterion makes ratings fall: every
fitted weight 0, or a held-out rank correlation that is not negative.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls
from scipy.stats import spearmanr

from ..errors import ConfigError
from .cost import CRITERIA

#: folds of the cross-validation (fewer when there are fewer pairs)
FOLDS = 5
#: a column whose spread is below this (JND², after centring) does not change
CONSTANT_TOLERANCE = 1e-9


@dataclass(frozen=True)
class Ratings:
    """A ratings table: per row the rating, the difference per criterion (JND) and the pair it rates."""

    criteria: tuple
    jnd: np.ndarray  # (n, len(criteria))
    rating: np.ndarray  # (n,)
    pair: np.ndarray  # (n,) int: rows of one pose pair share a number
    source: str


@dataclass(frozen=True)
class Calibration:
    weights: dict  # every criterion of CRITERIA; 0 for those not fitted
    intercept: float
    scale: float  # rating points per unit of (rescaled) cost
    held_out_spearman: float
    default_spearman: float
    folds: int
    rows: int
    pairs: int

    def as_dict(self, source: str) -> dict:
        return {"schema": "pinchmatch.weights/1", "source": source,
                "weights": {c: round(w, 6) for c, w in self.weights.items()},
                "fit": {"rows": self.rows, "pairs": self.pairs, "folds": self.folds,
                        "intercept_rating": round(self.intercept, 6),
                        "rating_per_cost": round(self.scale, 6),
                        "held_out_spearman_fitted": round(self.held_out_spearman, 4),
                        "held_out_spearman_default": round(self.default_spearman, 4)}}


def read_ratings(text: str, source: str, *, criteria: tuple | None = None) -> Ratings:
    """Parse a ratings CSV: a ``rating`` column and one ``<criterion>_jnd`` column per criterion
    (only ``criteria`` if given); optional ``pair`` or ``object`` + ``pose_source`` group the rows."""
    rows = list(csv.DictReader(io.StringIO(text)))
    if not rows:
        raise ConfigError(f"{source}: no rated rows; give a CSV with a header and one row per rated trial")
    header = set(rows[0])
    if "rating" not in header:
        raise ConfigError(f"{source}: no 'rating' column; the table needs rating and <criterion>_jnd columns "
                          "(docs/study.md)")
    present = tuple(c for c in CRITERIA if f"{c}_jnd" in header)
    if criteria is not None:
        missing = [c for c in criteria if c not in present]
        if missing:
            raise ConfigError(f"{source}: no column {', '.join(f'{c}_jnd' for c in missing)}; "
                              "fit only the criteria the table has")
        present = tuple(c for c in CRITERIA if c in criteria)
    if not present:
        raise ConfigError(f"{source}: no <criterion>_jnd column (one of "
                          f"{', '.join(c + '_jnd' for c in CRITERIA)})")
    rated = [r for r in rows if (r.get("rating") or "").strip()]  # an unrated trial (skipped) is left out
    values = np.empty((len(rated), len(present) + 1))
    for i, r in enumerate(rated):
        for k, name in enumerate(("rating",) + tuple(f"{c}_jnd" for c in present)):
            try:
                values[i, k] = float(r[name])
            except (TypeError, ValueError):
                raise ConfigError(f"{source}: row {i + 2}: {name} = {r[name]!r} is not a number") from None
    if not np.isfinite(values).all() or (values[:, 1:] < 0).any():
        raise ConfigError(f"{source}: a rating or a difference is not finite, or a difference is negative; "
                          "the <criterion>_jnd columns are sizes in JND (0 or more)")
    if "pair" in header:
        keys = [r["pair"] for r in rated]
    elif {"object", "pose_source"} <= header:
        keys = [(r["object"], r["pose_source"]) for r in rated]
    else:
        keys = list(range(len(rated)))
    index: dict = {}
    pair = np.array([index.setdefault(k, len(index)) for k in keys], dtype=np.int64)
    return Ratings(present, values[:, 1:], values[:, 0], pair, source)


def _check(r: Ratings) -> None:
    n, m = r.jnd.shape
    if n < m + 2:
        raise ConfigError(f"{r.source}: {n} rated rows cannot fix {m} weights and the rating scale; "
                          f"rate at least {m + 2} trials, or fit fewer criteria with --criteria")
    if r.pair.max() + 1 < 3:
        raise ConfigError(f"{r.source}: {r.pair.max() + 1} distinct pose pairs; rate at least 3 to fit and "
                          "check the weights")
    if np.ptp(r.rating) == 0:
        raise ConfigError(f"{r.source}: every rating is {r.rating[0]:g}, so they say nothing about the "
                          "criteria; rate pairs that differ")
    x = r.jnd ** 2
    xc = x - x.mean(axis=0)
    flat = [c for c, s in zip(r.criteria, np.abs(xc).max(axis=0)) if s < CONSTANT_TOLERANCE]
    if flat:
        raise ConfigError(f"{r.source}: {', '.join(flat)} never changes in the table, so its weight cannot be "
                          f"determined; leave it out with --criteria "
                          f"{','.join(c for c in r.criteria if c not in flat)}")
    scaled = xc / np.linalg.norm(xc, axis=0)
    if np.linalg.matrix_rank(scaled, tol=1e-8) < m:
        _, _, vt = np.linalg.svd(scaled, full_matrices=False)
        tied = [c for c, v in zip(r.criteria, vt[-1]) if abs(v) > 0.1]
        raise ConfigError(f"{r.source}: the differences in {', '.join(tied)} move together in every row, so their "
                          "weights cannot be told apart; rate pairs where they differ, or leave one out with --criteria")


def _fit(x: np.ndarray, rating: np.ndarray) -> tuple[np.ndarray, float]:
    """Non-negative ``w`` and free ``a`` minimising |rating - (a - x @ w)|²."""
    xm, rm = x.mean(axis=0), rating.mean()
    w, _ = nnls(-(x - xm), rating - rm)
    return w, float(rm + xm @ w)


def _spearman(cost: np.ndarray, rating: np.ndarray) -> float:
    if np.ptp(cost) == 0:
        return 0.0  # a cost that ranks nothing
    return float(spearmanr(cost, rating).statistic)


def calibrate(r: Ratings, *, seed: int = 0) -> Calibration:
    """Fit the weights of ``r.criteria`` and cross-validate them by pose pair (module notes)."""
    _check(r)
    x = r.jnd ** 2
    w, intercept = _fit(x, r.rating)
    if not (w > 0).any():
        raise ConfigError(f"{r.source}: the ratings do not fall as any criterion's difference grows, so no "
                          "non-negative weights fit them; check the rating scale (higher: the prop corresponds "
                          "better)")
    pairs = int(r.pair.max() + 1)
    folds = min(FOLDS, pairs)
    fold_of_pair = np.random.default_rng(seed).permutation(pairs) % folds
    fold = fold_of_pair[r.pair]
    held_out = np.empty(len(r.rating))
    for f in range(folds):
        test = fold == f
        wf, _ = _fit(x[~test], r.rating[~test])
        held_out[test] = x[test] @ wf
    held = _spearman(held_out, r.rating)
    if not held < 0:
        raise ConfigError(f"{r.source}: on held-out pose pairs the fitted cost does not fall with the rating (rank "
                          f"correlation {held:+.2f}), so the ratings do not fall as the criteria's differences grow; "
                          "check the rating scale (higher: the prop corresponds better) and rate more pairs")
    scale = len(r.criteria) / w.sum()
    weights = dict.fromkeys(CRITERIA, 0.0)
    weights.update({c: float(v * scale) for c, v in zip(r.criteria, w)})
    return Calibration(weights=weights, intercept=intercept, scale=1.0 / scale,
                       held_out_spearman=held,
                       default_spearman=_spearman(x.sum(axis=1), r.rating), folds=folds,
                       rows=len(r.rating), pairs=pairs)


def read_weights_file(text: str, source: str) -> dict:
    """The weights of a ``weights.json`` that ``calibrate`` wrote (or any ``{"weights": {...}}``)."""
    import json

    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{source}: not JSON ({exc.msg}, line {exc.lineno}); give the weights.json that "
                          "'pinchmatch calibrate' writes") from None
    weights = doc.get("weights") if isinstance(doc, dict) else None
    if not isinstance(weights, dict) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                and math.isfinite(v) for v in weights.values()):
        raise ConfigError(f"{source}: needs a 'weights' object of criterion: number; give the weights.json "
                          "that 'pinchmatch calibrate' writes")
    return {str(k): float(v) for k, v in weights.items()}
