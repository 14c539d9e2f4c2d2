"""One object's candidate poses: its feasible pinches, their features and feature table.

The search (:mod:`pinchmatch.match.search`) pairs a virtual object's candidates with each
tangible's; the cache stores them (:mod:`pinchmatch.runner.cache`).
"""

from __future__ import annotations

import dataclasses
import weakref
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, NoFeasiblePinchError
from ..grasp.analysis import ObjectAnalysis, find_pinches, score_pinches, score_tripods
from ..grasp.features import PinchFeatures, grasp_features
from ..grasp.pinches import Pinches, PinchSettings, concat_pinches
from .cost import MASS_COLUMNS, feature_table, mass_term, separable_terms


@dataclass(frozen=True)
class Candidates:
    """One object's candidate poses: its feasible pinches, their features and feature table.

    ``index`` maps each candidate to its place in the sampled or given list.
    """

    obj: ObjectAnalysis
    pinches: Pinches
    features: PinchFeatures
    table: np.ndarray
    index: np.ndarray
    given: bool

    @property
    def name(self) -> str:
        return self.obj.name

    def __len__(self) -> int:
        return len(self.pinches)

    def subset(self, keep) -> "Candidates":
        """The candidates at positions ``keep`` (their ``index`` kept)."""
        keep = np.asarray(keep)
        return Candidates(self.obj, self.pinches.subset(keep), features_subset(self.features, keep),
                          self.table[keep], self.index[keep], self.given)


def features_subset(features: PinchFeatures, keep: np.ndarray) -> PinchFeatures:
    """The features of the pinches at positions ``keep``."""
    return type(features)(**{f.name: getattr(features, f.name)[keep]
                             for f in dataclasses.fields(features)})


def candidate_poses(
    obj: ObjectAnalysis,
    *,
    settings: PinchSettings = PinchSettings(),
    given: tuple[np.ndarray, np.ndarray] | None = None,
    source: str | None = None,
) -> Candidates:
    """The feasible poses of ``obj``: sampled, or the ``given`` (p1_mm, p2_mm) checked.

    Parameters
    ----------
    obj : ObjectAnalysis
        The object (:func:`analyze_object`).
    settings : PinchSettings
        The sampling and the rules a pose must pass.
    given : (p1_mm, p2_mm), optional
        Poses to check instead of sampling: two (n, 3) arrays of contacts (mm).
    source : str, optional
        What messages call the given poses (their file).

    Returns
    -------
    Candidates
        The feasible poses, their features and the object they are on.

    Raises
    ------
    NoFeasiblePinchError
        No sampled pose is feasible, or none of the given ones is.
    ContactError
        A given contact is off the surface.

    Examples
    --------
    >>> from pinchmatch import PinchSettings, analyze_object
    >>> box = candidate_poses(analyze_object(box_stl), settings=PinchSettings(count=100, seed=0))
    >>> len(box.pinches), box.table.shape  # a row of 9 features per finger
    (100, (100, 2, 9))
    """
    if given is None:
        pinches, features = find_pinches(obj, settings=settings)
    elif settings.grasp == "tripod":  # given as a tuple of one (n, 3, 3) array
        pinches, features = score_tripods(obj, *given, settings=settings, source=source)
    else:
        pinches, features = score_pinches(obj, *given, settings=settings, source=source)
    keep = np.flatnonzero(pinches.feasible)
    if not len(keep):
        reasons = "; ".join(f"pose {i} breaks {', '.join(pinches.broken_rules(i))}"
                            for i in range(min(3, len(pinches))))
        raise NoFeasiblePinchError(
            f"{source or obj.loaded.path}: none of the {len(pinches)} given poses is feasible on "
            f"{obj.name} "
            f"({reasons}); give poses that a fingertip can hold, or loosen --friction-cone-deg"
        )
    pinches, features = pinches.subset(keep), features_subset(features, keep)
    return Candidates(obj, pinches, features, feature_table(features), keep, given is not None)


#: poses found after the sampling (refined, targeted) have no place in the sampled list: their
#: ``index``
REFINED_INDEX = -1


def extend(base: Candidates, pinches: Pinches) -> Candidates:
    """``base`` with feasible ``pinches`` added (features computed, index ``REFINED_INDEX``): how
    refinement and the targeted step grow an object's candidates."""
    features = grasp_features(pinches, base.obj.props)
    extra = Candidates(base.obj, pinches, features, feature_table(features),
                       np.full(len(pinches), REFINED_INDEX, dtype=base.index.dtype), base.given)
    return Candidates(base.obj, concat_pinches([base.pinches, pinches], base.pinches.rejected),
                      concat_features([base.features, extra.features]),
                      np.concatenate([base.table, extra.table]),
                      np.concatenate([base.index, extra.index]), base.given)


def concat_features(parts: list[PinchFeatures]) -> PinchFeatures:
    """The features of ``parts``' pinches, in order."""
    return type(parts[0])(**{f.name: np.concatenate([getattr(p, f.name) for p in parts])
                             for f in dataclasses.fields(parts[0])})


