"""The paper's Ref: the virtual object superimposed on the tangible as the files place them.

Where the tangible pose's pinch line meets the virtual surface gives the reference pose; its cost
under the run's model is what a matched pose is compared with (the paper's Table 2).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from ..grasp.analysis import ObjectAnalysis
from ..grasp.features import PinchFeatures, pinch_features
from ..grasp.pinches import Pinches, PinchSettings, check_pinches
from .candidates import Candidates, pair_terms
from .cost import CostModel, feature_table, total
from .register import FLIP_COSINE

#: surfaces a reference line is followed through, from each side
MAX_LINE_HITS = 16


def line_contacts(obj: ObjectAnalysis, point: np.ndarray,
                  direction: np.ndarray) -> np.ndarray | None:
    """(2, 3) where two fingers closing along a line meet the surface of ``obj``, or None.

    The line passes through ``point`` along ``direction``; the first finger comes from the
    -direction side, the second from the +direction side. None when the line misses.
    """
    hits = _line_hits(obj, point, direction)
    return None if hits is None else hits[0]


def _line_hits(obj: ObjectAnalysis, point: np.ndarray, direction: np.ndarray,
               near: np.ndarray | None = None):
    """:func:`line_contacts` and the (2,) triangles hit, or None.

    Without ``near``, each finger comes from far outside and stops at the first surface. With
    ``near`` ((2, 3): where each finger is, on the line), each stops at the surface facing it that
    is nearest to where it is: a finger inside a cup stays inside and meets the inner wall."""
    u = np.asarray(direction, dtype=np.float64)
    u = u / np.linalg.norm(u)
    bounds = obj.props.bounds_mm
    reach = (np.linalg.norm(bounds[1] - bounds[0]) + np.linalg.norm(point - bounds.mean(axis=0))
             + 1.0)
    if near is None:
        origins = np.array([point - reach * u, point + reach * u])
        face, dist = obj.context.first_hit(origins, np.array([u, -u]))
        if (face < 0).any():
            return None
        points = origins + dist[:, None] * np.array([u, -u])
    else:
        # the surfaces facing the first finger (normal against u) are where a ray along -u leaves
        # the solid, and those facing the second where a ray along +u does
        origins = np.array([point + reach * u, point - reach * u])
        ray, face_all, dist_all = obj.context.exits(origins, np.array([-u, u]),
                                                    max_distance=2.0 * reach,
                                                    max_hits=MAX_LINE_HITS)
        points, face = np.zeros((2, 3)), np.zeros(2, dtype=np.int64)
        for k, sign in ((0, -1.0), (1, 1.0)):
            mine = ray == k
            if not mine.any():
                return None
            hits = origins[k] + sign * dist_all[mine, None] * u
            pick = int(np.argmin(np.linalg.norm(hits - near[k], axis=1)))
            points[k], face[k] = hits[pick], face_all[mine][pick]
    if (points[1] - points[0]) @ u <= 1e-9:
        return None
    return points, face


def probe_key(point: np.ndarray, direction: np.ndarray, near: np.ndarray | None = None) -> str:
    """The name of a line (a point and a direction, exactly, and where its fingers are) in the
    memo of :func:`line_pinch`."""
    parts = [point, direction] + ([] if near is None else [near])
    data = np.concatenate([np.asarray(x, np.float64).ravel() for x in parts])
    return hashlib.sha256(data.tobytes()).hexdigest()[:32]


def line_pinch(virtual: Candidates, point: np.ndarray, direction: np.ndarray, *,
               settings: PinchSettings = PinchSettings(), near: np.ndarray | None = None,
               memo: dict | None = None) -> Pinches | None:
    """The one pinch (every rule checked) of two fingers closing on ``virtual`` along a line, as
    :func:`line_contacts` finds its contacts, or None when the line misses.

    ``memo`` (of this virtual object, by :func:`probe_key`, None where the line misses) keeps it:
    asked again, and in a warm run read back from the cache (:mod:`pinchmatch.runner.cache`), it
    needs neither the surface's sample nor its rays. The settings must be those the candidates
    were made with (the cache's key holds them)."""
    memo = {} if memo is None else memo
    key = probe_key(point, direction, near)
    if key not in memo:
        hits = _line_hits(virtual.obj, point, direction, near)
        memo[key] = None if hits is None else check_pinches(
            virtual.obj.context, hits[0][:1], hits[0][1:], settings=settings, faces=hits[1][None])
    return memo[key]


@dataclass(frozen=True)
class Reference:
    """The paper's Ref: the virtual object superimposed on the tangible as the files place them."""

    pinches: Pinches | None
    features: PinchFeatures | None
    terms: np.ndarray | None
    cost: float | None
    reason: str | None
    flipped: bool | None = None


def reference_pose(tangible: Candidates, t_pose: int, virtual: Candidates, model: CostModel, *,
                   settings: PinchSettings = PinchSettings(),
                   memo: dict | None = None) -> Reference:
    """Where the tangible pose's pinch line meets the virtual surface, and its cost.

    Each finger closes along the tangible's pinch line from its own side, from where it holds the
    tangible; its contact is the virtual surface facing it nearest to that place (a finger inside a
    cup meets the cup's inner wall, not the outer wall across the cup). The placement is the
    identity (both files' frames), the finger order p1 on p1. The cost is ``None`` with a reason
    when a finger meets nothing. Use :func:`reference_cost` for the same pose under another model;
    ``memo``: as for :func:`line_pinch`.
    """
    p = tangible.pinches.points[t_pose]
    if len(p) != 2:
        return Reference(None, None, None, None,
                         "the paper's reference places a pinch: a tripod has none")
    pinches = line_pinch(virtual, p.mean(axis=0), p[1] - p[0], settings=settings, near=p, memo=memo)
    if pinches is None:
        node = getattr(virtual.obj.spec, "node", None) if virtual.obj.spec is not None else None
        return Reference(None, None, None, None,
                         "the tangible's pinch line misses the virtual object" + (
            " (a level's node lies where the level puts it, not at its file's origin, where the "
            "paper's reference sets it on the prop)" if node is not None else ""))
    features = pinch_features(pinches, virtual.obj.props)
    flipped = bool(virtual.obj.loaded.up @ tangible.obj.loaded.up < FLIP_COSINE)
    terms = _reference_terms(tangible, t_pose, virtual, pinches, features, model)
    return Reference(pinches, features, terms, float(total(terms[None], model)[0]), None, flipped)


def reference_cost(tangible: Candidates, t_pose: int, virtual: Candidates, ref: Reference,
                   model: CostModel) -> float | None:
    """The cost of a reference pose under ``model`` (None where the fingers meet nothing)."""
    if ref.pinches is None:
        return None
    terms = _reference_terms(tangible, t_pose, virtual, ref.pinches, ref.features, model)
    return float(total(terms[None], model)[0])


def _reference_terms(tangible, t_pose, virtual, pinches, features, model) -> np.ndarray:
    """(8,) contributions of the reference pose, placed by the identity, p1 on p1."""
    terms, _ = pair_terms(tangible, virtual, tangible.table[t_pose][None], feature_table(features),
                          model, R=np.eye(3), t_points=tangible.pinches.points[t_pose][None],
                          v_points=pinches.points[:1])
    return terms[0]
