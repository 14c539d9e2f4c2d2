"""How different two pinches feel: the method's 14-number comparison (Step #3), pooled.

A pose is described by 14 numbers, the 7 features of each patch, the pose
features (width, com distance, tilt) appearing in both. Each difference is
divided by a scale; a criterion's *contribution* t_c is the mean over its
entries of (difference / scale)², so that x_c = √t_c is the criterion's
difference in scale units (in just-noticeable differences with ``jnd``).

The criteria are pooled (``pooling``):

- ``"quick"`` (default): probability summation of independent cues (Quick
  1974). Each criterion is detected with the Weibull psychometric function
  P_c = 1 - 2^(-w_c x_c^β), 1 JND being the 50 % detection level; detecting
  any of them is P = 1 - Π(1 - P_c) = 1 - 2^(-D^β) with the cost
  D = (Σ w_c x_c^β)^(1/β), β = :data:`QUICK_EXPONENT`. D is in JND: D = 1
  is noticed half of the time, whatever the number of criteria behind it.
- ``"sum"``: the paper's weighted sum of squares Σ w_c t_c (with
  ``--criteria paper --normalize range``, the paper's algorithm exactly).

Beyond the paper, the ``mass`` criterion compares where the mass is felt
and seen: |R·o_V - o_T|² / s², with o = centre of mass - pinch midpoint and
R the registration's rotation. It depends on the registration, so the
search works with its lower bound ((Δ along the line)² + (Δ lever arm)²) / s²,
which is separable like the paper's terms, and evaluates the exact term on
the few pairs that the bound cannot rule out (see :mod:`pinchmatch.match.search`).

Scales (``normalize``):

- ``"jnd"``: just-noticeable differences from ``shared/paper/perception.md``,
  relative to the tangible's value, with absolute floors near zero. A
  contribution of 1 means "just noticeable".
- ``"range"``: the paper's own choice, each feature's range over all
  candidate poses of the run.

Since every scale depends on the tangible side only, each term
a·(v - t)² splits into products of a tangible factor and a virtual
factor, so a whole block of pose pairs is one matrix product (BLAS) per
finger order: exact, and fast enough for 10,000 x 10,000 pairs.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError
from ..config import (CRITERIA, DEFAULT_CRITERIA, MAX_WEIGHT, PAPER_CRITERIA,  # noqa: F401
                      POOLINGS, Weights, complete_weights)
from ..config import WIDTH_JND_FLOOR_MM, WIDTH_JND_FRACTION  # noqa: F401 (re-exported)
from ..config import REST_FLOAT_MM_PER_JND, REST_SINK_MM_PER_JND
from ..grasp.features import PinchFeatures
from ..grasp.spread import other_order

#: Quick pooling's exponent, the common slope of the criteria's Weibull psychometric functions: 3.5,
#: the slope at which a Weibull function matches a cumulative Gaussian (Quick 1974), within the 3-4
#: that detection studies find when they pool independent cues (Graham 1989; Robson & Graham 1981)
QUICK_EXPONENT = 3.5
#: the probability that a difference of 1 JND is noticed: every threshold of the JND table is a 50 %
#: detection level (a 75 %-correct two-alternative threshold, corrected for guessing)
DETECTION_AT_ONE_JND = 0.5

#: orientations: 43.8 % of the reference angle, floor: 20° (edge orientation on the fingerpad,
#: Bensmaia)
ANGLE_JND_FRACTION, ANGLE_JND_FLOOR_DEG = 0.438, 20.0
#: curvature: 66.66 % of the reference, floor: 2 /m (2 cm stimuli, Gordon & Morison)
CURVATURE_JND_FRACTION, CURVATURE_JND_FLOOR_PER_M = 0.6666, 2.0
#: distance from the centre of mass: no published threshold; proprioceptive accuracy, about 20 mm
COM_JND_MM = 20.0
#: mass offset: the torque of a weight held in a pinch scales with the lever arm; static weight in a
#: pinch is discriminated at a Weber fraction of 22-44 % (van Beek et al. 2021): 22 % of the
#: tangible's offset, floor 20 mm (proprioceptive accuracy, as for d)
MASS_JND_FRACTION, MASS_JND_FLOOR_MM = 0.22, 20.0
#: a tripod's lever arm: the torque it pulls with is discriminated at 12.7 % (Jandura and Srinivasan
#: 1994, 60 mN·m); the same floor
TORQUE_JND_FRACTION = 0.127

#: ``range`` normalisation: a feature whose range is below this (in its unit) is constant over the
#: run
RANGE_TOLERANCE = 1e-6

#: columns of a feature table, per patch; the last two belong to ``mass``
COLUMNS = ("width", "com", "tilt", "normal", "axis", "kmax", "kmin", "mass_along", "mass_perp")
#: criterion index of each column
COLUMN_CRITERION = np.array([0, 1, 2, 3, 4, 5, 6, 7, 7])
#: the columns of the ``mass`` criterion (offset along the pinch line, lever arm)
MASS_COLUMNS = [7, 8]
N_COLUMNS = len(COLUMNS)


def feature_table(features: PinchFeatures) -> np.ndarray:
    """(n, F, 9) float64: per pose and patch (F = 2 for a pinch, 3 for a tripod), the columns of
    COLUMNS (NaN = undefined ρ).

    A tripod's ``width`` column holds its two widths: the aperture in the thumb's row and the
    fingers' spacing in theirs, so that its width criterion pools both in width JNDs (a third the
    aperture's, two thirds the spacing's: two fingertips feel the spacing, a documented choice)."""
    n, fingers = features.normal_angle_deg.shape
    # (n, 3)
    pose = np.stack([features.width_mm, features.com_distance_mm, features.tilt_deg], axis=-1)
    pose = np.repeat(pose[:, None, :], fingers, axis=1)
    if fingers == 3:
        pose[:, 1:, 0] = features.spacing_mm[:, None]
    patch = np.stack([features.normal_angle_deg, features.curvature_axis_angle_deg,
                      features.kappa_max_per_m, features.kappa_min_per_m, features.mass_along_mm,
                      # (n, F, 6)
                      np.broadcast_to(features.mass_perp_mm[:, None], (n, fingers))], axis=-1)
    return np.concatenate([pose, patch], axis=-1)


def parse_weights(text: str | None, *, criteria: tuple = DEFAULT_CRITERIA) -> dict[str, float]:
    """Parse ``"width=1,com=0.5"`` into the weights given, checked by :func:`complete_weights`."""
    given: dict[str, float] = {}
    for item in str(text or "").split(","):
        if not item.strip():
            continue
        name, sep, value = item.partition("=")
        name = name.strip()
        if name in given:
            raise ConfigError(f"--weights: {name!r} is named twice; give each criterion once")
        try:
            w = float(value) if sep else float("nan")
        except ValueError:
            raise ConfigError(f"--weights: {item.strip()!r} needs a weight of 0 or more, as "
                              f"{name}=1") from None
        given[name] = w
    return complete_weights(given, criteria=criteria)


def parse_criteria(text: str | None) -> tuple:
    """``"default"`` (the paper's seven with mass for com) or ``"paper"`` (the seven)."""
    if text in (None, "default"):
        return DEFAULT_CRITERIA
    if text == "paper":
        return PAPER_CRITERIA
    raise ConfigError(f"--criteria: unknown set {text!r}; use default (the paper's seven with mass "
                      "for com) or paper")


@dataclass(frozen=True)
class CostModel:
    """How pose differences are scaled and weighted.

    weights : criterion -> float >= 0, completed by :func:`complete_weights` (1 for the criteria in
        use that are not given, 0 for the others); held as a read-only mapping
    normalize : ``"jnd"`` or ``"range"``
    ranges : (9,) float64, per column, for ``"range"`` (see :func:`feature_ranges`)
    criteria : the criteria in use (reported); the others have weight 0
    pooling : ``"quick"`` or ``"sum"`` (module notes)
    rest_mm_per_jnd : (sink, hover), the mm of visible gap between a placed object and its prop's
    support
        that cost one JND (:mod:`pinchmatch.match.rest`)
    scan_trust : the expected cost adds the spread of a scanned prop's features at its scan's
        error (:mod:`pinchmatch.match.trust`)

    >>> model = CostModel({"width": 2.0})
    >>> model.weights["width"], model.weights["com"], model.weights["kmax"]
    (2.0, 0.0, 1.0)
    >>> float(model.p_noticed(1.0))
    0.5
    """

    weights: Mapping = field(default_factory=dict)
    normalize: str = "jnd"
    ranges: np.ndarray | None = None
    criteria: tuple = DEFAULT_CRITERIA
    pooling: str = "quick"
    rest_mm_per_jnd: tuple = (REST_SINK_MM_PER_JND, REST_FLOAT_MM_PER_JND)
    scan_trust: bool = False

    def __post_init__(self):
        if self.normalize not in ("jnd", "range"):
            raise ConfigError(f"--normalize: unknown mode {self.normalize!r}; use jnd or range")
        if self.normalize == "range" and self.ranges is None:
            raise ConfigError("range normalisation needs the feature ranges of the run")
        if self.pooling not in POOLINGS:
            raise ConfigError(f"--pooling: unknown pooling {self.pooling!r}; use quick "
                              "(probability summation, "
                              "the default) or sum (the paper's sum of squares)")
        object.__setattr__(self, "criteria", tuple(self.criteria))
        full = complete_weights(dict(self.weights), criteria=self.criteria)
        object.__setattr__(self, "weights", Weights(full))

    @property
    def uses_mass(self) -> bool:
        return self.weights["mass"] > 0

    @property
    def exponent(self) -> float:
        """β: the pooling's exponent (2 for ``sum``, whose cost is Σ w x²)."""
        return QUICK_EXPONENT if self.pooling == "quick" else 2.0

    def as_jnd(self) -> "CostModel":
        """The same criteria, weights and pooling, in just-noticeable differences (for
        ``p_noticed``)."""
        return CostModel(self.weights, "jnd", None, self.criteria, self.pooling,
                         self.rest_mm_per_jnd, self.scan_trust)

    def weight_vector(self) -> np.ndarray:
        """(8,) the weights in the order of :data:`CRITERIA`."""
        return np.array([self.weights[c] for c in CRITERIA])

    def pool(self, terms: np.ndarray, *, extra: np.ndarray | None = None, rest=None) -> np.ndarray:
        """The cost of (..., 8) contributions t_c: Σ w t (``sum``) or (Σ w t^(β/2))^(1/β)
        (``quick``).

        ``extra`` (..., m): further contributions in the same units, weight 1 each (the hand's
        redirection: :mod:`pinchmatch.match.redirect`). ``rest`` (...) or a number: a visible fault
        of the placement in JND-equivalents x (:mod:`pinchmatch.match.rest`), added to the pooled
        cost: x under ``quick`` (the cost is in JND), x² under ``sum`` (the cost is in
        contributions)."""
        cost = self._pooled(terms, extra)
        if rest is None:
            return cost
        rest = np.asarray(rest, dtype=np.float64)
        return cost + (rest if self.pooling == "quick" else rest * rest)

    def _pooled(self, terms: np.ndarray, extra: np.ndarray | None) -> np.ndarray:
        terms = np.maximum(np.asarray(terms, dtype=np.float64), 0.0)
        w = self.weight_vector()
        if extra is not None:
            extra = np.maximum(np.asarray(extra, dtype=np.float64), 0.0)
            terms = np.concatenate([terms,
                                    np.broadcast_to(extra, terms.shape[:-1] + extra.shape[-1:])],
                                    axis=-1)
            w = np.concatenate([w, np.ones(extra.shape[-1])])
        if self.pooling == "sum":
            return terms @ w
        beta = self.exponent
        # pooled relative to the largest: no overflow
        scale = np.sqrt(terms.max(axis=-1, keepdims=True))
        safe = np.where(scale > 0, scale, 1.0)
        return scale[..., 0] * (((np.sqrt(terms) / safe) ** beta) @ w) ** (1.0 / beta)

    def bound_from_separable(self, separable, *, extra_weight: float = 0.0,
                             out: np.ndarray | None = None) -> np.ndarray:
        """A lower bound of the cost from S = Σ w t, the sum that the blockwise pass computes (with
        ``extra_weight``, the weight of further contributions the sum holds: the redirection's
        angle); into ``out`` where given (float64, S's shape: S itself, overwritten).

        ``sum``: S itself. ``quick``: with W = Σ w, the power means give Σ w x^β ≥ W (S /
        W)^(β/2) for β ≥ 2 (Jensen), so D ≥ W^(1/β - 1/2) √S; increasing in S, so the pairs
        of least S are the ones to pool."""
        separable = np.maximum(np.asarray(separable, dtype=np.float64), 0.0, out=out)
        if self.pooling == "sum":
            return separable
        total_weight = float(self.weight_vector().sum()) + extra_weight
        bound = np.sqrt(separable, out=separable)
        bound *= total_weight ** (1.0 / self.exponent - 0.5)
        return bound

    def p_noticed(self, jnd_cost) -> np.ndarray:
        """The probability that a difference of pooled cost ``jnd_cost`` (in JND, under this
        pooling) is noticed: 1 - (1 - p₁)^(D^β) for ``quick`` (p₁ =
        :data:`DETECTION_AT_ONE_JND`), and the same with β = 2 for ``sum`` (whose cost is already
        D²)."""
        d = np.asarray(jnd_cost, dtype=np.float64)
        power = d if self.pooling == "sum" else np.power(d, self.exponent)
        return -np.expm1(power * np.log1p(-DETECTION_AT_ONE_JND))

    def scales(self, table: np.ndarray) -> np.ndarray:
        """Scale of each entry of a tangible feature table (..., 9), same shape (never 0)."""
        if self.normalize == "range":
            # a feature that does not vary over the run's candidates tells no pose from another:
            # an infinite scale makes it contribute nothing (instead of amplifying round-off)
            scale = np.where(self.ranges > RANGE_TOLERANCE, self.ranges, np.inf)
            return np.broadcast_to(scale, table.shape).copy()
        t = np.nan_to_num(np.abs(table))
        s = np.empty_like(t)
        s[..., 0] = np.maximum(WIDTH_JND_FRACTION * t[..., 0], WIDTH_JND_FLOOR_MM)
        s[..., 1] = COM_JND_MM
        s[..., 2:5] = np.maximum(ANGLE_JND_FRACTION * t[..., 2:5], ANGLE_JND_FLOOR_DEG)
        s[..., 5:7] = np.maximum(CURVATURE_JND_FRACTION * t[..., 5:7], CURVATURE_JND_FLOOR_PER_M)
        # a tripod's
        fraction = (TORQUE_JND_FRACTION if table.ndim >= 2 and table.shape[-2] == 3
                    else MASS_JND_FRACTION)
        s[..., 7:9] = np.maximum(fraction * np.hypot(t[..., 7], t[..., 8]),
                                 MASS_JND_FLOOR_MM)[..., None]
        return s

    def column_weights(self, fingers: int = 2) -> np.ndarray:
        """(F, 9): each entry's weight: a criterion's contribution is the mean of its entries over
        the F patches, and ``mass`` sums its two columns (along the line and lever arm)."""
        w = np.array([self.weights[c] for c in CRITERIA])[COLUMN_CRITERION]
        return np.broadcast_to(w / fingers, (fingers, N_COLUMNS))


def feature_ranges(*tables: np.ndarray) -> np.ndarray:
    """(9,) range of each column over every pose and patch of the given tables (NaN ignored).

    The two mass columns share one range: that of the offset length |c - m|.
    """
    return ranges_from_bounds([feature_bounds(t) for t in tables])


def feature_bounds(table: np.ndarray) -> np.ndarray:
    """(2, 10) least and greatest of each column of one table, and of the offset length (NaN
    ignored).

    What :func:`ranges_from_bounds` needs, so that ranges can be gathered object by object."""
    stacked = table.reshape(-1, N_COLUMNS)
    offset = np.hypot(stacked[:, 7], stacked[:, 8])
    values = np.column_stack([stacked, offset])
    return np.stack([np.fmin.reduce(values, axis=0, initial=np.inf),
                     np.fmax.reduce(values, axis=0, initial=-np.inf)])


def ranges_from_bounds(bounds: list[np.ndarray]) -> np.ndarray:
    """(9,) :func:`feature_ranges` from the bounds of each table."""
    b = np.stack(bounds)
    span = np.fmax.reduce(b[:, 1], axis=0) - np.fmin.reduce(b[:, 0], axis=0)
    # NaN: a column never defined
    ranges = np.where(np.isfinite(span[:N_COLUMNS]), span[:N_COLUMNS], np.nan)
    ranges[7:9] = span[N_COLUMNS]
    return ranges


def distinct_entries(fingers: int) -> tuple[np.ndarray, np.ndarray]:
    """The entries of a flattened (F, 9) table row that the blockwise passes compare, and how many
    of the row's entries each stands for. Every contact's row repeats the pose columns (width, com
    distance, tilt) and the lever arm; they count once, weighed by their repeats: a pinch's 18
    entries make 14, a tripod's 27 make 17 (its two fingers' spacing once, its mass offset across
    the grasp always 0, left out). The same sums, in fewer products."""
    repeated = [0, 1, 2, 8] if fingers == 2 else [1, 2, 7, 8]
    keep, repeats = [], []
    for row in range(fingers):
        for column in range(N_COLUMNS):
            if column in repeated and row > 0:
                continue
            if fingers > 2 and column == 0 and row == 2:  # the spacing: in both fingers' rows
                continue
            if fingers > 2 and column == 8:  # a tripod's offset across its line: 0 in every row
                continue
            keep.append(row * N_COLUMNS + column)
            repeats.append(fingers if column in repeated else 2 if fingers > 2 and column == 0
                           and row == 1 else 1)
    return np.array(keep), np.array(repeats, dtype=np.float64)


def _factors(virtual: np.ndarray, spread: np.ndarray | None = None) -> list[np.ndarray]:
    """Virtual factors for both finger orders over the :func:`distinct_entries` of a row: (nv, 3 x
    E) = [(v² + σ²) m, v m, m], m = defined, σ² the ``spread`` (a variance per entry, 0 without
    one)."""
    nv = len(virtual)
    out = []
    spread = np.zeros_like(virtual) if spread is None else spread
    other = other_order(virtual.shape[1])
    keep, _ = distinct_entries(virtual.shape[1])
    for v, var in ((virtual, spread), (virtual[:, other], spread[:, other])):
        v, var = v.reshape(nv, -1)[:, keep], var.reshape(nv, -1)[:, keep]
        ok = (~np.isnan(v)).astype(np.float64)
        vv = np.nan_to_num(v)
        out.append(np.ascontiguousarray(np.concatenate([(vv * vv + np.nan_to_num(var)) * ok,
                                                        vv * ok, ok], axis=1).T))
    return out


def _tangible_factors(t: np.ndarray, model: CostModel, w: np.ndarray,
                      spread: np.ndarray | None = None) -> np.ndarray:
    """Tangible factors of a block of rows (k, F, 9) over the :func:`distinct_entries` of a row,
    their weights ``w`` (E,) (repeats included): (k, 3 x E) [a, -2 a t, a (t² + σ²)] with a =
    weight / s² (0 where ρ is undefined), so that Σ a ((v - t)² + σ_v² + σ_t²) m_v = [a, -2
    a t, a (t² + σ_t²)] · [(v² + σ_v²) m_v, v m_v, m_v] (:func:`_factors`); σ² the
    ``spread`` of each entry (0 without one)."""
    keep, _ = distinct_entries(t.shape[1])
    s = model.scales(t).reshape(len(t), -1)[:, keep]
    var = 0.0 if spread is None else np.nan_to_num(spread.reshape(len(t), -1)[:, keep])
    t = t.reshape(len(t), -1)[:, keep]
    a = np.where(np.isnan(t), 0.0, w / s**2)
    tv = np.nan_to_num(t)
    return np.concatenate([a, -2.0 * a * tv, a * (tv * tv + var)], axis=1)


def entry_weights(model: CostModel, fingers: int) -> np.ndarray:
    """(E,) the weight of each of :func:`distinct_entries`, the entries it stands for included."""
    keep, repeats = distinct_entries(fingers)
    return model.column_weights(fingers).reshape(-1)[keep] * repeats


def pair_cost_blocks(tangible: np.ndarray, virtual: np.ndarray, model: CostModel, *,
                     block_rows: int = 2048, with_swapped: bool = True,
                     spreads: tuple | None = None, extra=None):
    """Yield ``(start, cost, swapped)`` for blocks of tangible rows: the separable cost of every
    pair.

    ``extra(start, stop)``, where given, returns for those tangible rows against every virtual row a
    further contribution (weight 1) added to the sum, and which pairs are allowed; the others cost
    inf (the redirection's budget: :func:`pinchmatch.match.redirect.pair_budget`).

    With ``spreads`` (the tangible's and the virtual table's variance per entry, each shaped as its
    table) each entry's squared difference gains both variances: the expected separable cost of two
    independent draws around the rows (:mod:`pinchmatch.match.steady`).

    With ``mass`` in use, this is the lower bound of the exact cost (see the module notes);
    without it, it is the exact cost. ``swapped`` (None unless ``with_swapped``) is True where
    the virtual pose's p1 goes on the tangible's p2. The blocks are views of buffers reused
    from one block to the next: use or copy each before taking the next.
    """
    nv = len(virtual)
    w = entry_weights(model, virtual.shape[1])
    t_spread, v_spread = spreads if spreads is not None else (None, None)
    v_orders = _factors(virtual, v_spread)
    rows = max(1, min(block_rows, len(tangible)))
    buffers = np.empty((2, rows, nv))  # allocated once: no page faults per block
    for start in range(0, len(tangible), rows):
        t = tangible[start:start + rows]
        left = _tangible_factors(t, model, w,
                                 None if t_spread is None else t_spread[start:start + rows])
        c0, c1 = buffers[0, :len(t)], buffers[1, :len(t)]
        np.matmul(left, v_orders[0], out=c0)
        np.matmul(left, v_orders[1], out=c1)
        swapped = np.less(c1, c0) if with_swapped else None
        np.minimum(c0, c1, out=c0)
        np.maximum(c0, 0.0, out=c0)  # round-off
        if extra is not None:
            term, ok = extra(start, start + len(t))
            c0 += term
            c0[~ok] = np.inf
        yield start, c0, swapped


def pooled_bound_blocks(tangible: np.ndarray, virtual: np.ndarray, model: CostModel, *,
                        block_rows: int = 512, extra=None):
    """Yield ``(start, bound)`` for blocks of tangible rows: per pair, the model's pooling of its
    separable contributions (``mass`` at its lower bound), in the better finger order.

    A lower bound of the exact cost, as :meth:`CostModel.bound_from_separable` is, but from each
    criterion's own contribution instead of their sum: under ``quick`` pooling that sum cannot
    tell one large difference from several small ones, and its bound falls up to a third below the
    cost where one criterion dominates (a ball against a box: every pose alike, the width apart).
    A matrix product per criterion and order, and a power per pair and criterion: several times
    the price of :func:`pair_cost_blocks`, for when its bound leaves too many pairs to evaluate.
    ``extra``: as :func:`pair_cost_blocks`' (pooled with weight 1).
    """
    nv, fingers = len(virtual), virtual.shape[1]
    w = entry_weights(model, fingers)
    keep, _ = distinct_entries(fingers)
    # each distinct entry of a row of F patches
    criterion = np.tile(COLUMN_CRITERION, fingers)[keep]
    weights = model.weight_vector()
    used = [c for c in range(len(CRITERIA)) if weights[c] > 0]
    width = len(keep)
    columns = {c: np.concatenate([e, e + width, e + 2 * width])
               for c in used for e in [np.flatnonzero(criterion == c)]}
    v_orders = _factors(virtual)
    half = model.exponent / 2.0
    rows = max(1, min(block_rows, len(tangible)))
    for start in range(0, len(tangible), rows):
        t = tangible[start:start + rows]
        left = _tangible_factors(t, model, w)
        best = None
        for order in v_orders:
            pooled = np.zeros((len(t), nv))
            for c in used:
                part = left[:, columns[c]] @ order[columns[c]]  # weight x contribution
                np.maximum(part, 0.0, out=part)  # round-off
                part /= weights[c]
                with np.errstate(divide="ignore"):
                    # x^half as exp(half·log x), faster than a power: 0 stays 0
                    np.log(part, out=part)
                part *= half
                np.exp(part, out=part)
                part *= weights[c]
                pooled += part
            best = pooled if best is None else np.minimum(best, pooled)
        if extra is not None:  # as pair_cost_blocks' extra
            term, ok = extra(start, start + len(t))
            best = best + (term if model.pooling == "sum" else term ** half)
            best[~ok] = np.inf
        yield start, best if model.pooling == "sum" else best ** (1.0 / model.exponent)


def pair_costs(tangible: np.ndarray, virtual: np.ndarray, model: CostModel, *,
               block_rows: int = 2048):
    """Separable cost of every (tangible pose, virtual pose) pair, with the better finger order.

    Parameters
    ----------
    tangible : (nt, 2, 9) feature table;  virtual : (nv, 2, 9) feature table.

    Returns
    -------
    cost : (nt, nv) float64   exact without ``mass``; its lower bound with it
    swapped : (nt, nv) bool   True where the virtual pose's p1 goes on the tangible's p2.

    An undefined ρ on either side contributes nothing.
    """
    cost = np.empty((len(tangible), len(virtual)))
    swapped = np.empty(cost.shape, dtype=bool)
    for start, c, sw in pair_cost_blocks(tangible, virtual, model, block_rows=block_rows):
        cost[start:start + len(c)] = c
        swapped[start:start + len(c)] = sw
    return cost, swapped


#: (9, 8) each column's criterion, as a matrix: a row of per-column values times it sums them per
#: criterion
_COLUMNS_TO_CRITERIA = np.eye(len(CRITERIA))[COLUMN_CRITERION]


def separable_terms(tangible_rows: np.ndarray, virtual_rows: np.ndarray, model: CostModel, *,
                    scales: np.ndarray | None = None) -> np.ndarray:
    """(k, 8) each criterion's contribution for k aligned pairs (virtual rows already in finger
    order); the ``mass`` entry is its lower bound. ``scales``: the tangible rows'
    :meth:`CostModel.scales`, where the caller has them."""
    s = model.scales(tangible_rows) if scales is None else scales
    z = ((virtual_rows - tangible_rows) / s) ** 2
    z = np.where(np.isnan(z), 0.0, z)  # undefined ρ contributes nothing
    per_column = z.mean(axis=1)  # mean over the two patches
    return per_column @ _COLUMNS_TO_CRITERIA  # each sum of one or two terms: exact in any order


def mass_term(tangible_rows: np.ndarray, delta_mm: np.ndarray, model: CostModel, *,
              scales: np.ndarray | None = None) -> np.ndarray:
    """(k,) exact ``mass`` contribution |Δ|²/s² for the offset mismatch Δ (k, 3) after
    registration (``scales`` as :func:`separable_terms` takes them)."""
    s = (model.scales(tangible_rows) if scales is None else scales)[:, 0, 7]
    return np.einsum("kd,kd->k", delta_mm, delta_mm) / s**2


def contributions(tangible_row: np.ndarray, virtual_row: np.ndarray, model: CostModel, *,
                  swapped: bool, mass_delta_mm: np.ndarray | None = None) -> dict:
    """Each criterion's contribution for one pair: mean over its entries of (difference / scale)².

    tangible_row, virtual_row : (2, 9). ``mass_delta_mm`` (3,), the offset mismatch after
    registration, gives the exact ``mass`` contribution; without it, its lower bound. The cost
    is Σ weight x contribution.
    """
    v = virtual_row[other_order(len(virtual_row))] if swapped else virtual_row
    terms = separable_terms(tangible_row[None], v[None], model)[0]
    if mass_delta_mm is not None:
        terms[7] = mass_term(tangible_row[None], np.asarray(mass_delta_mm, float)[None], model)[0]
    return dict(zip(CRITERIA, terms.tolist()))


def total(terms: np.ndarray, model: CostModel, extra: np.ndarray | None = None,
          rest=None) -> np.ndarray:
    """The model's cost of (..., 8) contributions, any ``extra`` ones and a ``rest`` fault
    (:meth:`CostModel.pool`)."""
    return model.pool(terms, extra=extra, rest=rest)
