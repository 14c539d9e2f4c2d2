"""Sampling feasible tripod grasps (thumb against index and middle finger; the rules:
:mod:`tripod_rules`).

Sampling (:func:`sample_tripods`) follows the pinch sampler's: thumb contacts drawn
area-uniformly, a direction within the thumb's friction cone, and where it leaves the solid within
the largest width the middle of the two fingers; the fingers are placed about it, a random spacing
apart along a random tangent direction, where rays from the thumb towards those places leave the
solid. The cheap rules prune the candidates with triangle normals; width strata and a spread order
over the three contacts (:mod:`strata`, :mod:`spread`, the two fingers in either order the same
tripod) choose the ones that get the full check.
"""

from __future__ import annotations

import numpy as np

from ..config import CLEARANCE_TOLERANCE_MM, PREFILTER_MARGIN_DEG, PinchSettings
from ..mesh.surface import SurfaceContext
from .curvature import tangent_frame
from .pinches import reach_rule
from .rounds import GraspKind, nested_sample, sample_rounds
from .sampling import cone_directions
from .tripod_rules import (MAX_SPACING_MM, TRIPOD_RULES, Tripods, cheap_broken, check_tripods,
                           count_first)

#: candidates drawn per requested tripod in the first round; all rounds together at most
#: MAX_DRAW_FACTOR
OVERSAMPLE, MAX_DRAW_FACTOR = 8, 60
#: a ray from the thumb is followed through at most this many surfaces
MAX_EXITS = 8
#: rounds of full checks after the strata
MAX_ROUNDS = 10


def _nearest_exit(ray, face, dist, rays: int, target: np.ndarray):
    """Per ray, the exit nearest ``target`` (rays,) along it: (face, distance), face -1 where
    none."""
    out_face, out_dist = np.full(rays, -1), np.full(rays, np.nan)
    if len(ray):
        order = np.lexsort((np.abs(dist - target[ray]), ray))
        first = order[np.r_[True, ray[order][1:] != ray[order][:-1]]]
        out_face[ray[first]], out_dist[ray[first]] = face[first], dist[first]
    return out_face, out_dist


def candidate_tripods(context: SurfaceContext, p0: np.ndarray, f0: np.ndarray,
                      settings: PinchSettings, rng, rejected: dict):
    """Tripods from thumb contacts ``p0`` on triangles ``f0`` (module notes): (m, 3, 3) points and
    (m, 3) triangles of those that keep the cheap rules (triangle normals, a wider cone)."""
    n = len(p0)
    reach_mm = settings.max_width_mm * (1 + 1e-6)
    d = cone_directions(context.face_normals[f0], settings.friction_cone_deg, rng)
    ray, face, dist = context.exits(p0, d, max_distance=reach_mm, max_hits=MAX_EXITS)
    # one exit per thumb, at random among its exits: the far side the fingers go to
    pick = rng.random(len(ray))
    order = np.lexsort((pick, ray))
    first = order[np.r_[True, ray[order][1:] != ray[order][:-1]]] if len(ray) else order
    rejected["aperture"] += int(n - len(first))
    ray, face, dist = ray[first], face[first], dist[first]
    thumb, thumb_face = p0[ray], f0[ray]
    middle = thumb + dist[:, None] * d[ray]
    # the fingers about the middle: a spacing of contacts from a pad's width to the largest, across
    # a random tangent direction of the far side
    r = settings.fingertip_radius_mm
    spacing = rng.uniform(2.0 * (r - CLEARANCE_TOLERANCE_MM), MAX_SPACING_MM, len(ray))
    phi = rng.random(len(ray)) * 2.0 * np.pi
    t1, t2 = tangent_frame(context.face_normals[face])
    offset = 0.5 * spacing[:, None] * (np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2)
    contacts, contact_faces = [thumb], [thumb_face]
    for sign in (1.0, -1.0):
        aim = middle + sign * offset - thumb
        length = np.linalg.norm(aim, axis=1)
        hits = context.exits(thumb, aim, max_distance=reach_mm, max_hits=MAX_EXITS)
        f, t = _nearest_exit(*hits, len(thumb), length)
        contact_faces.append(f)
        contacts.append(thumb + np.nan_to_num(t)[:, None] * aim
                        / np.maximum(length, 1e-300)[:, None])
    faces = np.stack(contact_faces, axis=1)
    points = np.stack(contacts, axis=1)
    found = (faces >= 0).all(axis=1)
    rejected["spacing"] += int((~found).sum())
    points, faces = points[found], faces[found]
    broken = cheap_broken(context, points, context.face_normals[faces], settings,
                          settings.friction_cone_deg + PREFILTER_MARGIN_DEG, every=False)
    count_first(broken, rejected)
    keep = ~broken.any(axis=1)
    return points[keep], faces[keep]


def _check_picks(context, points, faces, settings, rejected, precheck: bool = True) -> Tripods:
    """The feasible ones among picks: reach first with triangle normals (picks no hand gets to are
    not fitted), then every rule with the normals of fitted patches. Reach is always searched first
    (``precheck`` is the pinch's choice): a tripod's full check is three patches' worth. The hand's
    whole search runs: with its quick directions alone a mug samples twice as fast, but loses the
    tripods on its rim that a plate needs (benchmarks/RESULTS.md)."""
    early = reach_rule(context, points, context.face_normals[faces], settings)
    rejected["reach"] += int((~early.ok).sum())
    part = check_tripods(context, points[early.ok], faces[early.ok], settings=settings,
                         approach=early.approach[early.ok], rejected=rejected)
    return part.subset(part.feasible)


def sample_tripods(context: SurfaceContext, *, settings: PinchSettings = PinchSettings(),
                   source: str = "mesh") -> Tripods:
    """About ``settings.count`` feasible tripods spread over every graspable region (module notes).

    Raises
    ------
    NoFeasiblePinchError
        No candidate passes; the message says how many each rule rejected.

    A count above ``NESTED_ABOVE`` is sampled nested, as pinches are (:func:`nested_sample`).
    """
    return nested_sample(_sample_tripods, context, settings, source)


def _sample_tripods(context: SurfaceContext, settings: PinchSettings, source: str,
                    seen: np.ndarray | None = None, stream: tuple = ()) -> Tripods:
    return sample_rounds(TRIPOD, context, settings, source, seen, stream)


def _thumbs(points: np.ndarray) -> np.ndarray:
    """Local draws start at the thumbs of the tripods found (the draw places the fingers about a
    thumb)."""
    return points[:, 0]


def _refusal(source, drawn, rejected, settings, standing) -> str:
    counts = ", ".join(f"{rule} {k}" for rule, k in rejected.items() if k) or "nothing"
    return (f"{source}: no feasible tripod among {drawn} candidates (rejected by {counts}); "
            "the object may be too small or thin for three fingertips: try --grasp pinch")


#: what the rounds (:mod:`rounds`) sample as a tripod; the first contacts drawn are thumbs
TRIPOD = GraspKind(name="tripod", rules=TRIPOD_RULES, oversample=OVERSAMPLE,
                   max_draw_factor=MAX_DRAW_FACTOR, max_rounds=MAX_ROUNDS, stream=(3,),
                   draw=candidate_tripods, check=_check_picks, first_contacts=_thumbs,
                   refusal=_refusal)
