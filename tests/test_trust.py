"""A scanned prop's features at its scan's error (pinchmatch.match.trust, grasp.scan_noise): the
spread grows with the error's square, does not depend on the frame the prop sits in, is 0 for an
object not from a scan, and enters the felt cost as each criterion's expected squared difference."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pinchmatch.grasp.analysis import analyze_object
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.grasp.scan_noise import noisy_features
from pinchmatch.match.candidates import candidate_poses
from pinchmatch.match.cost import COLUMN_CRITERION, CRITERIA, CostModel
from pinchmatch.match.felt import FeltTables, felt_cost
from pinchmatch.match.scene import match_scene
from pinchmatch.match.search import MatchSettings
from pinchmatch.match.trust import (draws_variance, scan_variance, spread_terms,
                                    uncertainty_jnd)
from pinchmatch.mesh.manifest import read_manifest
from pinchmatch.mesh.shapes import cylinder, sphere

SETTINGS = PinchSettings(count=60, seed=3)


def _scanned(obj, error_mm):
    return dataclasses.replace(obj, spec=dataclasses.replace(obj.spec,
                                                             scan_residual_mm=error_mm))


@pytest.fixture(scope="module")
def cylinders(tmp_path_factory):
    """A cylinder of radius 25 mm, and a copy turned at random, off the origin, triangulated
    otherwise (14,000 faces instead of 20,000), with the same pinches carried over."""
    folder = tmp_path_factory.mktemp("cyl")
    plain = cylinder(25.0, 70.0, faces=20000).mesh
    turned = cylinder(25.0, 70.0, faces=14000, seed=5).mesh
    R = Rotation.random(random_state=11).as_matrix()
    t = np.array([130.0, -75.0, 42.0])
    turned.apply_transform(np.vstack([np.column_stack([R, t]), [0, 0, 0, 1]]))
    plain.export(folder / "plain.stl")
    turned.export(folder / "turned.stl")
    a = candidate_poses(analyze_object(folder / "plain.stl"), settings=SETTINGS)
    p = a.pinches.points
    b = candidate_poses(analyze_object(folder / "turned.stl"), settings=SETTINGS,
                        given=(p[:, 0] @ R.T + t, p[:, 1] @ R.T + t))
    return a, b


def _std(obj, pinches, error_mm, draws=48):
    drawn = noisy_features(obj.context, pinches, obj.props, error_mm, draws=draws)
    return {f: np.stack([getattr(d, f) for d in drawn]).std(axis=0)
            for f in ("width_mm", "normal_angle_deg", "kappa_max_per_m", "kappa_min_per_m")}


def test_the_spread_grows_with_the_square_of_the_error(cylinders):
    """The patch fit is linear in the samples' heights: twice the error, twice each feature's
    standard deviation (the same draws), within the fit's outlier cut and refits."""
    a, _ = cylinders
    small, large = _std(a.obj, a.pinches, 0.1), _std(a.obj, a.pinches, 0.2)
    for f in small:
        ratio = np.median(large[f]) / np.median(small[f])
        assert ratio == pytest.approx(2.0, rel=0.1), (f, ratio)


def test_the_spread_does_not_depend_on_the_frame(cylinders):
    """The same pinches on a turned, moved, re-triangulated copy: each feature's spread alike over
    the poses (other samples, other draws: within 15 % of the median)."""
    a, b = cylinders
    assert len(a) == len(b)
    here, there = _std(a.obj, a.pinches, 0.15), _std(b.obj, b.pinches, 0.15)
    for f in here:
        assert np.median(there[f]) == pytest.approx(np.median(here[f]), rel=0.15), f


def test_an_object_not_from_a_scan_has_no_spread_and_costs_what_it_did(cylinders):
    a, _ = cylinders
    assert not scan_variance(a).any()
    assert not uncertainty_jnd(a, np.arange(len(a)), CostModel()).any()


