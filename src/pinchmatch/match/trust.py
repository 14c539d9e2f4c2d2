"""What a scanned prop's features are worth: their spread at the scan's error, and in the cost.

A prop imported from a scan says how far its surface may still be off: the error the import's
smoothing left (the manifest's ``scan.residual_mm``; :func:`pinchmatch.scan.surface.residual`).
Its feature table is one draw of that error: each pose's features have a variance σ² around the
object's true ones (:func:`pinchmatch.grasp.scan_noise.noisy_features`).
:func:`uncertainty_jnd` reports it per pose as one number, in JND: the run's pooling in JND of one
standard deviation of every feature (``scan_uncertainty_jnd`` in ``matches.json``).

With ``--scan-trust`` (:class:`~pinchmatch.match.cost.CostModel`'s ``scan_trust``) the cost weighs
it. Under an error ε of variance σ² on the prop's side a criterion's expected squared difference
is E[(v - t - ε)²] = (v - t)² + σ², so the felt cost and the steady search add, per criterion,
the mean over its entries of σ² / s², as the landing spread adds its variance
(:mod:`pinchmatch.match.steady`); the nominal cost, the difference on target as the scan has it,
never does. s is the JND of the least value the feature may have, ``LEAST_SIGMAS`` σ nearer 0: a
JND relative to a value the noise inflated (a straight wall's curvature read as 8 /m) would call
that noise small, and the match would seek out exactly the pinches the scan got wrong.

It is off by default. On synthetic scans of three YCB props matched against eight YCB objects
(``benchmarks/bench_import.py --match``), the two pinches it changed felt worse on the real
objects; at 4,000 poses three changed, two for the better and one for the worse, a wash. The
spread, a variance, does not see where the import's smoothing changed the shape (a mug's rim),
which is where a scan is most wrong (docs/scans.md). An object not from a scan has a spread of 0
either way.
"""

from __future__ import annotations

import numpy as np

from ..grasp.scan_noise import NOISE_FLOOR_MM, noisy_features
from .candidates import Candidates, felt_table, memo_of, pose_key
from .cost import CostModel, feature_table, separable_terms

_SPREADS: dict[int, dict] = {}
#: a spread is measured in the JND of the least value its feature may have: this many standard
#: deviations nearer 0 than the scan has it
LEAST_SIGMAS = 2.0


def surface_error_mm(candidates: Candidates) -> float:
    """How far ``candidates``' object's surface may be off (mm RMS along the normal): the error its
    scan's smoothing left (``scan.residual_mm``), or where a manifest gives only the scan's noise,
    that noise (nothing known to have smoothed it); 0 for an object not from a scan."""
    spec = candidates.obj.spec
    if spec is None:
        return 0.0
    error = spec.scan_residual_mm if spec.scan_residual_mm is not None else spec.scan_noise_mm
    error = 0.0 if error is None else float(error)
    return error if error >= NOISE_FLOOR_MM else 0.0


def scan_variance(candidates: Candidates, poses=None) -> np.ndarray:
    """(k, F, 9) the variance of each pose's feature-table entries at its object's scan error (0
    everywhere for an object not from a scan; 0 where an entry is undefined in some draw). Made
    once per pose while the object lives, the missing ones in one batch."""
    poses = np.arange(len(candidates)) if poses is None else np.asarray(poses, dtype=np.int64)
    table = candidates.table
    noise = surface_error_mm(candidates)
    if noise == 0.0:
        return np.zeros((len(poses),) + table.shape[1:])
    store = memo_of(_SPREADS, candidates.obj).setdefault(
        (noise, type(candidates.pinches).__name__), {})
    keys = [pose_key(candidates.pinches, int(p)) for p in poses]
    missing = sorted({int(p) for p, key in zip(poses, keys) if key not in store})
    if missing:
        part = candidates.pinches.subset(np.array(missing))
        obj = candidates.obj
        var = draws_variance(np.stack([feature_table(f) for f in noisy_features(
            obj.context, part, obj.props, noise)]))
        for k, pose in enumerate(missing):
            store[pose_key(candidates.pinches, pose)] = var[k]
    return np.stack([store[key] for key in keys]) if keys else np.zeros((0,) + table.shape[1:])


def draws_variance(drawn: np.ndarray) -> np.ndarray:
    """The variance over the draws (axis 0) of each entry, over the draws where it is defined (not
    NaN); 0 for an entry undefined in every draw."""
    defined = ~np.isnan(drawn)
    count = np.maximum(defined.sum(axis=0), 1)
    mean = np.where(defined, drawn, 0.0).sum(axis=0) / count
    return np.where(defined, (np.nan_to_num(drawn) - mean) ** 2, 0.0).sum(axis=0) / count


def spread_terms(t_rows: np.ndarray, t_var: np.ndarray, v_var: np.ndarray, ratio: float,
                 model: CostModel) -> np.ndarray:
    """(k, 8) each criterion's contribution of the variances ``t_var`` (the tangible's) and
    ``v_var`` (the virtual's, in the tangible's finger order, its mass columns scaled by the mass
    ``ratio`` as :func:`~pinchmatch.match.candidates.felt_table` scales the values), in the
    tangible rows' scales: the mean over a criterion's entries of (σ_t² + σ_v²) / s²."""
    spread = np.sqrt(t_var + felt_table(felt_table(v_var, ratio), ratio))
    return separable_terms(t_rows, t_rows + spread, model)


def least(rows: np.ndarray, var: np.ndarray) -> np.ndarray:
    """``rows`` moved ``LEAST_SIGMAS`` standard deviations towards 0 (not past it): the scale a
    spread is measured in. A JND relative to a value the noise inflated (a straight wall's
    curvature read as 8 /m) would call its own noise small."""
    return np.sign(rows) * np.maximum(np.abs(rows) - LEAST_SIGMAS * np.sqrt(var), 0.0)


def scan_terms(tangible: Candidates, poses, model: CostModel) -> np.ndarray:
    """(k, 8) the contribution of the scan's spread of each of the tangible's ``poses``, in the JND
    of their :func:`least` values."""
    poses = np.asarray(poses, dtype=np.int64)
    var = scan_variance(tangible, poses)
    return spread_terms(least(tangible.table[poses], var), var, np.zeros_like(var), 1.0, model)


def uncertainty_jnd(tangible: Candidates, poses, model: CostModel) -> np.ndarray:
    """(k,) how uncertain each pose's features are at its object's scan error, in JND: the run's
    pooling, in JND with each of its criteria weighed 1, of one standard deviation of each feature
    (0 for an object not from a scan).
    """
    jnd = CostModel(dict.fromkeys(model.criteria, 1.0), "jnd", None, model.criteria,
                    model.pooling)
    return np.asarray(jnd.pool(scan_terms(tangible, poses, jnd)), dtype=np.float64)
