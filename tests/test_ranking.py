"""The one ranking of a match: every choice felt once, the row and the answer read from one list.

Two props off the origin, each turned about two axes, a can standing in a y-up level; registered
and fixed placement, every prop allowed or one. The felt costs are recomputed here from fresh
landing tables, over the sets the ranking documents, and the row and the answer are checked against
them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pinchmatch import Config, PinchSettings, analyze_spec, candidate_poses, cost_model
from pinchmatch.config import MatchSettings
from pinchmatch.match import ranking
from pinchmatch.match.choice import pinch_distance
from pinchmatch.match.felt import FeltTables, felt_cost
from pinchmatch.match.refine import refined_search
from pinchmatch.match.scene import match_one, redirect_stays, steady_search
from pinchmatch.mesh.manifest import object_specs

from levels import standing_can, tabletop_level

PINCH = PinchSettings(count=60, seed=2)


@pytest.fixture(scope="module")
def objects(tmp_path_factory):
    """Two props, a cylinder and a box, off the origin and turned about two axes, and a can in a
    level; their candidates."""
    folder = tmp_path_factory.mktemp("ranking")
    tabletop_level(folder / "level.glb", [("can", standing_can(), (0.16, 0.0, -0.06))])
    turns = [Rotation.from_euler("yx", [35, -90], degrees=True),
             Rotation.from_euler("zy", [20, -50], degrees=True)]
    (folder / "props.toml").write_text(
        '[[object]]\nname = "cylinder"\n'
        'shape = { kind = "cylinder", diameter_mm = 50, height_mm = 80 }\nmass_g = 150\n'
        f"pose = {{ position_mm = [120, 40, -80], quaternion_xyzw = "
        f"{turns[0].as_quat().tolist()} }}\n"
        '[[object]]\nname = "block"\nshape = { kind = "box", size_mm = [60, 45, 30] }\n'
        f"mass_g = 90\npose = {{ position_mm = [-210, 30, 95], quaternion_xyzw = "
        f"{turns[1].as_quat().tolist()} }}\n")
    props = [candidate_poses(analyze_spec(s), settings=PINCH)
             for s in object_specs([folder / "props.toml"], option="--tangible")]
    (can,) = [candidate_poses(analyze_spec(s), settings=PINCH)
              for s in object_specs([folder / "level.glb"], option="--virtual", split="nodes")]
    return props, can


def _felt_by_hand(search, steady, allowed, count):
    """Every pick of the documented sets, felt from fresh tables: {key: (cost, p_noticed, cost on
    target)}."""
    tables = FeltTables(search.settings.landing_mm, PINCH)
    nominal = max(count, ranking.ranked_choices(PINCH.count))
    picks = search.choices(0, allowed, nominal) + steady.choices(allowed, max(count, 32))
    for t in range(len(search.tangibles)):
        if np.isfinite(search.best_cost(0, t)):
            picks += search.choices(0, [t], 3) + steady.choices([t], 3)
    out = {}
    for p in picks:
        felt = felt_cost(search.tangibles[p.tangible], search.virtuals[0], p, search.model, tables)
        out[(p.tangible, p.t_pose, p.v_pose, p.swapped)] = (
            felt.ranked(search.settings.rank), felt.ranked_p_noticed(search.settings.rank),
            p.cost_nominal)
    return out


@pytest.mark.parametrize("placement", ["registered", "fixed"])
@pytest.mark.parametrize("allowed", [[0, 1], [0], [1]])
def test_the_row_and_the_answer_come_from_one_felt_list(objects, placement, allowed):
    props, can = objects
    settings = MatchSettings(placement=placement, refine=False, top_k=4, max_redirect_deg=90.0)
    model = cost_model(settings, [*props, can])
    search = refined_search(props, can, model, settings, pinch_settings=PINCH)
    steady = steady_search(search, props, can, PINCH)
    count = settings.top_k + 1
    got = ranking.rank(search, steady, FeltTables(settings.landing_mm, PINCH), allowed, count)
    felt = _felt_by_hand(search, steady, allowed, count)
    # the row: each prop's first choice in the answer's order, over every prop whatever is allowed
    least = min(c for c, _, _ in felt.values())
    band = least + max(ranking.EQUIVALENT_JND, ranking.EQUIVALENT_SHARE * least)
    for t in range(len(props)):
        mine = [(c, n, k[1], k[2], p) for k, (c, p, n) in felt.items() if k[0] == t]
        if not mine:
            assert got.row[t] == np.inf and got.noticed[t]
            continue
        cost, _, _, _, p = min(mine)
        if cost > band:  # nothing of it among the equivalent: its cheapest
            assert got.row[t] == cost and got.noticed[t] == (p >= 0.5)
        else:  # one of its choices within the band
            assert any(got.row[t] == c and got.noticed[t] == (q >= 0.5) for c, _, _, _, q in mine)
            assert cost <= got.row[t] <= band + 1e-12
    # the answer: on the allowed props, each as felt, never below its prop's row, distinct
    if not np.isfinite(got.row[allowed]).any():  # the block is out of the redirection's reach
        assert got.answer == [] and placement == "fixed"
        return
    assert 1 <= len(got.answer) <= count
    best = got.answer[0][0]
    assert got.row[best.tangible] == best.cost
    if got.row[allowed].min() == got.row.min():  # the best prop is allowed
        assert least <= best.cost <= band + 1e-12
    for choice, _ in got.answer:
        key = (choice.tangible, choice.t_pose, choice.v_pose, choice.swapped)
        assert choice.tangible in allowed and felt[key][0] == choice.cost
    # the band first (in comfort order), then the rest by cost
    inside = [c.cost <= band + 1e-12 for c, _ in got.answer]
    assert inside == sorted(inside, reverse=True)
    beyond = [c.cost for c, _ in got.answer if c.cost > band + 1e-12]
    assert beyond == sorted(beyond)
    for i, (a, _) in enumerate(got.answer):
        for b, _ in got.answer[:i]:
            same = a.tangible == b.tangible and all(
                pinch_distance(x.contacts_mm[None], y.contacts_mm)[0] < settings.distinct_mm
                for x, y in ((a.tangible_pose, b.tangible_pose),
                             (a.virtual_pose, b.virtual_pose)))
            assert not same


@pytest.mark.parametrize("placement", ["registered", "fixed"])
def test_the_match_its_row_and_the_props_ranking_agree(objects, placement):
    """The match's best is the one ``select`` and ``design`` read (details off), at the cost the
    row gives its prop, at most the equivalence band above the cheapest prop's; under fixed
    placement the row takes, per prop, the redirected or the carousel's cost by the one rule."""
    props, can = objects
    config = Config(PINCH, MatchSettings(placement=placement, refine=False, top_k=3,
                                         max_redirect_deg=90.0))
    model = cost_model(config.match, [*props, can])
    full = match_one(props, can, config, model=model)
    bare = match_one(props, can, config, model=model, details=False)
    key = (full.best.tangible, full.best.t_pose, full.best.v_pose, full.best.swapped)
    assert (bare.best.tangible, bare.best.t_pose, bare.best.v_pose, bare.best.swapped) == key
    assert bare.best.cost == full.best.cost
    np.testing.assert_array_equal(bare.row, full.row)
    assert full.row[full.best.tangible] == full.best.cost
    assert full.row.min() >= full.best.cost - max(0.1, 0.05 * full.row.min()) - 1e-12
    if placement == "fixed":
        registered = dataclasses.replace(config.match, placement="registered")
        served = refined_search(props, can, model, registered, pinch_settings=PINCH)
        carousel = ranking.rank(served, steady_search(served, props, can, PINCH),
                                FeltTables(config.match.landing_mm, PINCH), [0, 1], 4)
        fixed = refined_search(props, can, model, config.match, pinch_settings=PINCH)
        redirected = ranking.rank(fixed, steady_search(fixed, props, can, PINCH),
                                  FeltTables(config.match.landing_mm, PINCH), [0, 1], 4)
        stays = redirect_stays(redirected.row, carousel.row, config.match.carousel_margin_jnd)
        np.testing.assert_array_equal(full.row, np.where(stays, redirected.row, carousel.row))
        assert full.redirection["mode"] in ("redirect", "carousel")
