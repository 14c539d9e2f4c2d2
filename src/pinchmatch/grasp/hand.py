"""The hand: can two fingers of one hand get to the two contacts of a pinch?

Model (lengths in mm):

- **Fingertip:** a sphere of radius ``r_tip`` touching the contact p_i from
  outside, centred at c_i = p_i + r_tip·n_i (the ``clearance`` rule checks it).
- **Finger:** a capsule of radius ``r_f`` whose axis runs from c_i along its
  direction h_i for ``L`` (the distal and middle phalanges).
- **The V of the fingers:** each h_i is the hand's approach h leaned by the
  splay σ (``finger_splay_deg``) in the plane of h and u, away from the other
  finger: h_i = h(θ, α - σ) for the thumb, h(θ, α + σ) for the others. The
  pads of a pinch meet with the fingers converging, not side by side; parallel
  fingers could not both follow a curved wall (outside a bowl, the finger runs
  into the wall above it).
- **One hand:** every finger leans from one h. The pads face each other, so h lies
  within ``approach_tilt_deg`` of the plane perpendicular to the pinch line u
  (for a tripod, the line from the thumb to the middle of the two fingers
  opposite it, whose tips may lie at most ``finger_stagger_mm`` apart along h):
  h(θ, α) = cos α (cos θ e1 + sin θ e2) + sin α u, |α| ≤ A. e1 points away
  from the centroid of the surface, perpendicular to u, so θ = 0 is "from
  outside the object"; e2 = u × e1.

A direction h **clears** when no surface sample lies within ``r_f - tol`` of
either finger's axis (``tol``: the pad's compliance, as for the fingertip).

**The support.** An object that stands on something (:mod:`pinchmatch.mesh.support`: a prop on its
table, a level's object on its counter) has the half-space below its support plane as part of what
the fingers must clear: a test sphere's distance to the object is the smaller of its distance to the
nearest sample and its height above the plane (0 below it), so no finger capsule dips below the
table by more than the pad's tolerance; and no finger's axis h_i may point below the plane's
horizontal (h_i · up ≥ 0), so the hand behind the fingers, which runs on along them, never comes
from under the table. The pinch is **reachable** when some h clears and the hand behind the
fingers gets out: from each finger's end, the line on along h_i meets no
surface. The proximal phalanx and the palm are far wider than a finger, so
where the finger's own line runs into the object (a finger lying flat on the
inside bottom of a cup) the hand cannot follow. And the hand joins the
fingers at their ends: the segment from the thumb's end to each other
finger's meets no surface, so a sheet pinched far in from its edge (a
plate's well) passes between the fingers, never through the hand. These
tests are made at each direction the search evaluates.

The axis test is exact with respect to the dense surface sample: test spheres
of radius ρ = sqrt((r_f - tol)² + (Δ/2)²) sit on the axis every Δ. A sample
within r_f - tol of the axis is within ρ of the nearest test centre, so it is
always seen; Δ is chosen so that ρ = r_f - tol/4, which lets a finger slide
along a flat face at its own radius and pass.

Search for h:

1. Directions at α = 0: θ = 0°, 120°, 240°, and where none clears 60°, 180°,
   300°; where none of those clears, six
   directions tangent to both contact surfaces (perpendicular to n1 - n2, and
   within the band: the fingers slide along a wall or a sheet pinched
   obliquely); where none clears, the surface's three principal axes both
   ways, within the band (a hand leaning onto a ring's or a cup's axis); where
   none clears, the file's three axes both ways (a vessel's axis, where its
   spreads are too alike for the principal axes to find it: a mug's handle
   turns them by 10°, and a finger sliding down the wall along such a tilted
   axis runs into it; objects are mostly modelled upright, so its axis is
   one of the file's); where none clears, the six θ of step 1 leaned by ±2/3
   of the largest tilt (a
   hand reaching past a ring's inner edge). When
   any clears, the pinch is reachable; the approach is the one
   with the most clearance (the largest smallest distance from either axis to
   the surface, resolved up to ``CLEARANCE_CAP_MM`` beyond the finger radius),
   ties to the earlier θ.
2. Otherwise a branch and bound over the whole band: cells of 30° in θ and of
   at most 20° in α, split in four until decided. For a cell whose centre h_c
   is at chord δ from its farthest corner (the farthest point of a θ-α
   rectangle on the sphere of directions), every test centre at distance s
   from the fingertip moves by at most s·δ, and distances to the surface are
   1-Lipschitz, so a cell whose
   centre has d_j(h_c) + s_j·δ < ρ for some test sphere j holds no clearing
   direction and is dropped; a centre that clears decides the pinch. Cells are
   split until L·δ ≤ tol: an approach that clears with ``tol`` to spare is
   then always found, so a gap the search misses is narrower than the finger
   by less than the tolerance. The work is bounded: each pinch keeps at most
   ``MAX_CELLS_PER_PINCH`` cells per level, those with the largest bound; the
   guarantee holds where no more were open (a finger that can only slide
   exactly along a sheet leaves a thin band of directions open at every level).
   The hand's tests are made at cell centres only: a cell whose centre's hand is
   stuck is not refined, whether its fingers fit there or not (so the many
   cells along the border of a region where the fingers fit but the hand does
   not get out, deep in a mug, are dropped at once).

The hand's test comes before the fingers': a direction or a cell whose hand
is stuck fails whatever its fingers meet, so its test spheres are never
queried (a hollow object has many such, and a ray costs less than the dozen
distance queries of a finger). How the spheres' distances are queried, each
only where a decision needs it, is :mod:`pinchmatch.grasp.finger_spheres`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import CLEARANCE_TOLERANCE_MM
from .finger_spheres import axis_distances

#: allowed penetration (mm) of a fingertip or finger into the surface: the pad is soft
PAD_TOLERANCE_MM = CLEARANCE_TOLERANCE_MM
#: directions of the first, quick search: θ steps at α = 0
QUICK_DIRECTIONS = 6
#: the last quick group leans the hand this share of the largest tilt towards either finger
LEAN_SHARE = 2.0 / 3.0
#: coarse cells of the full search: θ width (deg) and largest α width (deg)
CELL_THETA_DEG = 30.0
CELL_ALPHA_DEG = 20.0
#: clearance beyond the finger radius that the distance queries resolve (mm); more counts as this
CLEARANCE_CAP_MM = 1.0
#: at most this many open cells per pinch and refinement level, the most promising kept
MAX_CELLS_PER_PINCH = 32
#: how far the fingertips beside the thumb's opposite (index and middle of a tripod) may lie apart
#: along the approach: the middle finger is about 8 mm longer than the index (hand anthropometry,
#: e.g. Greiner 1991), and flexing one finger a little more than the other makes up about as much
#: again; a documented choice
FINGER_STAGGER_MM = 20.0
#: how far each finger leans from the hand's approach, away from the other finger (deg): the pads of
#: a pinch meet with the fingers in a V, not side by side; a documented choice (docs/method.md)
FINGER_SPLAY_DEG = 15.0
#: how far below the support's horizontal a hand's approach may point (a hand sliding along the
#: table)
SUPPORT_LEVEL_TOLERANCE = 1e-9


@dataclass(frozen=True)
class Hand:
    """The finger geometry of the reach rule (mm, degrees)."""

    fingertip_radius_mm: float = 8.0
    finger_radius_mm: float = 8.0
    finger_length_mm: float = 45.0
    approach_tilt_deg: float = 30.0
    tolerance_mm: float = PAD_TOLERANCE_MM
    finger_stagger_mm: float = FINGER_STAGGER_MM
    finger_splay_deg: float = FINGER_SPLAY_DEG

    @property
    def test_radius_mm(self) -> float:
        """ρ: a sample closer than this to a test centre is too close to the axis."""
        return self.finger_radius_mm - 0.25 * self.tolerance_mm

    @property
    def test_offsets_mm(self) -> np.ndarray:
        """(P,) distances s_j of the test centres from the fingertip centre, the last at L."""
        inner = max(self.finger_radius_mm - self.tolerance_mm, 1e-3)
        half = math.sqrt(max(self.test_radius_mm**2 - inner**2, 1e-6))
        spacing = min(2.0 * half, self.finger_radius_mm)
        count = max(1, math.ceil(self.finger_length_mm / spacing))
        return np.linspace(self.finger_length_mm / count, self.finger_length_mm, count)


def hand_of(settings) -> Hand:
    """The hand of a run's :class:`pinchmatch.config.PinchSettings`."""
    return Hand(fingertip_radius_mm=settings.fingertip_radius_mm,
                finger_radius_mm=settings.finger_radius_mm,
                finger_length_mm=settings.finger_length_mm,
                approach_tilt_deg=settings.approach_tilt_deg, tolerance_mm=PAD_TOLERANCE_MM,
                finger_splay_deg=settings.finger_splay_deg)


