"""Step #3: the one match (:func:`match_one`: one virtual object against the props under one
:class:`~pinchmatch.match.config.Config`), and a whole scene of them (:func:`match_scene`).

Each virtual object is searched on its own (:class:`pinchmatch.match.search.Search`, refined
unless ``refine`` is off: :mod:`pinchmatch.match.refine`), so a scene matched at once and one
matched an object at a time, as parallel runs do, give the same bits. With ``one_to_one`` the
assignment of least total cost (scipy's ``linear_sum_assignment``) decides which tangible each
object may use.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..errors import ConfigError
from ..grasp.pinches import PinchSettings
from .candidates import Candidates, one_grasp
from .cost import CostModel
from .felt import FeltTables
from .landing import LANDING_AXIS_DEG, Landing
from .reference import Reference, reference_pose
from .refine import refined_search
from .redirect import redirection
from ..config import Config, config_of
from ..grasp.spread import other_order
from .ranking import EQUIVALENT_JND, EQUIVALENT_SHARE, Ranking, rank
from .search import Choice, MatchSettings, Search, cost_model, cost_row
from .steady import SteadySearch, ranks_by_landings




@dataclass
class VirtualMatch:
    """The result for one virtual object.

    - ``virtual``: ``int``, its index in the scene's virtual objects; ``name``: ``str``, its name;
    - ``best``: the :class:`Choice` of least cost, or ``None`` (then ``reason``, a one-line ``str``,
      says why: no allowed registration, or every tangible taken under ``one_to_one``);
    - ``alternatives``: up to ``top_k`` further ``Choice`` s, by cost, none a near duplicate of an
      earlier one (both pinches within ``distinct_mm``);
    - ``reference``: the paper's Ref on the best choice's tangible pose (:class:`Reference`), or
      ``None`` without a best choice;
    - ``tangibles``, ``candidates``: the candidates its choices' pose indices point into: every
      tangible's and its own, with the poses refinement added (after the sampled ones);
    - ``landing``: the best choice's cost when the fingers land within ``landing_mm`` of its
      targets (:class:`pinchmatch.match.landing.Landing`), or ``None`` without a best choice;
    - ``redirection``: under ``placement="fixed"``, how the hand is led to the best choice
      (:meth:`pinchmatch.match.redirect.Redirection.record`: ``mode`` ``redirect``, or ``carousel``
      when no pair is within the redirection budget and the object is brought onto the prop,
      registered), else ``None``;
    - ``row``: ``(n,) float64``, its least exact cost on each tangible (inf where none is allowed),
      and ``row_noticed``: ``(n,) bool``, whether that least-cost choice is noticed at least half of
      the time;
    - ``equivalent``: ``[(tangible index, cost)]``, the other tangibles whose row cost is within
      ``EQUIVALENT_JND`` or ``EQUIVALENT_SHARE`` of the best's (:func:`equivalent_tangibles`), by
      cost.
    """

    virtual: int
    best: Choice | None
    alternatives: list
    reason: str | None = None
    reference: Reference | None = None
    name: str = ""
    tangibles: list | None = None
    candidates: Candidates | None = None
    landing: Landing | None = None
    redirection: dict | None = None
    row: np.ndarray | None = None
    row_noticed: np.ndarray | None = None
    equivalent: list | None = None


@dataclass
class SceneMatch:
    """Every virtual object matched against every tangible.

    - ``tangibles``, ``virtuals``: the ``n`` and ``m`` objects' :class:`Candidates`, in input order,
      as sampled (a match's own, refined, are on its :class:`VirtualMatch`: :meth:`objects`);
    - ``settings``: the :class:`MatchSettings` used; ``model``: the run's
      :class:`pinchmatch.match.cost.CostModel` (its scales, weights and criteria);
    - ``cost_matrix``: ``(m, n) float64``, dimensionless: the least exact cost of each virtual
      object on each tangible, inf where no registration is allowed;
    - ``matches``: ``m`` :class:`VirtualMatch` es, in the order of ``virtuals``.
    """

    tangibles: list
    virtuals: list
    settings: MatchSettings
    model: CostModel
    cost_matrix: np.ndarray
    matches: list
    config: Config | None = None

    def objects(self, vm: VirtualMatch) -> tuple[list, Candidates]:
        """The tangibles' and the virtual object's candidates that ``vm``'s choices index."""
        return (vm.tangibles if vm.tangibles is not None else self.tangibles,
                vm.candidates if vm.candidates is not None else self.virtuals[vm.virtual])


def match_one(tangibles: list[Candidates], virtual: Candidates, config: Config, *, model: CostModel,
              allowed: tuple[list[int], str | None] | None = None, index: int = 0,
              probes: dict | None = None, details: bool = True,
              search: Search | None = None) -> VirtualMatch:
    """One virtual object matched against the tangibles under one configuration: the one match.

    Every command and the library come here: :func:`match_scene` for each virtual object, the
    command line's tasks (local, Dask), ``demo``, ``select`` and ``design``. It searches (refined
    unless ``config.match.refine`` is off), picks the best choice and its alternatives among the
    ``allowed`` tangibles (:func:`allowed_tangibles`' entry; default every one), lands it, finds the
    paper's reference and, under ``placement="fixed"``, redirects the hand or hands the object to
    the carousel.

    ``model`` is the run's cost model (:func:`cost_model` over every object, so that runs in parts
    give the same bits); ``index`` the object's place in the scene; ``probes`` the memo of the
    reference's lines on this object (:func:`pinchmatch.match.reference.line_pinch`; read and added
    to); ``search`` its search when the caller already made it (a one-to-one scene's cost rows).
    With ``details`` off only the best choice, its alternatives and the cost row are made (no
    landing, reference or redirection): what ``select`` and ``design`` rank props by.

    Parameters
    ----------
    tangibles : list of Candidates
        The props' poses.
    virtual : Candidates
        The virtual object's poses.
    config : Config
        The run's pinch and match settings.
    model : CostModel
        The run's cost model.
    allowed : (list of int, str or None), optional
        The tangibles this object may use, and why none is left where none is.
    index : int
        The object's place in the scene.
    probes : dict, optional
        The memo of the reference's lines on this object.
    details : bool
        Make the landing, the reference and the redirection (off: the best, alternatives and row).
    search : Search, optional
        The object's search, when the caller already made it.

    Returns
    -------
    VirtualMatch
        The best choice, its alternatives, the cost row over the tangibles and what the details add.

    Examples
    --------
    >>> from pinchmatch import Config, PinchSettings, analyze_object, candidate_poses, cost_model
    >>> config = Config(PinchSettings(count=200, seed=0))
    >>> box = candidate_poses(analyze_object(box_stl), settings=config.pinch)
    >>> can = candidate_poses(analyze_object(can_obj, units="m"), settings=config.pinch)
    >>> vm = match_one([box, can], can, config, model=cost_model(config.match, [box, can]))
    >>> vm.best.tangible_name, round(vm.best.cost, 6), vm.row.shape
    ('can.obj', 0.0, (2,))
    """
    settings, pinch = config.match, config.pinch
    one_grasp([*tangibles, virtual])
    search = search or refined_search(tangibles, virtual, model, settings, pinch_settings=pinch)
    tables = FeltTables(settings.landing_mm, pinch)
    allowed = allowed or (list(range(len(tangibles))), None)
    count = settings.top_k + 1
    ranking = rank(search, steady_search(search, tangibles, virtual, pinch), tables, allowed[0],
                   count)
    row, noticed, carousel = ranking.row, ranking.noticed, None
    if settings.redirect is not None:  # each prop serves by redirection or by the carousel
        registered = dataclasses.replace(settings, placement="registered")
        served = refined_search(search.tangibles, search.virtuals[0], search.model, registered,
                                pinch_settings=pinch)
        carousel = (served, rank(served, steady_search(served, tangibles, virtual, pinch), tables,
                                 allowed[0], count))
        stays = redirect_stays(row, carousel[1].row, settings.carousel_margin_jnd)
        row = np.where(stays, row, carousel[1].row)
        noticed = np.where(stays, noticed, carousel[1].noticed)
    vm = _placed(search, ranking, allowed[1], pinch_settings=pinch, index=index, probes=probes,
                 carousel=carousel, details=details)
    return dataclasses.replace(vm, row=row, row_noticed=noticed,
                               equivalent=equivalent_tangibles(vm.best, row) if details else None)


def equivalent_tangibles(best: Choice | None, row: np.ndarray) -> list:
    """[(tangible index, cost)] of the tangibles other than the best choice's whose ranked cost in
    ``row`` is within ``EQUIVALENT_JND`` or ``EQUIVALENT_SHARE`` of the best's (whichever is
    larger), cheapest first, ties in the order the tangibles were given (the best itself is chosen
    the same way: :func:`~pinchmatch.match.ranking.rank`)."""
    if best is None:
        return []
    limit = best.cost + max(EQUIVALENT_JND, EQUIVALENT_SHARE * best.cost)
    near = [t for t in np.flatnonzero(np.isfinite(row) & (row <= limit)) if t != best.tangible]
    return [(int(t), float(row[t])) for t in sorted(near, key=lambda t: (row[t], t))]


def match_scene(tangibles: list[Candidates], virtuals: list[Candidates], *,
                config: Config | None = None, settings: MatchSettings | None = None,
                model: CostModel | None = None, pinch_settings: PinchSettings
                | None = None) -> SceneMatch:
    """For every virtual object, the best tangible, pose pair and registration, with alternatives.

    ``config`` (default :class:`Config`'s), or its parts ``settings`` and ``pinch_settings``;
    ``model`` defaults to :func:`cost_model` over all candidates. Each object is matched by
    :func:`match_one`.

    Parameters
    ----------
    tangibles, virtuals : list of Candidates
        The props' and the virtual objects' poses.
    config : Config, optional
        The run's settings (or its parts ``settings`` and ``pinch_settings``).
    settings : MatchSettings, optional
        The match settings, where ``config`` is not given.
    model : CostModel, optional
        The cost model (default: over every candidate).
    pinch_settings : PinchSettings, optional
        The pinch settings, where ``config`` is not given.

    Returns
    -------
    SceneMatch
        Every virtual object's match and the scene's cost matrix.

    Examples
    --------
    >>> from pinchmatch import MatchSettings, PinchSettings, analyze_object, candidate_poses
    >>> settings = PinchSettings(count=200, seed=0)
    >>> box = candidate_poses(analyze_object(box_stl), settings=settings)
    >>> can = candidate_poses(analyze_object(can_obj, units="m"), settings=settings)
    >>> scene = match_scene([box, can], [can], settings=MatchSettings(top_k=1))
    >>> best = scene.matches[0].best
    >>> # the can is best served by itself
    >>> best.tangible_name, round(best.cost, 6), scene.cost_matrix.shape
    ('can.obj', 0.0, (1, 2))
    >>> best.tangible_pose.p1_mm.shape  # each choice carries its pinches
    (3,)
    """
    config = config_of(config, settings=settings, pinch_settings=pinch_settings)
    if not tangibles:
        raise ConfigError("no tangible object given; name at least one with --tangible")
    if not virtuals:
        raise ConfigError("no virtual object given; name at least one with --virtual")
    one_grasp(tangibles + virtuals)
    model = model or cost_model(config.match, tangibles + virtuals)
    m, n = len(virtuals), len(tangibles)
    if config.match.one_to_one:  # the assignment needs every row first
        searches = [refined_search(tangibles, v, model, config.match, pinch_settings=config.pinch)
                    for v in virtuals]
        plan = allowed_tangibles(np.array([cost_row(s, 0) for s in searches]).reshape(m, n),
                                 config.match)
    else:
        searches, plan = [None] * m, [None] * m
    matches = [match_one(tangibles, v, config, model=model, allowed=plan[j], index=j,
                         search=searches[j])
               for j, v in enumerate(virtuals)]
    cost_matrix = np.array([vm.row for vm in matches]).reshape(m, n)
    return SceneMatch(tangibles, virtuals, config.match, model, cost_matrix, matches, config)


def allowed_tangibles(cost_matrix: np.ndarray,
                      settings: MatchSettings) -> list[tuple[list[int], str | None]]:
    """Per virtual object, the tangibles it may use and, when none, why: all of them, or the one
    ``--one-to-one`` assigns."""
    m, n = cost_matrix.shape
    if not settings.one_to_one:
        return [(list(range(n)), None)] * m
    assigned = assign_one_to_one(cost_matrix)
    return [([int(assigned[j])], None) if assigned[j] >= 0 else
            ([], "every tangible serves another virtual object (--one-to-one)"
             if np.isfinite(cost_matrix[j]).any() else "no upright registration on any tangible")
            for j in range(m)]


def steady_search(search: Search, tangibles: list[Candidates], virtual: Candidates,
                  pinch_settings: PinchSettings) -> SteadySearch | None:
    """The steady search beside ``search`` (over the sampled ``tangibles`` and ``virtual``), or None
    where the match ranks on target (``--rank nominal``, or a landing radius of 0)."""
    settings = search.settings
    if not ranks_by_landings(settings):
        return None
    return SteadySearch(search, tangibles, virtual, settings.landing_mm, pinch_settings)


def _match(search: Search, ranking: Ranking, reason: str | None, *,
           pinch_settings: PinchSettings, index: int = 0, probes: dict | None = None,
           details: bool = True) -> VirtualMatch:
    """The result of a one-virtual-object search, as the scene's virtual object ``index``: its best
    choice and alternatives, the answer of its ``ranking``; with ``details``, the reference and the
    landing of the best."""
    settings, virtual = search.settings, search.virtuals[0]
    felt = [(dataclasses.replace(p, virtual=index), f) for p, f in ranking.answer]
    picks = [p for p, _ in felt]
    if not picks and reason is None:
        reason = "no registration is allowed: every one flips the virtual object (--keep-upright)"
    best = picks[0] if picks else None
    if not details:  # what select and design rank props by: the best and the row
        return VirtualMatch(index, best, [], None if best else reason, None, virtual.name,
                            list(search.tangibles), virtual)
    ref = reference_pose(search.tangibles[best.tangible], best.t_pose, virtual, search.model,
                         settings=pinch_settings, memo=probes) if best else None
    landed = None
    if felt:
        f = felt[0][1]
        landed = Landing(settings.landing_mm, LANDING_AXIS_DEG, f.nominal, f.expected, f.worst,
                         f.p_noticed_worst, f.criteria_noticeable, f.landings, f.missed)
    return VirtualMatch(index, best, picks[1:], None if best else reason, ref, virtual.name,
                        list(search.tangibles), virtual, landed)


def _placed(search: Search, ranking: Ranking, reason: str | None, *,
            pinch_settings: PinchSettings, index: int = 0, probes: dict | None = None,
            carousel: tuple | None = None, details: bool = True) -> VirtualMatch:
    """The virtual object's match; under ``placement="fixed"`` with its redirection, or the
    carousel's (registered) match (``carousel``: its search and ranking) where no pair is within
    the redirection budget, or where the carousel costs more than ``carousel_margin_jnd`` less than
    the best redirected pair (:func:`redirect_stays`). The redirection's record gives both costs
    and the reason."""
    kw = dict(pinch_settings=pinch_settings, index=index, probes=probes, details=details)
    vm = _match(search, ranking, reason, **kw)
    settings = search.settings
    if carousel is None:
        return vm
    served = _match(*carousel, reason, **kw)
    mode, why = _mode(vm, served, settings.carousel_margin_jnd)
    costs = {"redirect_cost": None if vm.best is None else round(float(vm.best.cost), 6),
             "carousel_cost": None if served.best is None else round(float(served.best.cost), 6),
             "reason": why}
    if mode == "carousel":
        vm = served
    if vm.best is None or not details:
        return vm
    best = vm.best
    tangible = vm.tangibles[best.tangible]
    v_points = vm.candidates.pinches.points[best.v_pose]
    moved = redirection(tangible.obj, tangible.pinches.points[best.t_pose][None],
                        (v_points[other_order(len(v_points))] if best.swapped else v_points)[None],
                        settings.redirect)
    return dataclasses.replace(vm, redirection=moved.record(0, mode) | costs)


def redirect_stays(redirect_cost, carousel_cost, margin: float):
    """Whether an object stays in the level, the hand redirected (per element of the costs, or one
    bool): the one rule of ``--placement fixed``. It stays when a redirected pair exists (a finite
    cost) costing at most ``margin`` more than the carousel's (infinite where the carousel has no
    placement)."""
    r, c = np.asarray(redirect_cost, dtype=np.float64), np.asarray(carousel_cost, dtype=np.float64)
    return np.isfinite(r) & (r <= c + margin)


def _mode(redirected: VirtualMatch, carousel: VirtualMatch, margin: float) -> tuple[str, str]:
    """``redirect`` or ``carousel`` (:func:`redirect_stays`) and why."""
    a = float(redirected.best.cost) if redirected.best is not None else np.inf
    b = float(carousel.best.cost) if carousel.best is not None else np.inf
    if not redirect_stays(a, b, margin):
        if redirected.best is None:
            return ("carousel",
                    "no pose pair is within the redirection budget (angle and reach gain)")
        return ("carousel",
                f"the carousel costs {b:.3g}, more than {margin:g} below redirecting's {a:.3g}")
    if carousel.best is None:
        return "redirect", "the carousel has no allowed placement"
    return "redirect", f"redirecting costs {a:.3g}, within {margin:g} of the carousel's {b:.3g}"


def match_virtual(tangibles: list[Candidates], virtual: Candidates, *,
                  model: CostModel | None = None, config: Config | None = None,
                  settings: MatchSettings | None = None, allowed: tuple[list[int], str | None]
                  | None = None, pinch_settings: PinchSettings | None = None,
                  probes: dict | None = None) -> SceneMatch:
    """One virtual object's row of :func:`match_scene`, bit for bit, as a one-row scene
    (:func:`match_one`).

    ``model`` must be the run's to match the scene's row (built over every object; default: over
    these objects only); ``config`` (or ``settings`` and ``pinch_settings``) default as in
    :func:`match_scene`; ``allowed`` is its entry of :func:`allowed_tangibles` (default: every
    tangible, which is right unless ``one_to_one``); ``probes`` as for :func:`match_one`.

    Parameters
    ----------
    tangibles : list of Candidates
        The props' poses.
    virtual : Candidates
        The virtual object's poses.
    model : CostModel, optional
        The run's cost model (default: over these objects).
    config : Config, optional
        The run's settings (or ``settings`` and ``pinch_settings``).
    settings : MatchSettings, optional
        The match settings, where ``config`` is not given.
    allowed : (list of int, str or None), optional
        The tangibles this object may use.
    pinch_settings : PinchSettings, optional
        The pinch settings, where ``config`` is not given.
    probes : dict, optional
        The memo of the reference's lines on this object.

    Returns
    -------
    SceneMatch
        A scene of this one object.

    Examples
    --------
    >>> from pinchmatch import PinchSettings, analyze_object, candidate_poses
    >>> settings = PinchSettings(count=200, seed=0)
    >>> box = candidate_poses(analyze_object(box_stl), settings=settings)
    >>> can = candidate_poses(analyze_object(can_obj, units="m"), settings=settings)
    >>> scene = match_scene([box, can], [can])
    >>> one = match_virtual([box, can], can, model=scene.model)  # the scene's row, on its own
    >>> one.matches[0].best.cost == scene.matches[0].best.cost
    True
    """
    config = config_of(config, settings=settings, pinch_settings=pinch_settings)
    model = model or cost_model(config.match, tangibles + [virtual])
    vm = match_one(tangibles, virtual, config, model=model, allowed=allowed, probes=probes)
    return SceneMatch(tangibles, [virtual], config.match, model, vm.row[None], [vm], config)


def assign_one_to_one(cost_matrix: np.ndarray) -> np.ndarray:
    """(m,) tangible of each virtual object, -1 for none: the assignment of least total cost in
    which each tangible serves at most one virtual object and as many as possible are served.

    Pairs with no allowed registration (inf) are never assigned.
    """
    m, n = cost_matrix.shape
    finite = np.isfinite(cost_matrix)
    out = np.full(m, -1, dtype=np.int64)
    if not finite.any():
        return out
    # serve as many as possible first, then least cost: a forbidden pair costs more than any full
    # set
    big = (np.abs(cost_matrix[finite]).sum() + 1.0) * (min(m, n) + 1)
    rows, cols = linear_sum_assignment(np.where(finite, cost_matrix, big))
    for r, c in zip(rows, cols):
        if finite[r, c]:
            out[r] = c
    return out
