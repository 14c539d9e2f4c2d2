import numpy as np
import pytest

from pinchmatch import ConfigError
from pinchmatch.match.cost import (CRITERIA, CostModel, contributions, feature_ranges, pair_costs,
                                   parse_weights, pooled_bound_blocks)


def random_table(n, seed):
    rng = np.random.default_rng(seed)
    t = np.empty((n, 2, 9))
    t[:, :, 0] = rng.uniform(5, 80, n)[:, None]          # width
    t[:, :, 1] = rng.uniform(0, 60, n)[:, None]          # com distance
    t[:, :, 2] = rng.uniform(0, 90, n)[:, None]          # tilt
    t[:, :, 3] = rng.uniform(0, 30, (n, 2))              # normal angle
    t[:, :, 4] = rng.uniform(0, 90, (n, 2))              # curvature axis angle
    t[:, :, 4][rng.random((n, 2)) < 0.3] = np.nan       # undefined rho
    t[:, :, 5] = rng.uniform(0, 100, (n, 2))             # kappa max
    t[:, :, 6] = t[:, :, 5] - rng.uniform(0, 100, (n, 2))
    along = rng.uniform(-40, 40, n)
    # mass offset along the line, seen from each finger
    t[:, 0, 7], t[:, 1, 7] = along, -along
    t[:, :, 8] = rng.uniform(0, 60, n)[:, None]          # mass lever arm
    return t


def brute_force(tang, virt, model):
    cost = np.empty((len(tang), len(virt)))
    for i, t in enumerate(tang):
        for j, v in enumerate(virt):
            w = model.weights
            c = [sum(w[k] * x for k, x in contributions(t, v, model, swapped=s).items())
                 for s in (False, True)]
            cost[i, j] = min(c)
    return cost