@dataclass(frozen=True)
class Reach:
    """Result of the reach rule for n pinches.

    ok : (n,) bool                  some approach clears
    approach : (n, 3) float64       unit h with the most clearance found (NaN where none clears)
    clearance_mm : (n,) float64     smallest distance from either finger's axis to the surface,
                                    minus the finger radius, along ``approach`` (NaN where none)
    """

    ok: np.ndarray
    approach: np.ndarray
    clearance_mm: np.ndarray


def pinch_lines(points: np.ndarray) -> np.ndarray:
    """(n, 3) unit pinch lines u: from the thumb (contact 0) towards the other fingers' middle."""
    seg = points[:, 1:].mean(axis=1) - points[:, 0]
    return seg / np.maximum(np.linalg.norm(seg, axis=1, keepdims=True), 1e-300)


def approach_frame(context, points: np.ndarray, axis: np.ndarray | None = None):
    """u, e1 and e2 = u × e1, each (n, 3): u the pinch line (or ``axis``), e1 perpendicular
    to it, pointing away from the surface's centroid. On the line through the centroid along u,
    where "away" has no direction, e1 is the surface's principal axis of least spread (the
    symmetry axis of a ring, a plate, a disc), or of middle spread when that one lies along u."""
    u = pinch_lines(points) if axis is None else axis
    out = points.mean(axis=1) - context.centroid_mm
    out -= np.einsum("ij,ij->i", out, u)[:, None] * u
    norm = np.linalg.norm(out, axis=1)
    first, second = context.principal_axes[:, 0], context.principal_axes[:, 1]
    fallback = first - (u @ first)[:, None] * u
    along = np.linalg.norm(fallback, axis=1) < 0.3
    fallback[along] = second - (u[along] @ second)[:, None] * u[along]
    fallback /= np.linalg.norm(fallback, axis=1, keepdims=True)
    e1 = np.where((norm > 1e-6)[:, None], out / np.maximum(norm, 1e-300)[:, None], fallback)
    return u, e1, np.cross(u, e1)


