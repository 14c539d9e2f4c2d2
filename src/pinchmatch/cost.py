"""How different two pinches feel: the method's 14-number comparison (Step #3).

A pose is described by 14 numbers, the 7 features of each patch, the pose
features (width, com distance, tilt) appearing in both. Each difference is
divided by a scale; a criterion's *contribution* is the mean over its
entries of (difference / scale)², and the cost is the weighted sum of the
contributions.

Scales (``normalize``):

- ``"jnd"``: just-noticeable differences from ``shared/paper/perception.md``,
  relative to the tangible's value, with absolute floors near zero. A
  contribution of 1 means "just noticeable".
- ``"range"``: the paper's own choice, each feature's range over all
  candidate poses of the run.

Since every scale depends on the tangible side only, each term
(v/s - t/s)² splits into products of a tangible factor and a virtual
factor, so a whole block of pose pairs is three matrix products (BLAS):
exact, and fast enough for 10,000 x 10,000 pairs.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field

import numpy as np

from .errors import ConfigError
from .features import PinchFeatures

CRITERIA = ("width", "com", "tilt", "normal", "axis", "kmax", "kmin")

#: width: 5.75 % of the reference width (de Tinguy et al., WHC 2019), floor: 0.4 mm (Ho & Srinivasan)
WIDTH_JND_FRACTION, WIDTH_JND_FLOOR_MM = 0.0575, 0.4
#: orientations: 43.8 % of the reference angle, floor: 20° (edge orientation on the fingerpad, Bensmaia)
ANGLE_JND_FRACTION, ANGLE_JND_FLOOR_DEG = 0.438, 20.0
#: curvature: 66.66 % of the reference, floor: 2 /m (2 cm stimuli, Gordon & Morison)
CURVATURE_JND_FRACTION, CURVATURE_JND_FLOOR_PER_M = 0.6666, 2.0
#: distance from the centre of mass: no published threshold; proprioceptive accuracy, about 20 mm
COM_JND_MM = 20.0

#: column layout of a feature table: per patch k in (0, 1), these 7 columns
_COLUMNS = ("width", "com", "tilt", "normal", "axis", "kmax", "kmin")


def feature_table(features: PinchFeatures) -> np.ndarray:
    """(n, 2, 7) float64: per pose and patch, the 7 features in CRITERIA order (NaN = undefined ρ)."""
    n = len(features.width_mm)
    pose = np.stack([features.width_mm, features.com_distance_mm, features.tilt_deg], axis=-1)  # (n, 3)
    patch = np.stack([features.normal_angle_deg, features.curvature_axis_angle_deg,
                      features.kappa_max_per_m, features.kappa_min_per_m], axis=-1)  # (n, 2, 4)
    return np.concatenate([np.broadcast_to(pose[:, None, :], (n, 2, 3)), patch], axis=-1)


def parse_weights(text: str | None) -> dict[str, float]:
    """Parse ``"width=1,com=0.5"`` into weights for every criterion (default 1)."""
    weights = dict.fromkeys(CRITERIA, 1.0)
    if not text:
        return weights
    for item in str(text).split(","):
        name, sep, value = item.partition("=")
        name = name.strip()
        if name not in weights:
            close = difflib.get_close_matches(name, CRITERIA, n=1)
            hint = f"did you mean {close[0]!r}? " if close else ""
            raise ConfigError(f"--weights: unknown criterion {name!r}; {hint}valid: {', '.join(CRITERIA)}")
        try:
            w = float(value)
        except ValueError:
            w = float("nan")
        if not sep or not np.isfinite(w) or w < 0:
            raise ConfigError(f"--weights: {item.strip()!r} needs a weight of 0 or more, as {name}=1")
        weights[name] = w
    return weights


@dataclass(frozen=True)
class CostModel:
    """How pose differences are scaled and weighted.

    weights : dict criterion -> float >= 0
    normalize : ``"jnd"`` or ``"range"``
    ranges : (7,) float64, per criterion, for ``"range"`` (see :func:`feature_ranges`)
    """

    weights: dict = field(default_factory=lambda: dict.fromkeys(CRITERIA, 1.0))
    normalize: str = "jnd"
    ranges: np.ndarray | None = None

    def __post_init__(self):
        if self.normalize not in ("jnd", "range"):
            raise ConfigError(f"--normalize: unknown mode {self.normalize!r}; use jnd or range")
        if self.normalize == "range" and self.ranges is None:
            raise ConfigError("range normalisation needs the feature ranges of the run")

    def scales(self, table: np.ndarray) -> np.ndarray:
        """Scale of each entry of a tangible feature table, same shape (never 0)."""
        if self.normalize == "range":
            return np.broadcast_to(np.maximum(self.ranges, 1e-12), table.shape).copy()
        t = np.nan_to_num(np.abs(table))
        s = np.empty_like(t)
        s[..., 0] = np.maximum(WIDTH_JND_FRACTION * t[..., 0], WIDTH_JND_FLOOR_MM)
        s[..., 1] = COM_JND_MM
        s[..., 2:5] = np.maximum(ANGLE_JND_FRACTION * t[..., 2:5], ANGLE_JND_FLOOR_DEG)
        s[..., 5:7] = np.maximum(CURVATURE_JND_FRACTION * t[..., 5:7], CURVATURE_JND_FLOOR_PER_M)
        return s

    def column_weights(self) -> np.ndarray:
        """(2, 7): each entry's weight, so that a criterion's contribution is the mean of its entries."""
        w = np.array([self.weights[c] for c in _COLUMNS])
        return np.broadcast_to(w / 2.0, (2, 7))


def feature_ranges(*tables: np.ndarray) -> np.ndarray:
    """(7,) range of each criterion over every pose and patch of the given tables (NaN ignored)."""
    stacked = np.concatenate([t.reshape(-1, 7) for t in tables])
    return np.nanmax(stacked, axis=0) - np.nanmin(stacked, axis=0)


def pair_costs(tangible: np.ndarray, virtual: np.ndarray, model: CostModel, *, block_rows: int = 2048):
    """Exact cost of every (tangible pose, virtual pose) pair, with the better finger order.

    Parameters
    ----------
    tangible : (nt, 2, 7) feature table;  virtual : (nv, 2, 7) feature table.

    Returns
    -------
    cost : (nt, nv) float64
    swapped : (nt, nv) bool   True where the virtual pose's p1 goes on the tangible's p2.

    An undefined ρ on either side contributes nothing. Memory is bounded by
    working in blocks of ``block_rows`` tangible poses.
    """
    nt, nv = len(tangible), len(virtual)
    w = model.column_weights().reshape(14)
    cost = np.empty((nt, nv))
    swapped = np.empty((nt, nv), dtype=bool)
    # virtual factors for both finger orders: values, squares, and the defined-mask
    v_orders = [virtual.reshape(nv, 14), virtual[:, ::-1].reshape(nv, 14)]
    for start in range(0, nt, block_rows):
        t = tangible[start:start + block_rows]
        s = model.scales(t).reshape(len(t), 14)
        t = t.reshape(len(t), 14)
        t_ok = ~np.isnan(t)
        a = np.where(t_ok, w / s**2, 0.0)  # weight / s²
        tv = np.nan_to_num(t)
        best = None
        for order, v in enumerate(v_orders):
            v_ok = (~np.isnan(v)).astype(float)
            vv = np.nan_to_num(v)
            # Σ a (v - t)² m_v = Σ a m_v v² - 2 Σ a t m_v v + Σ a t² m_v
            c = a @ (vv * vv * v_ok).T - 2.0 * (a * tv) @ (vv * v_ok).T + (a * tv * tv) @ v_ok.T
            np.maximum(c, 0.0, out=c)  # round-off
            if best is None:
                best, flip = c, np.zeros(c.shape, dtype=bool)
            else:
                flip = c < best
                best = np.where(flip, c, best)
        cost[start:start + len(t)] = best
        swapped[start:start + len(t)] = flip
    return cost, swapped


def contributions(tangible_row: np.ndarray, virtual_row: np.ndarray, model: CostModel, *, swapped: bool) -> dict:
    """Each criterion's contribution for one pair: mean over its entries of (difference / scale)².

    tangible_row, virtual_row : (2, 7). Returns {criterion: float}; the cost is
    Σ weight x contribution.
    """
    v = virtual_row[::-1] if swapped else virtual_row
    s = model.scales(tangible_row[None])[0]
    z = ((v - tangible_row) / s) ** 2
    z = np.where(np.isnan(z), 0.0, z)
    return {c: float(z[:, i].mean()) for i, c in enumerate(_COLUMNS)}
