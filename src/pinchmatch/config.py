"""The one configuration of a run: everything that changes a result, in one frozen record.

:class:`Config` holds :class:`PinchSettings` (the pinch rules, the hand and the sampling: what an
object's candidates depend on) and :class:`MatchSettings` (the criteria, weights, pooling,
normalisation, placement and redirection, top-k, distinct, landing, refinement, ranking). Its
:meth:`Config.digest` is computed from every field; the caches' keys are made of it, the code's
digest (:func:`pinchmatch.options.code_digest`) and the inputs' bytes, with no hand-kept list. Each
field describes its own command-line option (:func:`pinchmatch.options.option`), so the command
line's options, defaults, bounds and help are generated from these records
(:func:`pinchmatch.cli.parser.add_record_options`) and cannot drift from the library.

Plain Python: the command line builds its parser from these records without loading the pipeline.
Each stage reads its part: the grasp stage the pinch settings, matching the match settings.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field

from .errors import ConfigError
from .options import digest, option

# the criteria
CRITERIA = ("width", "com", "tilt", "normal", "axis", "kmax", "kmin", "mass")
#: the method paper's seven criteria (``--criteria paper``)
PAPER_CRITERIA = CRITERIA[:7]
#: the default set: the paper's criteria with ``mass`` for ``com``. Both measure how far the pinch
#: sits from the centre of mass (d is the part of the offset o along the principal axis); ``mass``
#: compares the whole offset, or the felt torque where both masses are known, so ``com`` would
#: charge the same lever arm twice
DEFAULT_CRITERIA = ("width", "tilt", "normal", "axis", "kmax", "kmin", "mass")
#: the largest weight: beyond it, costs in JND^3.5 leave the range of a float for ordinary
#: differences
MAX_WEIGHT = 1e6
#: ways of pooling the criteria into one cost (module notes)
POOLINGS = ("quick", "sum")
#: what a match is ranked by (:mod:`pinchmatch.match.felt`): its cost over where the fingers land,
#: the worst of those, or its cost on target
RANKS = ("expected", "worst", "nominal")

class Weights(Mapping):
    """A read-only mapping of criterion -> weight (a frozen record's weights stay as they were
    made); picklable, so a model travels to worker processes."""

    def __init__(self, values: Mapping):
        self._values = dict(values)

    def __getitem__(self, key):
        return self._values[key]

    def __iter__(self):
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def __eq__(self, other) -> bool:
        return isinstance(other, Mapping) and dict(self) == dict(other)

    def __hash__(self) -> int:
        return hash(tuple(sorted(self._values.items())))

    def __repr__(self) -> str:
        return f"Weights({self._values!r})"

    def __reduce__(self):
        return (Weights, (self._values,))


def complete_weights(given: Mapping, *, criteria: tuple = DEFAULT_CRITERIA) -> dict[str, float]:
    """Weights for every criterion: those given, 1 for the other criteria in use, 0 for criteria
    not in use. The one rule for the library's :class:`match.MatchSettings` and ``--weights``.

    Refused: unknown or misspelt names, criteria not in use (unless given as 0), weights that
    are negative or not finite, and weights that are all zero (nothing would be compared).

    Parameters
    ----------
    given : mapping
        {criterion: weight} the user gave.
    criteria : tuple of str
        The criteria in use (:data:`pinchmatch.config.DEFAULT_CRITERIA` or the paper's).

    Returns
    -------
    dict
        {criterion: weight} for every criterion.

    Examples
    --------
    >>> weights = complete_weights({"width": 2})
    >>> weights["width"], weights["kmax"], weights["com"]  # com: not a default criterion
    (2.0, 1.0, 0.0)
    """
    weights = {c: (1.0 if c in criteria else 0.0) for c in CRITERIA}
    for name, w in given.items():
        if name in CRITERIA and name not in criteria and w == 0:
            continue  # a criterion not in use, given as off
        if name not in criteria:
            close = difflib.get_close_matches(str(name), criteria, n=1)
            hint = f"did you mean {close[0]!r}? " if close else ""
            which = "paper" if tuple(criteria) == PAPER_CRITERIA else "default"
            extra = f" (not part of --criteria {which})" if name in CRITERIA else ""
            raise ConfigError(f"--weights: unknown criterion {name!r}{extra}; {hint}valid: "
                              f"{', '.join(criteria)}")
        try:
            w = float(w)
        except (TypeError, ValueError):
            w = float("nan")
        if not math.isfinite(w) or w < 0:
            raise ConfigError(f"--weights: {name}={given[name]!r} needs a weight of 0 or more, as "
                              f"{name}=1")
        if w > MAX_WEIGHT:
            raise ConfigError(f"--weights: {name}={given[name]!r} is more than {MAX_WEIGHT:g}; "
                              "weights say how much "
                              "each criterion counts against the others, give them between 0 and "
                              f"{MAX_WEIGHT:g}")
        weights[name] = w
    if not any(weights[c] > 0 for c in criteria):
        raise ConfigError("--weights: every weight is 0, so nothing would be compared; give at "
                          "least one criterion a positive weight")
    return weights



# the pinch rules, the hand and the sampling
#: width's just-noticeable difference: 5.75 % of the reference width (de Tinguy et al., WHC 2019),
#: floor
#: 0.4 mm (Ho & Srinivasan); the cost's width criterion and the sampler's spread both count widths
#: in it
WIDTH_JND_FRACTION, WIDTH_JND_FLOOR_MM = 0.0575, 0.4
#: allowed fingertip-sphere penetration (mm): the pad is soft (the hand model's tolerance too)
CLEARANCE_TOLERANCE_MM = 0.3
#: pre-filter margin on the friction cone with triangle normals, before patch normals exist
PREFILTER_MARGIN_DEG = 2.0
#: fingertip radii a hand (or a gloved hand, or a stylus-like tool) has: 2-25 mm
FINGERTIP_RADIUS_RANGE_MM = (2.0, 25.0)
#: the widest thumb-index pinch of a large adult hand, with margin (mm)
MAX_WIDTH_MM = 300.0
#: pinches per object at most: memory grows with the count (about 40 candidates are drawn per pinch)
MAX_COUNT = 100_000


def _whole(value) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


#: the grasps a run can look for: a thumb-index pinch, or a tripod (thumb against index and middle
#: finger)
GRASPS = ("pinch", "tripod")


@dataclass(frozen=True)
class PinchSettings:
    """Options of pinch sampling and feasibility (lengths in mm, angles in degrees)."""

    friction_cone_deg: float = option(30.0, group="pinch", kind="float",
                                      help="antipodal tolerance: how far each squeeze may lean "
                                           "from the surface normal, 0 to 90 deg")
    min_width_mm: float = option(0.5, group="pinch", kind="float",
                                 help="smallest pinch width (a bowl wall, a plate rim, a card)")
    max_width_mm: float = option(100.0, group="pinch", kind="float",
                                 help="largest pinch width; at most 300")
    fingertip_radius_mm: float = option(8.0, group="pinch", kind="float",
                                        help="fingertip sphere radius; 2 to 25")
    patch_radius_mm: float = option(8.0, group="pinch", kind="float",
                                    help="contact patch radius; 0.5 to 50")
    count: int = option(1000, group="sampling", kind="int",
                        help="about how many pinches per object; at most 100,000")
    seed: int = option(0, group="sampling", kind="int", help="random seed, 0 or more")
    snap_tolerance_mm: float = option(2.0, group="pinch", kind="float",
                                      help="how far a given contact may be from the surface")
    finger_radius_mm: float = option(8.0, group="pinch", kind="float",
                                     help="radius of the finger capsule behind each fingertip; at "
                                          "most the fingertip's")
    finger_length_mm: float = option(45.0, group="pinch", kind="float",
                                     help="length of the finger capsule: distal and middle "
                                          "phalanges; 5 to 150")
    approach_tilt_deg: float = option(30.0, group="pinch", kind="float",
                                      help="how far the hand's approach may lean towards either "
                                           "finger from the "
                                           "plane perpendicular to the pinch line; 0 to 90")
    finger_splay_deg: float = option(15.0, group="pinch", kind="float",
                                     help="how far each finger leans from the hand's approach, "
                                          "away from the "
                                          "other: the V of the thumb and index; 0 (side by side) "
                                          "to 45")
    grasp: str = option("pinch", group="sampling", kind="choice", choices=GRASPS,
                        help="the grasp: pinch (thumb and index) or tripod (thumb against index "
                             "and middle finger; docs/method.md)")

    def __post_init__(self):
        lo, hi = FINGERTIP_RADIUS_RANGE_MM
        checks = [
            ("--friction-cone-deg", self.friction_cone_deg, 0.0 < self.friction_cone_deg < 90.0,
             "between 0 and 90 (exclusive)"),
            ("--min-width-mm", self.min_width_mm, self.min_width_mm >= 0.0, "0 or more"),
            ("--max-width-mm", self.max_width_mm, self.min_width_mm < self.max_width_mm
             <= MAX_WIDTH_MM,
             f"larger than --min-width-mm and at most {MAX_WIDTH_MM:g} (a thumb-index pinch spans "
             "at most a hand)"),
            ("--fingertip-radius-mm", self.fingertip_radius_mm, lo <= self.fingertip_radius_mm
             <= hi,
             f"between {lo:g} and {hi:g} (a child's to a large adult's finger pad, with room for "
             "gloves and tools)"),
            ("--patch-radius-mm", self.patch_radius_mm, 0.5 <= self.patch_radius_mm <= 50.0,
             "between 0.5 and 50 (what a fingertip pad touches)"),
            ("--count", self.count, _whole(self.count) and 1 <= self.count <= MAX_COUNT,
             f"a whole number from 1 to {MAX_COUNT:,} (memory grows with it; match objects in "
             "several runs instead)"),
            ("--seed", self.seed, _whole(self.seed) and 0 <= self.seed < 2**63,
             "a whole number of 0 or more"),
            ("--snap-tolerance-mm", self.snap_tolerance_mm, self.snap_tolerance_mm > 0.0,
             "positive"),
            ("--finger-radius-mm", self.finger_radius_mm,
             CLEARANCE_TOLERANCE_MM < self.finger_radius_mm <= self.fingertip_radius_mm,
             f"more than {CLEARANCE_TOLERANCE_MM:g} and at most --fingertip-radius-mm (the finger "
             "starts at the fingertip sphere's centre)"),
            ("--finger-length-mm", self.finger_length_mm, 5.0 <= self.finger_length_mm <= 150.0,
             "between 5 and 150 (a fingertip alone to a whole finger)"),
            ("--approach-tilt-deg", self.approach_tilt_deg, 0.0 <= self.approach_tilt_deg < 90.0,
             "between 0 and 90 (0 included)"),
            ("--finger-splay-deg", self.finger_splay_deg, 0.0 <= self.finger_splay_deg <= 45.0,
             "between 0 and 45 (0: the fingers side by side)"),
            ("--grasp", 0.0, self.grasp in GRASPS, " or ".join(GRASPS)),
        ]
        for flag, value, ok, want in checks:
            if isinstance(value, bool) or not (ok and math.isfinite(float(value))):
                # True is not a number
                raise ConfigError(f"{flag}: got {value!r}; it must be {want}")

    def as_dict(self) -> dict:
        return {
            "friction_cone_deg": self.friction_cone_deg,
            "min_width_mm": self.min_width_mm,
            "max_width_mm": self.max_width_mm,
            "fingertip_radius_mm": self.fingertip_radius_mm,
            "patch_radius_mm": self.patch_radius_mm,
            "count": int(self.count),
            "seed": int(self.seed),
            "snap_tolerance_mm": self.snap_tolerance_mm,
            "clearance_tolerance_mm": CLEARANCE_TOLERANCE_MM,
            "finger_radius_mm": self.finger_radius_mm,
            "finger_length_mm": self.finger_length_mm,
            "approach_tilt_deg": self.approach_tilt_deg,
            "finger_splay_deg": self.finger_splay_deg,
            "grasp": self.grasp,
        }


# the redirection of the hand (placement fixed)
#: body-warping detection threshold of the redirection angle (deg): Zenner and Krüger 2019
REDIRECT_THRESHOLD_DEG = 4.5
#: the largest redirection angle a match may use before the carousel takes over (deg)
MAX_REDIRECT_DEG = 4.5
#: the turn of the pinch axis that counts as one threshold unit (deg): the orientation threshold of
#: an edge on the fingerpad (about 20°, Bensmaia et al. 2008; perception.md), a documented choice
AXIS_THRESHOLD_DEG = 20.0
#: where the hand rests before it reaches, when not given: a user standing at the prop's table, the
#: hand 150 mm above the table (the prop's support) and 300 mm toward the user (+Z, the side a glTF
#: scene faces) from the middle of the prop's footprint, mm
DEFAULT_HAND_OFFSET_MM = (0.0, 150.0, 300.0)
#: the reach gains a redirection may use (virtual over physical distance from the hand's start): the
#: unnoticed hand-movement gains of HaRT (Zenner et al., the Haptic Retargeting Toolkit's defaults)
GAIN_RANGE = (0.94, 1.14)
#: the farthest a hand start may be from a prop it reaches for (mm): an arm's reach, 95th percentile
#: (about 800 mm, shoulder to grip), with a lean; from farther, every offset is a small angle and
#: redirection means nothing
MAX_REACH_MM = 1000.0
#: an object stays in the level (redirected) unless the carousel would cost this much less (JND)
CAROUSEL_MARGIN_JND = 0.5
#: the bounds of the options (deg, mm)
MAX_THRESHOLD_DEG, MAX_HAND_START_MM = 90.0, 1e5
PLACEMENTS = ("registered", "fixed")

# where the user stands (:mod:`pinchmatch.match.comfort`)
#: an approach from the far half of a prop (seen from the user) must come from at least this far
#: above the horizontal (deg): lower, the wrist or forearm would turn beyond its functional range; a
#: choice
FAR_SIDE_MIN_ELEVATION_DEG = 35.0

# how a virtual object shown on a prop rests on the prop's support (:mod:`pinchmatch.match.rest`)
#: within this many mm below or above the support, a placed object reads as resting and costs
#: nothing
REST_TOLERANCE_MM = 2.0
#: mm past the tolerance that cost one JND: sinking into the support (a violation of solidity, seen
#: at once) and hovering above it (read as resting or just lifted); choices, reasoned in
#: docs/matching.md
REST_SINK_MM_PER_JND = 1.0
REST_FLOAT_MM_PER_JND = 10.0
#: the bounds of both rates (mm per JND)
REST_RATE_RANGE_MM = (0.01, 1e4)


@dataclass(frozen=True)
class Redirect:
    """How far the hand may be redirected and what it costs (see the module notes);
    ``hand_start_mm`` None: each prop's default (``DEFAULT_HAND_OFFSET_MM`` from its pose
    position)."""

    hand_start_mm: tuple | None = None
    threshold_deg: float = REDIRECT_THRESHOLD_DEG
    max_angle_deg: float = MAX_REDIRECT_DEG
    axis_threshold_deg: float = AXIS_THRESHOLD_DEG
    gain_range: tuple = GAIN_RANGE


@dataclass(frozen=True)
class MatchSettings:
    """Options of the search (the cost model is built from the candidates, see
    :func:`cost_model`)."""

    weights: dict = option(default_factory=dict, group="weights", kind="weights",
                           metavar="NAME=W,...",
                           help="weight per criterion, 0 to 10^6, default 1: "
                                "width,tilt,normal,axis,kmax,kmin,mass (com with --criteria paper)")
    criteria: tuple = option(DEFAULT_CRITERIA, group="cost", kind="choice",
                             choices={"default": DEFAULT_CRITERIA, "paper": PAPER_CRITERIA},
                             help="default: the paper's criteria with mass (the lever arm) for "
                                  "com; paper: the paper's seven")
    normalize: str = option("jnd", group="match", kind="choice", choices=("jnd", "range"),
                            help="jnd: differences in just-noticeable differences; range: the "
                                 "paper's scaling")
    pooling: str = option("quick", group="cost", kind="choice", choices=POOLINGS,
                          help="quick: probability summation of the criteria in JND; sum: the "
                               "paper's sum of squares")
    scan_trust: bool = option(False, group="cost", kind="flag",
                              help="weigh each pinch on a prop imported from a scan by how far "
                                   "the scan's error makes its features uncertain (off: on YCB "
                                   "scans it chose pinches that felt worse on the object; "
                                   "docs/scans.md)")
    top_k: int = option(3, group="match", kind="int",
                        help="distinct alternatives per virtual object")
    one_to_one: bool = option(False, group="assignment", kind="flag",
                              help="each tangible serves at most one virtual object")
    keep_upright: bool = option(False, group="match", kind="flag",
                                help="never turn a virtual object upside down")
    distinct_mm: float = option(8.0, group="match", kind="float",
                                help="alternatives differ by at least this much at a contact, on "
                                     "one object or both")
    block_rows: int = 2048  # rows of the blockwise search at a time: memory, never the result
    refine: bool = option(True, group="match", kind="onoff",
                          help="on: follow the best pairs on both surfaces past the sample until "
                               "the cost settles, "
                               "so that the answer does not hang on --seed; off: the best sampled "
                               "pair")
    landing_mm: float = option(5.0, group="match", kind="float",
                               help="each match says what it costs when a fingertip lands up to "
                                    "this far off its "
                                    "target, the pinch axis up to 14 degrees off (the headset "
                                    "allows 5; 0 to 20)")
    rank: str = option("expected", group="match", kind="choice", choices=RANKS,
                       help="what a match is ranked by: expected, its cost over where guided "
                            "fingers land (within "
                            "--landing-mm and 14 degrees: docs/matching.md); worst, its worst "
                            "landing (--robust is "
                            "the same); nominal, its cost with the fingers on their targets")
    placement: str = option("registered", group="placement", kind="choice", choices=PLACEMENTS,
                            help="registered: each virtual object is brought onto the prop; fixed: "
                                 "it stays where "
                                 "the level puts it and the hand is redirected to the prop, or, "
                                 "beyond "
                                 "--max-redirect-deg, the carousel brings it (docs/redirection.md)")
    hand_start_mm: tuple | None = option(None, group="placement", kind="vector",
                                         flag="--hand-start", metavar="X,Y,Z",
                                         help="with --placement fixed: where the hand rests before "
                                              "it reaches, mm in "
                                              "the level's frame (default: 150 mm above and 300 mm "
                                              "in front of each "
                                              "prop's pose: +Z in a y-up level, -Y in a z-up one)")
    redirect_threshold_deg: float = option(REDIRECT_THRESHOLD_DEG, group="placement", kind="float",
                                           help="the redirection angle that costs as much as one "
                                                "just-noticeable difference")
    max_redirect_deg: float = option(MAX_REDIRECT_DEG, group="placement", kind="float",
                                     help="with --placement fixed: the largest redirection angle "
                                          "seen from the "
                                          "hand's start; beyond it the carousel serves the object "
                                          "(the detection threshold of body warping)")
    axis_threshold_deg: float = option(AXIS_THRESHOLD_DEG, group="placement", kind="float",
                                       help="the turn of the pinch axis that costs as much as one "
                                            "just-noticeable difference")
    gain_range: tuple = option(GAIN_RANGE, group="placement", kind="vector", metavar="LOW,HIGH",
                               help="with --placement fixed: the reach gains a redirection may "
                                    "use, the virtual "
                                    "target's distance from the hand's start over the physical "
                                    "one's (HaRT's unnoticed gains)")
    carousel_margin_jnd: float = option(CAROUSEL_MARGIN_JND, group="placement", kind="float",
                                        help="with --placement fixed: an object stays in the "
                                             "level, the hand "
                                             "redirected, unless the carousel costs this many JND "
                                             "less (keeping the level intact is worth that much: "
                                             "docs/redirection.md)")
    user_mm: tuple | None = option(None, group="placement", kind="vector", flag="--user-at",
                                   metavar="X,Y,Z",
                                   help="where the user stands, mm in the level's frame (y up): a "
                                        "prop standing on a "
                                        "table is pinched from this side or from above (default: "
                                        "where the hand "
                                        "starts, in front (+Z) of each prop; docs/method.md)")
    rest_sink_mm_per_jnd: float = option(REST_SINK_MM_PER_JND, group="placement", kind="float",
                                         help="an object shown on a prop that stands on a table "
                                              "costs one JND per "
                                              "this many mm it sinks into the table beyond 2 mm "
                                              "(docs/matching.md)")
    rest_float_mm_per_jnd: float = option(REST_FLOAT_MM_PER_JND, group="placement", kind="float",
                                          help="an object shown on a prop that stands on a table "
                                               "costs one JND per "
                                               "this many mm it hovers above the table beyond 2 mm")

    def __post_init__(self):
        if tuple(self.criteria) not in (DEFAULT_CRITERIA, PAPER_CRITERIA):
            raise ConfigError(f"criteria: {self.criteria!r} is neither the default set "
                              f"({', '.join(DEFAULT_CRITERIA)}) "
                              f"nor the paper's ({', '.join(PAPER_CRITERIA)})")
        object.__setattr__(self, "criteria", tuple(self.criteria))
        object.__setattr__(self, "weights",
                           Weights(complete_weights(dict(self.weights), criteria=self.criteria)))
        if not isinstance(self.top_k, int) or isinstance(self.top_k, bool) or self.top_k < 0:
            raise ConfigError(f"--top-k: {self.top_k!r} must be a whole number of 0 or more")
        if not _finite(self.distinct_mm) or self.distinct_mm < 0:
            raise ConfigError(f"--distinct-mm: {self.distinct_mm!r} must be a distance of 0 mm or "
                              "more")
        if self.normalize not in ("jnd", "range"):
            raise ConfigError(f"--normalize: unknown mode {self.normalize!r}; use jnd or range")
        if not (_finite(self.landing_mm) and 0.0 <= self.landing_mm <= 20.0):
            raise ConfigError(f"--landing-mm: {self.landing_mm!r} must be from 0 to 20 mm (how far "
                              "off its target a fingertip may land; the headset allows 5)")
        if not isinstance(self.refine, bool):
            raise ConfigError(f"--refine: {self.refine!r} must be on or off")
        if self.rank not in RANKS:
            raise ConfigError(f"--rank: unknown ranking {self.rank!r}; use expected (the cost "
                              "where guided fingers land, the default), worst or nominal")
        if self.pooling not in POOLINGS:
            raise ConfigError(f"--pooling: unknown pooling {self.pooling!r}; use quick "
                              "(probability summation, "
                              "the default) or sum (the paper's sum of squares)")
        self._check_redirect()
        if self.user_mm is not None:
            object.__setattr__(self, "user_mm", _point("--user-at", self.user_mm))
        lo, hi = REST_RATE_RANGE_MM
        for name in ("rest_sink_mm_per_jnd", "rest_float_mm_per_jnd"):
            value = getattr(self, name)
            if not (_finite(value) and lo <= value <= hi):
                flag = "--" + name.replace("_", "-")
                raise ConfigError(f"{flag}: {value!r} must be from {lo:g} to {hi:g} mm per JND "
                                  "(how many mm of "
                                  "visible gap between a shown object and the table cost one "
                                  "just-noticeable difference)")

    def _check_redirect(self) -> None:
        if self.placement not in PLACEMENTS:
            raise ConfigError(f"--placement: unknown placement {self.placement!r}; use registered "
                              "(the virtual "
                              "object brought onto the prop) or fixed (it stays where the level "
                              "puts it)")
        if self.hand_start_mm is not None:
            object.__setattr__(self, "hand_start_mm", _point("--hand-start", self.hand_start_mm))
        try:
            gains = tuple(float(g) for g in self.gain_range)
        except (TypeError, ValueError, OverflowError):
            gains = ()
        if (len(gains) != 2 or not all(math.isfinite(g) for g in gains)
                or not 0.0 < gains[0] <= 1.0 <= gains[1] <= 10.0):
            raise ConfigError(f"--gain-range: {self.gain_range!r} must be two gains LOW,HIGH with "
                              "0 < LOW <= 1 <= HIGH <= 10 (HaRT's unnoticed gains are 0.94,1.14)")
        object.__setattr__(self, "gain_range", gains)
        if not (_finite(self.carousel_margin_jnd) and 0.0 <= self.carousel_margin_jnd <= 100.0):
            raise ConfigError(f"--carousel-margin-jnd: {self.carousel_margin_jnd!r} must be from 0 "
                              "to 100 JND")
        for name in ("redirect_threshold_deg", "max_redirect_deg", "axis_threshold_deg"):
            value = getattr(self, name)
            if not (_finite(value) and 0.0 < value <= MAX_THRESHOLD_DEG):
                flag = "--" + name.replace("_deg", "-deg").replace("_", "-")
                raise ConfigError(f"{flag}: {value!r} must be an angle above 0 and at most "
                                  f"{MAX_THRESHOLD_DEG:g} deg")

    @property
    def redirect(self) -> Redirect | None:
        """The redirection's settings under ``placement="fixed"``, else None."""
        if self.placement != "fixed":
            return None
        return Redirect(self.hand_start_mm, self.redirect_threshold_deg, self.max_redirect_deg,
                        self.axis_threshold_deg, self.gain_range)

    def as_dict(self) -> dict:
        return {
            "criteria": list(self.criteria),
            "weights": {c: self.weights[c] for c in self.criteria},
            "normalize": self.normalize,
            "pooling": self.pooling,
            "top_k": self.top_k,
            "one_to_one": self.one_to_one,
            "keep_upright": self.keep_upright,
            "distinct_mm": self.distinct_mm,
            "refine": self.refine,
            "landing_mm": self.landing_mm,
            "rank": self.rank,
            "placement": self.placement,
            "user_mm": None if self.user_mm is None else list(self.user_mm),
            "rest_sink_mm_per_jnd": self.rest_sink_mm_per_jnd,
            "rest_float_mm_per_jnd": self.rest_float_mm_per_jnd,
        } | ({} if self.placement != "fixed" else {
            "hand_start_mm": None if self.hand_start_mm is None else list(self.hand_start_mm),
            "redirect_threshold_deg": self.redirect_threshold_deg,
            "max_redirect_deg": self.max_redirect_deg,
            "axis_threshold_deg": self.axis_threshold_deg,
            "gain_range": list(self.gain_range),
            "carousel_margin_jnd": self.carousel_margin_jnd,
        })