def _directions(u, e1, e2, theta, alpha):
    """h(θ, α) for rows of frames and matching (m,) angles in radians."""
    ca = np.cos(alpha)[:, None]
    return ca * (np.cos(theta)[:, None] * e1 + np.sin(theta)[:, None]
                 * e2) + np.sin(alpha)[:, None] * u


def _splay_signs(fingers: int) -> np.ndarray:
    """(F,) which way each finger leans from the hand's approach along the pinch line: the thumb
    away from the others (-1), the others away from the thumb (+1)."""
    return np.r_[-1.0, np.ones(fingers - 1)]


def _finger_directions(u, h, splay, fingers):
    """(m, F, 3) each finger's direction for hand approaches h (m, 3) and pinch lines u (m, 3): h
    leaned by ``splay`` (radians) in the plane of h and u, away from the other finger; h itself for
    0."""
    if splay == 0.0:
        return np.repeat(h[:, None, :], fingers, axis=1)
    along = np.clip(np.einsum("md,md->m", h, u), -1.0, 1.0)
    flat = h - along[:, None] * u
    flat /= np.maximum(np.linalg.norm(flat, axis=1, keepdims=True), 1e-300)
    alpha = np.arcsin(along)[:, None] + splay * _splay_signs(fingers)[None, :]
    return np.cos(alpha)[:, :, None] * flat[:, None, :] + np.sin(alpha)[:, :, None] * u[:, None, :]