@pytest.mark.parametrize("mode", ["jnd", "range"])
def test_blockwise_costs_equal_brute_force(mode):
    tang, virt = random_table(23, 1), random_table(17, 2)
    model = CostModel(weights=dict(zip(CRITERIA, [1, 0.5, 2, 1, 1, 3, 1, 2])), normalize=mode,
                      ranges=feature_ranges(tang, virt), criteria=CRITERIA, pooling="sum")
    cost, _ = pair_costs(tang, virt, model, block_rows=5)
    np.testing.assert_allclose(cost, brute_force(tang, virt, model), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("pooling", ["quick", "sum"])
def test_the_pooled_bound_pools_each_criterion_in_the_better_finger_order(pooling):
    """Blockwise, each pair's bound is the model's pooling of its separable contributions (``mass``
    at its lower bound), the cheaper of the two finger orders."""
    tang, virt = random_table(23, 5), random_table(17, 6)
    model = CostModel(weights=dict(zip(CRITERIA, [1, 0.5, 2, 1, 1, 3, 1, 2])), criteria=CRITERIA,
                      pooling=pooling)
    bound = np.concatenate([b for _, b in pooled_bound_blocks(tang, virt, model, block_rows=5)])
    each = np.array([[[model.pool(np.array(list(contributions(t, v, model, swapped=s).values())))
                       for s in (False, True)] for v in virt] for t in tang])
    first_wins = each[..., 0] < each[..., 1] * (1 - 1e-3)
    assert 0.2 < first_wins.mean() < 0.8  # each order is the better one for many pairs
    np.testing.assert_allclose(bound, each.min(axis=-1), rtol=1e-9, atol=1e-9)


def test_a_pose_against_itself_costs_nothing_in_either_finger_order():
    t = random_table(40, 3)
    cost, _ = pair_costs(t, t, CostModel())
    np.testing.assert_allclose(np.diag(cost), 0.0, atol=1e-9)
    cost_swapped, swapped = pair_costs(t, t[:, ::-1], CostModel())
    np.testing.assert_allclose(np.diag(cost_swapped), 0.0, atol=1e-9)
    np.testing.assert_allclose(cost_swapped, cost, atol=1e-9)  # swapping p1 and p2 changes no cost


def test_one_jnd_of_width_contributes_one():
    t = random_table(1, 4)[0]
    v = t.copy()
    v[:, 0] = t[:, 0] * (1 + 0.0575)
    c = contributions(t, v, CostModel(), swapped=False)
    assert c["width"] == pytest.approx(1.0)
    assert all(c[k] == 0 for k in CRITERIA if k != "width")


def test_weights_are_parsed_and_checked():
    assert parse_weights("width=2, kmax=0")["width"] == 2.0
    with pytest.raises(ConfigError, match="unknown criterion 'widht'; did you mean 'width'"):
        parse_weights("widht=1")
    with pytest.raises(ConfigError, match="needs a weight of 0 or more"):
        parse_weights("width=-1")
    with pytest.raises(ConfigError, match="unknown mode 'zscore'"):
        CostModel(normalize="zscore")


def test_a_feature_constant_over_the_run_contributes_nothing_in_range_mode():
    t = random_table(30, 5)
    t[:, :, 2] = 0.0  # every pinch horizontal: tilt 0 everywhere
    v = t.copy()
    v[:, :, 2] = 1e-9  # round-off
    model = CostModel(normalize="range", ranges=feature_ranges(t))
    assert model.ranges[2] == 0.0
    cost, _ = pair_costs(t, v, model)
    assert np.isfinite(cost).all()
    np.testing.assert_allclose(np.diag(cost), 0.0, atol=1e-9)
    assert contributions(t[0], v[0], model, swapped=False)["tilt"] == 0.0


def test_jnd_scales_are_the_perception_data_as_literals():
    """Each criterion's just-noticeable difference, for tangible values above and below its floor,
    written out from shared/paper/perception.md (not from the code's constants)."""
    from pinchmatch.match.cost import CostModel

    model = CostModel(dict.fromkeys(CRITERIA, 1.0), "jnd", None, CRITERIA)
    # columns: width, com, tilt, normal angle, axis angle, kmax, kmin, mass along the line, mass
    # lever arm
    above = np.array([[40.0, 12.0, 60.0, 50.0, 70.0, 50.0, 30.0, 60.0, 80.0]])
    below = np.array([[5.0, 0.0, 10.0, 0.0, 30.0, 1.0, 0.0, 3.0, 4.0]])
    np.testing.assert_allclose(model.scales(above)[0],
                               [2.3, 20.0, 26.28, 21.9, 30.66, 33.33, 19.998, 22.0, 22.0],
                               rtol=1e-3)
    np.testing.assert_allclose(model.scales(below)[0],
                               [0.4, 20.0, 20.0, 20.0, 20.0, 2.0, 2.0, 20.0, 20.0], rtol=1e-9)


def test_range_mode_spans_every_object_and_the_mass_columns_share_the_offset_length():
    nan = np.nan
    # columns: width, com, tilt, normal angle, axis angle, kmax, kmin, mass along the line, mass
    # lever arm
    first = np.array([[[30.0, 5.0, 10.0, 20.0, 40.0, 50.0, 10.0, 3.0, 4.0],      # offset 5
                       [30.0, 5.0, 10.0, 30.0, nan, 60.0, -5.0, -6.0, 8.0]]])    # offset 10
    second = np.array([[[70.0, -15.0, 0.0, 10.0, 80.0, 20.0, 0.0, 0.0, 0.0]] * 2])  # offset 0
    np.testing.assert_array_equal(feature_ranges(first, second),
                                  [40.0, 20.0, 10.0, 20.0, 40.0, 40.0, 15.0, 10.0, 10.0])
    axis_never_defined = first.copy()
    axis_never_defined[:, :, 4] = nan
    assert np.isnan(feature_ranges(axis_never_defined)[4])


def test_each_column_counts_towards_its_own_criterion():
    # one pose against itself but for one column: only that column's criterion contributes
    from pinchmatch.match.cost import COLUMNS

    model = CostModel(dict.fromkeys(CRITERIA, 1.0), "jnd", None, CRITERIA)
    base = np.array([[40.0, 12.0, 60.0, 50.0, 70.0, 50.0, 30.0, 60.0, 80.0]] * 2)
    owner = ["width", "com", "tilt", "normal", "axis", "kmax", "kmin", "mass", "mass"]
    assert list(COLUMNS) == ["width", "com", "tilt", "normal", "axis", "kmax", "kmin", "mass_along",
                             "mass_perp"]
    for k, criterion in enumerate(owner):
        other = base.copy()
        other[:, k] += 5.0
        terms = contributions(base, other, model, swapped=False)
        assert [c for c, v in terms.items() if v > 0] == [criterion], (k, terms)


def test_the_feature_table_lays_out_pose_and_patch_features():
    from pinchmatch.grasp.features import PinchFeatures
    from pinchmatch.match.cost import feature_table

    f = PinchFeatures(width_mm=np.array([40.0]), com_distance_mm=np.array([12.0]),
                      tilt_deg=np.array([60.0]), normal_angle_deg=np.array([[5.0, 6.0]]),
                      curvature_axis_angle_deg=np.array([[70.0, np.nan]]),
                      kappa_max_per_m=np.array([[50.0, 51.0]]),
                      kappa_min_per_m=np.array([[30.0, 31.0]]),
                      mass_along_mm=np.array([[7.0, -7.0]]), mass_perp_mm=np.array([9.0]))
    np.testing.assert_array_equal(feature_table(f), [[[40, 12, 60, 5, 70, 50, 30, 7, 9],
                                                       [40, 12, 60, 6, np.nan, 51, 31, -7, 9]]])


def test_weights_default_to_one_for_criteria_in_use_and_zero_for_the_rest():
    from pinchmatch.match.cost import PAPER_CRITERIA, complete_weights

    # mass carries the lever arm
    assert complete_weights({}) == {**dict.fromkeys(CRITERIA, 1.0), "com": 0.0}
    with pytest.raises(ConfigError, match="not part of --criteria default"):
        complete_weights({"com": 1})
    paper = complete_weights({"width": 2.0}, criteria=PAPER_CRITERIA)
    assert paper == {**dict.fromkeys(PAPER_CRITERIA, 1.0), "width": 2.0, "mass": 0.0}
    # off, though not in use
    assert complete_weights({"mass": 0}, criteria=PAPER_CRITERIA)["mass"] == 0.0
    with pytest.raises(ConfigError, match="not part of --criteria paper"):
        complete_weights({"mass": 1}, criteria=PAPER_CRITERIA)
    assert complete_weights({"width": 0.0})["width"] == 0.0
    model = CostModel(complete_weights({"mass": 0.0}), "jnd", None, CRITERIA)
    assert model.weights["mass"] == 0.0


def test_a_model_fills_in_zero_for_unnamed_criteria_and_uses_mass_only_when_weighted():
    model = CostModel({"width": 2.0}, "jnd", None, ("width",))
    assert model.weights == {**dict.fromkeys(CRITERIA, 0.0), "width": 2.0}
    assert not model.uses_mass
    with pytest.raises(TypeError):
        model.weights["width"] = 3.0  # a frozen record's weights stay as made
    assert not CostModel({"mass": 0.0, "width": 1.0}).uses_mass
    assert CostModel({"mass": 0.5}).uses_mass


def test_the_mass_term_is_the_squared_offset_mismatch_over_the_squared_jnd():
    from pinchmatch.match.cost import mass_term

    model = CostModel(dict.fromkeys(CRITERIA, 1.0), "jnd", None, CRITERIA)
    # tangible offsets (along, lever arm) (30, 40): |o| = 50 mm, below 20 / 0.22, so s = 20 mm;
    # (300, 400): |o| = 500 mm, s = 0.22 x 500 = 110 mm
    rows = np.zeros((2, 2, 9))
    rows[0, :, 7:] = [30.0, 40.0]
    rows[1, :, 7:] = [300.0, 400.0]
    delta = np.array([[10.0, 0.0, 0.0], [0.0, 55.0, 0.0]])
    np.testing.assert_allclose(mass_term(rows, delta, model), [100.0 / 400.0, 55.0**2 / 110.0**2],
                               rtol=1e-12)


def test_a_felt_table_scales_both_mass_columns_and_nothing_else():
    from pinchmatch.match.candidates import felt_table

    table = np.arange(2 * 2 * 9, dtype=float).reshape(2, 2, 9) + 1.0
    twice = felt_table(table, 2.0)
    np.testing.assert_array_equal(twice[..., 7:], 2.0 * table[..., 7:])
    np.testing.assert_array_equal(twice[..., :7], table[..., :7])
    assert felt_table(table, 1.0) is table


def test_a_model_completes_omitted_weights_and_refuses_unknown_or_negative_ones():
    model = CostModel(weights={"width": 2})
    assert model.weights == {**dict.fromkeys(CRITERIA, 1.0), "com": 0.0, "width": 2.0}
    with pytest.raises(ConfigError, match="unknown criterion 'grip'"):
        CostModel(weights={"grip": 1.0})
    with pytest.raises(ConfigError, match="needs a weight of 0 or more"):
        CostModel(weights={"width": -1.0})


def test_quick_pooling_is_probability_summation_of_weibull_detections():
    model = CostModel(weights={"width": 2.0})
    terms = np.zeros((3, 8))
    terms[0, 0] = 1.0  # 1 JND of width, weight 2
    terms[1, [3, 5]] = [0.25, 4.0]  # 0.5 JND of normal, 2 JND of kmax
    terms[2, 2] = 1.0  # 1 JND of tilt alone: noticed half of the time
    expected = np.array([2.0, 0.5 ** 3.5 + 2.0 ** 3.5, 1.0]) ** (1 / 3.5)
    cost = model.pool(terms)
    np.testing.assert_allclose(cost, expected, rtol=1e-12)
    # P = 1 - prod over criteria (1 - P_c), P_c = 1 - 2^(-w x^3.5)
    p_c = 1.0 - 2.0 ** -(np.array([2.0, 1, 1, 1, 1, 1, 1])
                         * np.sqrt(terms[:, [0, 2, 3, 4, 5, 6, 7]]) ** 3.5)
    np.testing.assert_allclose(model.p_noticed(cost), 1.0 - np.prod(1.0 - p_c, axis=1), rtol=1e-12)
    assert model.p_noticed(1.0) == pytest.approx(0.5)
    # one large difference is not outweighed by several small ones, unlike the sum of squares
    many_small, one_large = np.zeros(8), np.zeros(8)
    many_small[[0, 2, 3, 4, 5, 6]] = 0.8 ** 2
    one_large[5] = 1.5 ** 2
    assert model.pool(one_large) > model.pool(many_small)
    summed = CostModel(pooling="sum")
    assert summed.pool(one_large) < summed.pool(many_small)


@pytest.mark.parametrize("pooling", ["quick", "sum"])
def test_the_bound_from_the_separable_sum_never_exceeds_the_pooled_cost(pooling):
    rng = np.random.default_rng(7)
    model = CostModel(weights={"width": 2.0, "kmax": 0.5, "mass": 3.0}, pooling=pooling)
    terms = rng.exponential(1.0, (5000, 8)) * (rng.random((5000, 8)) < 0.6)
    separable = terms @ model.weight_vector()
    assert (model.bound_from_separable(separable) <= model.pool(terms) * (1 + 1e-12)).all()
    one = np.zeros((1, 8))
    one[0, 0] = 1.0  # equal differences everywhere make the bound tight
    equal = np.where(model.weight_vector() > 0, 1.0, 0.0)[None]
    np.testing.assert_allclose(model.bound_from_separable(equal @ model.weight_vector()),
                               model.pool(equal))


def test_a_concave_patch_scales_by_its_curvature_s_size_not_its_sign():
    table = np.zeros((2, 2, 9))
    table[:, :, 0] = 40.0
    table[0, :, 5], table[1, :, 5] = 30.0, -30.0  # kmax of a convex and of a concave patch, per m
    s = CostModel().scales(table)
    assert s[0, 0, 5] == s[1, 0, 5] == pytest.approx(0.6666 * 30.0)


def test_the_pooled_bound_of_identical_rows_is_zero_not_the_round_offs_nan():
    """A table against itself: every matched entry differs by 0, which the blockwise expansion
    |t|² - 2 t·v + |v|² leaves a few ulps either side of 0. The bound pools those parts with a
    power of 1.75 (quick): clipped, it is 0 and finite; a negative part would make it NaN."""
    table = random_table(60, 11)
    table[:, :, 4] = 30.0  # every ρ defined, so that each pose matches itself in every column
    model = CostModel(weights=dict.fromkeys(CRITERIA, 1.0), criteria=CRITERIA, pooling="quick")
    bound = np.concatenate([b for _, b in pooled_bound_blocks(table, table, model, block_rows=7)])
    assert np.isfinite(bound).all() and (bound >= 0).all()
    np.testing.assert_allclose(np.diag(bound), 0.0, atol=1e-6)


def test_contributions_take_the_mass_offset_as_any_sequence():
    t, v = random_table(2, 12)
    model = CostModel(criteria=CRITERIA)
    as_array = contributions(t, v, model, swapped=False, mass_delta_mm=np.array([3.0, -4.0, 12.0]))
    assert contributions(t, v, model, swapped=False, mass_delta_mm=(3.0, -4.0, 12.0)) == as_array
    assert contributions(t, v, model, swapped=False, mass_delta_mm=[3, -4, 12]) == as_array


def _tripod_table(n, seed):
    """Feature tables of n tripods as feature_table makes them: the aperture in the thumb's row and
    the spacing in both fingers', the com distance, tilt and lever arm in every row, 0 across the
    grasp; ρ undefined at random."""
    rng = np.random.default_rng(seed)
    t = np.empty((n, 3, 9))
    t[:, 0, 0] = rng.uniform(10, 80, n)
    t[:, 1:, 0] = rng.uniform(16, 45, n)[:, None]
    t[:, :, 1] = rng.uniform(0, 60, n)[:, None]
    t[:, :, 2] = rng.uniform(0, 90, n)[:, None]
    t[:, :, 3] = rng.uniform(0, 30, (n, 3))
    t[:, :, 4] = rng.uniform(0, 90, (n, 3))
    t[:, :, 4][rng.random((n, 3)) < 0.3] = np.nan
    t[:, :, 5] = rng.uniform(0, 100, (n, 3))
    t[:, :, 6] = t[:, :, 5] - rng.uniform(0, 100, (n, 3))
    t[:, :, 7] = rng.uniform(0, 90, n)[:, None]
    t[:, :, 8] = 0.0
    return t


def test_tripod_pairs_cost_the_written_out_sum_in_the_better_order_of_the_fingers():
    """The blockwise pass and the pooled bound over tripod tables (three rows, index and middle in
    either order) against each pair's sum written out entry by entry; the lever arm's scale is the
    torque JND."""
    from pinchmatch.match.cost import distinct_entries

    T, V = _tripod_table(9, 1), _tripod_table(7, 2)
    model = CostModel(dict.fromkeys(CRITERIA, 1.0), "jnd", None, CRITERIA)
    s = model.scales(T)
    np.testing.assert_allclose(s[:, :, 7], np.maximum(0.127 * T[:, :, 7], 20.0))
    np.testing.assert_allclose(s[:, 0, 0], np.maximum(0.0575 * T[:, 0, 0], 0.4), rtol=1e-9)
    w = model.column_weights(3)  # (3, 9): every entry a third of its criterion's weight
    np.testing.assert_allclose(w, np.broadcast_to(model.column_weights(2)[0] * 2 / 3, (3, 9)))
    want = np.empty((9, 7))
    for i in range(9):
        for j in range(7):
            orders = []
            for vv in (V[j], V[j][[0, 2, 1]]):
                z = w * ((vv - T[i]) / s[i]) ** 2
                orders.append(float(np.nansum(z)))
            want[i, j] = min(orders)
    got, swapped = pair_costs(T, V, model)
    np.testing.assert_allclose(got, want, rtol=1e-12)
    assert swapped.any() and not swapped.all()
    keep, repeats = distinct_entries(3)
    # 27 entries less the three across the grasp (always 0)
    assert len(keep) == 17 and repeats.sum() == 24
    bound = np.concatenate([b for _, b in pooled_bound_blocks(T, V, model, block_rows=4)])
    assert np.all(bound <= got ** (1 / 2) * 10) and np.all(bound > 0)


@pytest.mark.parametrize("pooling", ["quick", "sum"])
def test_a_placement_s_visible_fault_adds_to_the_pooled_cost_in_the_pooling_s_units(pooling):
    """A rest gap's JND-equivalents x add x to a cost in JND (quick) and x² to a sum of
    contributions (sum), after the criteria and any redirection are pooled; none, or 0, changes no
    bit."""
    rng = np.random.default_rng(3)
    model = CostModel(pooling=pooling)
    terms, extra, rest = (rng.uniform(0, 4, (50, 8)), rng.uniform(0, 2, (50, 2)),
                          rng.uniform(0, 3, 50))
    pooled = model.pool(terms, extra=extra)
    added = rest if pooling == "quick" else rest ** 2
    np.testing.assert_allclose(model.pool(terms, extra=extra, rest=rest), pooled + added,
                               rtol=1e-12)
    assert np.array_equal(model.pool(terms, extra=extra, rest=np.zeros(50)), pooled)
    assert np.array_equal(model.pool(terms, extra=None, rest=None), model.pool(terms))
    np.testing.assert_allclose(model.pool(terms[0], rest=1.5),
                               model.pool(terms[0]) + (1.5 if pooling == "quick" else 2.25))


def test_a_model_keeps_its_rest_rates_in_jnd_form():
    model = CostModel(rest_mm_per_jnd=(0.5, 7.0))
    assert model.as_jnd().rest_mm_per_jnd == (0.5, 7.0)


def test_a_tripods_lever_arm_is_scaled_by_the_torque_threshold_a_pinchs_by_the_weights():
    """A tripod's mass columns (three contacts) take the 12.7 % torque threshold, a pinch's (two)
    the 22 % weight threshold, each above its 20 mm floor: a lever arm of 400 mm."""
    from pinchmatch.match.cost import MASS_JND_FRACTION, TORQUE_JND_FRACTION

    for fingers, fraction in ((3, TORQUE_JND_FRACTION), (2, MASS_JND_FRACTION)):
        table = np.zeros((1, fingers, 9))
        table[..., 7] = 400.0
        s = CostModel().scales(table)
        assert s[..., 7:9] == pytest.approx(np.full((1, fingers, 2), fraction * 400.0))