def test_the_felt_cost_adds_each_criterions_expected_squared_difference(tmp_path, cylinders):
    """Under ``sum`` pooling a cost is linear in the contributions, so the felt cost at a scan's
    error is the felt cost without it plus Σ_c w_c mean_entries(σ² / s²), s the JND of the value
    two σ nearer 0, computed here from the spread and the JND table directly, under
    ``--scan-trust``; the nominal cost does not move."""
    a, _ = cylinders
    ball = sphere(20.0, faces=8000).mesh
    ball.export(tmp_path / "ball.stl")
    V = candidate_poses(analyze_object(tmp_path / "ball.stl"), settings=SETTINGS)
    scanned = dataclasses.replace(a, obj=_scanned(a.obj, 0.2))
    assert scan_variance(scanned, []).shape == (0, 2, 9)  # no poses asked, none drawn
    settings = MatchSettings(top_k=2, pooling="sum", scan_trust=True)
    scene = match_scene([scanned], [V], settings=settings, pinch_settings=SETTINGS)
    model = scene.model
    default = dataclasses.replace(model, scan_trust=False)
    for choice in [scene.matches[0].best] + scene.matches[0].alternatives:
        T, Vc = scene.objects(scene.matches[0])[0][0], scene.objects(scene.matches[0])[1]
        with_error = felt_cost(T, Vc, choice, model, FeltTables(5.0, SETTINGS))
        plain = dataclasses.replace(T, obj=_scanned(T.obj, None))
        without = felt_cost(plain, Vc, choice, model, FeltTables(5.0, SETTINGS))
        var = scan_variance(T, [choice.t_pose])[0]  # (2, 9)
        row = T.table[choice.t_pose]
        # the JND of the least value each feature may have: two standard deviations nearer 0
        least = np.sign(row) * np.maximum(np.abs(row) - 2.0 * np.sqrt(var), 0.0)
        s = model.scales(least[None])[0]
        per_column = (var / s ** 2).mean(axis=0)  # the two patches' mean
        oracle = np.zeros(len(CRITERIA))
        np.add.at(oracle, COLUMN_CRITERION, per_column)
        added = float(model.weight_vector() @ oracle)
        assert added > 0
        assert with_error.nominal == without.nominal == pytest.approx(choice.cost_nominal)
        assert with_error.expected - without.expected == pytest.approx(added, rel=1e-6)
        assert with_error.worst - without.worst == pytest.approx(added, rel=1e-6)
        # without --scan-trust the spread is reported, never weighed
        assert felt_cost(T, Vc, choice, default, FeltTables(5.0, SETTINGS)) == without


def test_the_manifests_scan_table_is_read_and_checked(tmp_path):
    cylinder(25.0, 70.0).mesh.export(tmp_path / "c.stl")
    good = tmp_path / "good.toml"
    good.write_text('[[object]]\nfile = "c.stl"\nunits = "mm"\n'
                    'scan = { noise_mm = 0.6, residual_mm = 0.12, scale_verified = false }\n')
    (spec,) = read_manifest(good)
    assert (spec.scan_noise_mm, spec.scan_residual_mm, spec.scale_verified) == (0.6, 0.12, False)
    for bad in ('scan = { noise_mm = -1 }', 'scan = { noise = 0.5 }', 'scan = 0.5',
                'scan = { scale_verified = "no" }', 'scan = { residual_mm = 20 }'):
        path = tmp_path / "bad.toml"
        path.write_text(f'[[object]]\nfile = "c.stl"\n{bad}\n')
        with pytest.raises(Exception, match=r"bad\.toml.*scan: must be a table"):
            read_manifest(path)


def test_the_variance_over_draws_leaves_out_an_undefined_entry():
    """ρ is undefined (NaN) on an umbilic patch: a draw where it is counts for nothing."""
    drawn = np.array([[1.0, np.nan, 4.0], [np.nan, np.nan, 4.0], [3.0, np.nan, 4.0]])
    assert draws_variance(drawn).tolist() == [1.0, 0.0, 0.0]


def test_a_virtual_spread_counts_in_the_mass_the_tangible_feels():
    """The virtual object's mass offsets are compared scaled by the mass ratio, so their variance
    counts at the ratio squared; each criterion in the tangible's scales."""
    model = CostModel()
    t_rows = np.full((1, 2, 9), 30.0)
    v_var = np.zeros((1, 2, 9))
    v_var[..., 7] = 4.0  # the offset along the line, 2 mm
    terms = spread_terms(t_rows, np.zeros_like(v_var), v_var, 3.0, model)[0]
    s = model.scales(t_rows)[0, 0, 7]
    mass = CRITERIA.index("mass")
    # the mass criterion sums its two columns, each the mean of the two patches
    assert terms[mass] == pytest.approx(9.0 * 4.0 / s**2, rel=1e-12)
    assert np.delete(terms, mass).tolist() == [0.0] * (len(CRITERIA) - 1)