def finger_directions(points: np.ndarray, approach: np.ndarray, hand: Hand) -> np.ndarray:
    """(n, F, 3) the direction of each finger from its fingertip towards the hand, for contacts
    ``points`` (n, F, 3, the thumb's first) held from ``approach`` (n, 3): what a viewer draws."""
    return _finger_directions(pinch_lines(points), np.asarray(approach, dtype=np.float64),
                              math.radians(hand.finger_splay_deg), points.shape[1])


def _staggered(tips, h, limit):
    """(m,) bool: the fingers opposite the thumb (tips 1…F-1) lie further apart along h than
    ``limit`` (never for a pinch's single finger)."""
    if tips.shape[1] < 3:
        return np.zeros(len(h), dtype=bool)
    along = np.einsum("mfd,md->mf", tips[:, 1:], h)
    return along.max(axis=1) - along.min(axis=1) > limit


def _hand_free(context, tips, h, length):
    """(m,) bool: beyond each finger's end, the line on along its direction h (m, F, 3) meets no
    surface (the hand gets out), the segment from the thumb's end to each other finger's meets none
    (the web of the hand joins them there: a sheet pinched far in from its edge passes between
    splayed fingers, never through the hand), and no finger points below the support's horizontal
    (no hand comes from under the table)."""
    fingers = tips.shape[1]
    ends = tips + length * h
    face = context.rays.intersects_first(ends.reshape(-1, 3), h.reshape(-1, 3))
    free = (np.asarray(face) < 0).reshape(-1, fingers).all(axis=1)
    # the hand joins the fingers' ends: nothing of the object lies between the thumb's end and
    # another's
    web = (ends[:, 1:] - ends[:, :1]).reshape(-1, 3)
    span = np.linalg.norm(web, axis=1)
    apart = span > 1e-9
    _, hit = context.first_hit(np.repeat(ends[:, 0], fingers - 1, axis=0)[apart], web[apart])
    joined = np.ones(len(span), dtype=bool)
    joined[apart] = hit > span[apart]
    free &= joined.reshape(-1, fingers - 1).all(axis=1)
    if context.support is not None:
        free &= (h @ context.support.normal >= -SUPPORT_LEVEL_TOLERANCE).all(axis=1)
    return free


def _hand_gate(context, tips, h, length, possible=None):
    """The gate of :func:`~pinchmatch.grasp.finger_spheres.axis_distances` for fingertips ``tips``
    and finger directions ``h`` (m, F, 3): of the rows it is asked about, those ``possible`` (m,)
    bool (default: all) whose hand gets out (:func:`_hand_free`)."""
    def gate(sub):
        passed = np.ones(len(sub), dtype=bool) if possible is None else possible[sub].copy()
        if passed.any():
            passed[passed] = _hand_free(context, tips[sub[passed]], h[sub[passed]], length)
        return passed
    return gate