def finite_number(value) -> bool:
    """A real number (not a bool, not text) that is finite as a float: an integer of hundreds of
    digits, as a file may hold, is not (it has no float)."""
    if not isinstance(value, numbers.Real) or isinstance(value, bool):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


_finite = finite_number


def _point(flag: str, value) -> tuple:
    """``value`` as a point (x, y, z) in mm within ``MAX_HAND_START_MM`` of the level's origin, or a
    one-line error naming ``flag``."""
    try:
        point = tuple(float(c) for c in value)
    except (TypeError, ValueError, OverflowError):
        point = ()
    if len(point) != 3 or not all(math.isfinite(c) and abs(c) <= MAX_HAND_START_MM for c in point):
        raise ConfigError(f"{flag}: {value!r} must be three numbers X,Y,Z in mm within "
                          f"{MAX_HAND_START_MM:g} mm of the level's origin")
    return point


@dataclass(frozen=True)
class Config:
    """The pinch settings and the match settings of a run, frozen.

    >>> Config().digest() == Config(PinchSettings(), MatchSettings()).digest()
    True
    >>> Config().digest() == Config(match=MatchSettings(top_k=2)).digest()
    False
    """

    pinch: PinchSettings = field(default_factory=PinchSettings)
    match: MatchSettings = field(default_factory=MatchSettings)

    def __post_init__(self):
        if not isinstance(self.pinch, PinchSettings) or not isinstance(self.match, MatchSettings):
            raise ConfigError("Config(pinch, match): give a PinchSettings and a MatchSettings")

    def digest(self) -> str:
        """SHA-256 of every field of both parts."""
        return digest(self)

    def replace(self, **changes) -> "Config":
        """A copy with fields of either part changed, by name (``count=300``, ``top_k=1``)."""
        names = {f.name for f in dataclasses.fields(PinchSettings)}
        pinch = {k: v for k, v in changes.items() if k in names}
        match = {k: v for k, v in changes.items() if k not in names}
        unknown = [k for k in match if k not in {f.name for f in dataclasses.fields(MatchSettings)}]
        if unknown:
            raise ConfigError(f"Config.replace: no setting named {unknown[0]!r}")
        return Config(dataclasses.replace(self.pinch, **pinch),
                      dataclasses.replace(self.match, **match))


def config_of(config: Config | None = None, *, settings: MatchSettings | None = None,
              pinch_settings: PinchSettings | None = None) -> Config:
    """``config``, or one made of the parts given (the others default)."""
    if config is not None:
        if settings is not None or pinch_settings is not None:
            raise ConfigError("give config, or settings and pinch_settings, not both")
        return config
    return Config(pinch_settings or PinchSettings(), settings or MatchSettings())