def merge_candidates(first: Candidates, second: Candidates) -> Candidates:
    """The candidates of both (same object); the second's indices follow the first's list."""
    features = concat_features([first.features, second.features])
    offset = int(first.index.max()) + 1 if len(first.index) else 0
    return Candidates(first.obj, concat_pinches([first.pinches, second.pinches]), features,
                      np.concatenate([first.table, second.table]),
                      np.concatenate([first.index, second.index + offset]),
                      first.given and second.given)


def with_count(base: int, count: int, most: int) -> int:
    """``base`` at a sampling count up to the default (:class:`PinchSettings`' ``count``), in
    proportion above it (rounded up), at most ``most``: how many of a search's best pairs a step
    takes, so that a denser sample, which holds more pairs near each good one, looks as far into its
    order as a smaller one did."""
    default = PinchSettings().count
    return int(min(max(base, -(-base * int(count) // default)), max(most, base)))


def memo_of(store: dict, owner) -> dict:
    """The memo that ``store`` keeps for ``owner`` (by identity) while ``owner`` lives: a process
    makes what depends on one object alone (its landings, its feature pool) once however many
    matches ask."""
    entry = store.get(id(owner))
    if entry is None or entry[0]() is not owner:
        entry = (weakref.ref(owner), {})
        store[id(owner)] = entry
        weakref.finalize(owner, store.pop, id(owner), None)
    return entry[1]


def pose_key(pinches, pose: int) -> bytes:
    """What a pose's geometry on its object (its landing table, its spread at a scan's noise)
    depends on besides the object: its contacts and their triangles."""
    return pinches.points[pose].tobytes() + pinches.face_index[pose].tobytes()


def mass_ratio(tangible: Candidates, virtual: Candidates) -> float:
    """m_V / m_T, the virtual object's mass over the tangible's, where both are known; else 1.

    The weight of an object held in a pinch pulls with a torque m·g × o about the pinch, o being
    the centre of mass's offset from the pinch midpoint. Felt and seen torques agree when
    m_T·o_T = m_V·R·o_V, so the ``mass`` criterion compares o_T with (m_V / m_T)·R·o_V: the
    offset at which the tangible's own mass would pull as the virtual object is seen to. Where a
    mass is missing on either side, nothing is known about the ratio and the masses are taken as
    equal: the criterion then compares where the mass sits, as it does with no masses at all.
    """
    m_t, m_v = tangible.obj.mass_g, virtual.obj.mass_g
    return float(m_v / m_t) if m_t and m_v else 1.0


def felt_table(table: np.ndarray, ratio: float) -> np.ndarray:
    """A virtual feature table with its ``mass`` columns scaled by :func:`mass_ratio` (a copy,
    or the table itself where the ratio is 1)."""
    if ratio == 1.0:
        return table
    out = table.copy()
    out[..., MASS_COLUMNS] *= ratio
    return out


def pair_terms(tangible: Candidates, virtual: Candidates, t_rows: np.ndarray, v_rows: np.ndarray,
               model, *, R: np.ndarray | None = None, t_points: np.ndarray | None = None,
               v_points: np.ndarray | None = None,
               delta: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """How k pose pairs score: (k, 8) each criterion's contribution, and (k, 3) the mass offset.

    The one scoring of a pose pair, used by the search, the landings, the reference and the
    reports. ``t_rows``/``v_rows`` are the pairs' feature-table rows (the virtual ones as seen, in
    the tangible's finger order). The mass offset ``delta`` is the centre of mass's offset from the
    pinch midpoint as seen (turned into the tangible's frame, scaled by :func:`mass_ratio`) minus as
    felt, mm in the tangible's frame; unless given, it is computed from ``t_points``/``v_points``
    (k, 2, 3), the contacts in each object's frame, and ``R`` (k, 3, 3) or (3, 3), which turns the
    virtual object's frame into the tangible's."""
    ratio = mass_ratio(tangible, virtual)
    if delta is None:
        seen = virtual.obj.props.com_mm - v_points.mean(axis=-2)
        seen = np.einsum("kij,kj->ki", R, seen) if R.ndim == 3 else seen @ R.T
        delta = ratio * seen - (tangible.obj.props.com_mm - t_points.mean(axis=-2))
    scales = model.scales(t_rows)
    terms = separable_terms(t_rows, felt_table(v_rows, ratio), model, scales=scales)
    terms[:, 7] = mass_term(t_rows, delta, model, scales=scales)
    return terms, delta


def one_grasp(candidates: list) -> None:
    """Refuse, in one line, candidates of two grasps (pinches and tripods) in one match: their
    features and contacts cannot be compared. Each object's candidates are made with one
    ``PinchSettings.grasp``."""
    kinds = {}
    for c in candidates:
        kinds.setdefault("tripod" if c.pinches.points.shape[1] == 3 else "pinch", c.name)
    if len(kinds) > 1:
        raise ConfigError(f"{kinds['tripod']}'s candidates are tripods and {kinds['pinch']}'s are "
                          "pinches; a match "
                          "compares one grasp: make every object's candidates with the same "
                          "PinchSettings(grasp=...)")