def reach(context, points: np.ndarray, normals: np.ndarray, hand: Hand,
          *, approach: np.ndarray | None = None, thorough: bool = True) -> Reach:
    """The reach rule for n grasps of F fingers (2: a pinch; 3: a tripod).

    Parameters
    ----------
    context : SurfaceContext
    points, normals : (n, F, 3) float64
        Contacts and unit outward normals, the thumb's first.
    approach : (n, 3) float64, optional
        A direction to try first (an earlier answer for nearly the same pinch); where it
        clears it is kept and nothing else is searched.
    thorough : bool
        False: only the quick directions (step 1) are tried, no branch and bound; a pinch found
        reachable is reachable, but a few reachable ones are missed (for candidates that need
        not all be found: refinement's moves).
    """
    n = len(points)
    tips = points + hand.fingertip_radius_mm * normals
    offsets = hand.test_offsets_mm
    rho = hand.test_radius_mm
    cap = hand.finger_radius_mm + CLEARANCE_CAP_MM
    ok = np.zeros(n, dtype=bool)
    best_h = np.full((n, 3), np.nan)
    best_margin = np.full(n, np.nan)
    if n == 0:
        return Reach(ok, best_h, best_margin)
    u, e1, e2 = approach_frame(context, points)

    sin_tilt = np.sin(np.radians(hand.approach_tilt_deg)) + 1e-12
    geometry, found = (u, tips, offsets, rho, cap), (ok, best_h, best_margin)
    pending = np.arange(n)
    if approach is not None:
        given = np.asarray(approach, dtype=np.float64)
        try_rows = pending[np.isfinite(given).all(axis=1)]
        if len(try_rows):
            _quick(context, hand, try_rows, given[try_rows], geometry, sin_tilt, found)
            pending = pending[~ok[pending]]

    # 1. quick: six directions perpendicular to the pinch line (three at a time); where none clears,
    # six tangent
    #    to both contact surfaces (perpendicular to the squeeze axis of the normals: the fingers
    #    slide along a sheet or a wall pinched obliquely); where none clears, the object's three
    #    principal axes both ways (a hand leaning onto a ring's or a cup's axis). The one with the
    #    most clearance.
    k = QUICK_DIRECTIONS
    theta = np.arange(k) * (2.0 * np.pi / k)
    groups = ("perpendicular", "perpendicular, between", "tangent", "principal", "frame", "leaned")
    if points.shape[1] > 2:  # a tripod: first the two directions with its fingers side by side
        groups = ("side by side",) + groups
    for group in groups:
        if not len(pending):
            break
        if group == "side by side":
            side = np.cross(u[pending], tips[pending, 2] - tips[pending, 1])
            side /= np.maximum(np.linalg.norm(side, axis=1, keepdims=True), 1e-300)
            h = np.stack([side, -side], axis=1).reshape(-1, 3)
        elif group in ("principal", "frame"):
            axes = context.principal_axes.T if group == "principal" else np.eye(3)
            h = np.tile(np.concatenate([axes, -axes]), (len(pending), 1))
        elif group == "leaned":
            lean = np.radians(LEAN_SHARE * hand.approach_tilt_deg)
            m = 2 * k
            h = _directions(np.repeat(u[pending], m, axis=0), np.repeat(e1[pending], m, axis=0),
                            np.repeat(e2[pending], m, axis=0),
                            np.tile(np.repeat(theta, 2), len(pending)),
                            np.tile(np.tile([lean, -lean], k), len(pending)))
        else:
            angles = theta
            if group == "tangent":
                axis = normals[pending, 0] - normals[pending, 1:].mean(axis=1)
                norm = np.linalg.norm(axis, axis=1, keepdims=True)
                axis = np.where(norm > 1e-9, axis / np.maximum(norm, 1e-300), u[pending])
                _, f1, f2 = approach_frame(context, points[pending], axis=axis)
            else:
                # the six perpendicular directions in two halves: 0, 120, 240 degrees, then the
                # others
                angles = theta[0::2] if group == "perpendicular" else theta[1::2]
                axis, f1, f2 = u[pending], e1[pending], e2[pending]
            m = len(angles)
            h = _directions(np.repeat(axis, m, axis=0), np.repeat(f1, m, axis=0),
                            np.repeat(f2, m, axis=0), np.tile(angles, len(pending)),
                            np.zeros(m * len(pending)))
        _quick(context, hand, pending, h, geometry, sin_tilt, found)
        pending = pending[~ok[pending]]

    # 2. branch and bound over the whole band
    if len(pending) and thorough:
        found_rows, found_h, found_margin = _search_band(context, tips, u, e1, e2, pending, hand,
                                                         offsets, rho, cap)
        ok[found_rows] = True
        best_h[found_rows] = found_h
        best_margin[found_rows] = found_margin
    return Reach(ok, best_h, best_margin)


def _quick(context, hand, pending, h, geometry, sin_tilt, found):
    """Try k directions for each pending pinch (``h``: (len(pending) * k, 3), pinch-major) and
    record, where some clear, the one with the most clearance (the first of equals)."""
    u, tips, offsets, rho, cap = geometry
    ok, best_h, best_margin = found
    k = len(h) // len(pending)
    rows = np.repeat(pending, k)
    in_band = np.abs(np.einsum("ij,ij->i", h, u[rows])) <= sin_tilt
    hf = _finger_directions(u[rows], h, math.radians(hand.finger_splay_deg), tips.shape[1])
    # a direction out of the band, or whose hand is stuck, fails whatever its fingers meet: not
    # queried
    possible = in_band & ~_staggered(tips[rows], h, hand.finger_stagger_mm)
    d, refused = axis_distances(context, tips[rows], hf, offsets, cap, rho,
                                gate=_hand_gate(context, tips[rows], hf, hand.finger_length_mm,
                                                possible))
    # each asked the gate: its hand gets out
    clears = possible & ~refused & (d >= rho).all(axis=(1, 2))
    clears = clears.reshape(-1, k)
    margin = (d.min(axis=(1, 2)) - hand.finger_radius_mm).reshape(-1, k)
    pick = np.argmax(np.where(clears, margin, -np.inf), axis=1)
    hit = clears.any(axis=1)
    chosen = pending[hit]
    ok[chosen] = True
    best_h[chosen] = h.reshape(-1, k, 3)[hit, pick[hit]]
    best_margin[chosen] = margin[hit, pick[hit]]


def band_cells(hand: Hand):
    """Coarse cells covering the band: centres (theta, alpha) and half widths, radians."""
    n_theta = int(round(360.0 / CELL_THETA_DEG))
    tilt = hand.approach_tilt_deg
    n_alpha = max(1, math.ceil(2.0 * tilt / CELL_ALPHA_DEG)) if tilt > 0 else 1
    half_theta = math.radians(180.0 / n_theta)
    half_alpha = math.radians(tilt / n_alpha)
    theta = np.arange(n_theta) * 2.0 * half_theta
    alpha = (-tilt + (2 * np.arange(n_alpha) + 1) * tilt / n_alpha) if tilt > 0 else np.zeros(1)
    tt, aa = np.meshgrid(theta, np.radians(alpha), indexing="xy")
    return tt.ravel(), aa.ravel(), half_theta, half_alpha


def _far_chord(alpha, ht, ha):
    """The chord from the direction at the centre of a θ-α cell (θ half width ``ht``, α centre
    ``alpha`` and half width ``ha``, radians) to the cell's farthest corner: on the sphere of
    directions, the farthest point of a θ-α rectangle from its centre is a corner."""
    cos_far = np.minimum(np.sin(alpha) * np.sin(alpha + ha) + np.cos(alpha) * np.cos(alpha + ha)
                         * np.cos(ht),
                         np.sin(alpha) * np.sin(alpha - ha) + np.cos(alpha) * np.cos(alpha - ha)
                         * np.cos(ht))
    return np.sqrt(np.maximum(2.0 - 2.0 * cos_far, 0.0))  # chord length of a unit vector


def _search_band(context, tips, u, e1, e2, pending, hand, offsets, rho, cap):
    theta0, alpha0, ht, ha = band_cells(hand)
    c = len(theta0)
    rows = np.repeat(pending, c)
    theta = np.tile(theta0, len(pending))
    alpha = np.tile(alpha0, len(pending))
    hint = np.full(len(rows), -1)  # the (finger, sphere) that bounded the parent cell tightest
    length = hand.finger_length_mm
    fingers = tips.shape[1]
    flat_offsets = np.tile(offsets, fingers)  # (FP,): finger-major, as d.reshape(m, FP)
    decided = np.zeros(len(tips), dtype=bool)
    out_rows, out_h, out_margin = [], [], []
    splay = math.radians(hand.finger_splay_deg) * _splay_signs(fingers)
    while len(rows):
        # how far a test centre s from the fingertip can move within a cell: s·chord, the chord
        # of the angle from the cell's centre to its farthest corner (on the sphere of directions,
        # the farthest point of a θ-α rectangle from its centre is a corner); each finger's cell
        # is the hand's moved by its splay along α
        delta = _far_chord(alpha, ht, ha)
        h = _directions(u[rows], e1[rows], e2[rows], theta, alpha)
        finger_alpha = alpha[:, None] + splay[None, :]
        hf = np.stack([_directions(u[rows], e1[rows], e2[rows], theta, finger_alpha[:, f])
                       for f in range(fingers)], axis=1)
        delta_f = _far_chord(finger_alpha, ht, ha)
        live = np.ones(len(rows), dtype=bool)
        if fingers > 2:
            # the cells whose every direction staggers the fingers beyond the limit are dropped
            apart = tips[rows, 2] - tips[rows, 1]
            least = np.abs(np.einsum("md,md->m", apart, h)) - np.linalg.norm(apart, axis=1) * delta
            live = least <= hand.finger_stagger_mm
        idx = np.flatnonzero(live)
        # the sphere that bounded the parent is queried first: most cells that can be dropped are
        # dropped by it a cell whose centre's hand is stuck is dropped whatever its fingers meet:
        # its spheres are not queried
        d, stuck = axis_distances(context, tips[rows[idx]], hf[idx], offsets, cap, rho,
                                  delta_f[idx], first=hint[idx],
                                  gate=_hand_gate(context, tips[rows[idx]], hf[idx], length))
        d = d.reshape(len(idx), fingers * len(offsets))
        margin = d.min(axis=1) - hand.finger_radius_mm
        fits = (d >= rho).all(axis=1) & ~_staggered(tips[rows[idx]], h[idx], hand.finger_stagger_mm)
        clears = fits & ~stuck  # a row that fits was asked the gate: its hand gets out
        if clears.any():
            # per pinch, the clearing cell with the most clearance (first of equals in cell order)
            hit = np.flatnonzero(clears)
            order = np.lexsort((hit, -margin[hit], rows[idx[hit]]))
            hit = hit[order]
            first = np.r_[True, rows[idx[hit]][1:] != rows[idx[hit]][:-1]]
            hit = hit[first]
            out_rows.append(rows[idx[hit]])
            out_h.append(h[idx[hit]])
            out_margin.append(margin[hit])
            decided[rows[idx[hit]]] = True
        if length * delta_f.max() <= hand.tolerance_mm:
            break
        # a cell can hold a clearing direction only if every test sphere could move clear
        slack = d + flat_offsets[None, :] * np.repeat(delta_f[idx], len(offsets), axis=1)
        bound = slack.min(axis=1)
        # a finger that fits where the hand behind it does not get out is not refined: the
        # hand's line is tested at cell centres only, and neither is a cell whose centre's hand is
        # stuck
        keep = ~decided[rows[idx]] & ~fits & ~stuck & (bound >= rho)
        cand = np.flatnonzero(keep)
        if len(cand):
            # per pinch, the most promising cells (largest bound, then cell order)
            order = cand[np.lexsort((cand, -bound[cand], rows[idx[cand]]))]
            group = rows[idx[order]]
            start = np.r_[0, np.flatnonzero(group[1:] != group[:-1]) + 1]
            rank = np.arange(len(order)) - np.repeat(start, np.diff(np.r_[start, len(order)]))
            keep = np.zeros_like(keep)
            keep[np.sort(order[rank < MAX_CELLS_PER_PINCH // 4])] = True
        kept = idx[keep]
        next_hint = np.argmin(slack[keep], axis=1)
        ht, ha = ht / 2.0, ha / 2.0
        signs = np.array([[-1, -1], [-1, 1], [1, -1], [1, 1]], dtype=float)
        rows = np.repeat(rows[kept], 4)
        hint = np.repeat(next_hint, 4)
        theta = (theta[kept][:, None] + signs[None, :, 0] * ht).ravel()
        alpha = (alpha[kept][:, None] + signs[None, :, 1] * ha).ravel()
    if not out_rows:
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0)
    return np.concatenate(out_rows), np.concatenate(out_h), np.concatenate(out_margin)
