import numpy as np
import pytest
import trimesh

from pinchmatch import PinchSettings, check_pinches, object_properties, pinch_features, sample_pinches
from pinchmatch.mesh import shapes
from pinchmatch.mesh.surface import SurfaceContext

from conftest import random_rigid, transformed

UP = np.array([0.0, 0.0, 1.0])


def features_of(mesh, p1, p2, up=UP):
    props = object_properties(mesh, up=up, watertight=True)
    pinches = check_pinches(SurfaceContext(mesh), p1, p2)
    return pinches, pinch_features(pinches, props)


def test_cylinder_features_match_closed_form():
    # R = 20 mm, 80 mm tall, axis Z, centre of mass at the origin
    mesh = shapes.cylinder(20.0, 80.0, triangulation="regular", faces=20000).mesh
    z = 15.0
    pinches, f = features_of(mesh, [[-20.0, 0, z]], [[20.0, 0, z]])
    assert pinches.feasible[0]
    # contacts lie on the facets, inside the true cylinder by at most the sagitta
    assert 40.0 - 0.02 <= f.width_mm[0] <= 40.0 + 1e-9
    assert f.com_distance_mm[0] == pytest.approx(z, abs=1e-6)
    assert f.tilt_deg[0] == pytest.approx(0.0, abs=0.05)
    np.testing.assert_allclose(f.normal_angle_deg[0], 0.0, atol=0.1)
    np.testing.assert_allclose(f.kappa_max_per_m[0], 50.0, rtol=0.015)
    np.testing.assert_allclose(f.kappa_min_per_m[0], 0.0, atol=1.0)
    # kappa_max runs around the cylinder, perpendicular to its axis
    np.testing.assert_allclose(f.curvature_axis_angle_deg[0], 90.0, atol=1.0)


def test_tilted_pinch_on_a_box():
    # a pinch across the 40 mm box, 10 mm higher at p2: tilt = atan(10/40) from the horizontal
    mesh = trimesh.creation.box(extents=(40.0, 30.0, 80.0)).subdivide_to_size(5.0)
    pinches, f = features_of(mesh, [[-20.0, 0, -5.0]], [[20.0, 0, 5.0]])
    assert f.tilt_deg[0] == pytest.approx(np.degrees(np.arctan2(10.0, 40.0)), abs=1e-6)
    np.testing.assert_allclose(f.normal_angle_deg[0], np.degrees(np.arctan2(10.0, 40.0)), atol=1e-4)
    assert f.width_mm[0] == pytest.approx(np.hypot(40.0, 10.0))
    assert f.com_distance_mm[0] == pytest.approx(0.0, abs=1e-6)
    # flat faces: no curvature and so no curvature direction
    assert np.isnan(f.curvature_axis_angle_deg[0]).all()
    np.testing.assert_allclose(f.kappa_max_per_m[0], 0.0, atol=1e-6)


def test_rho_undefined_on_a_sphere_and_along_the_axis():
    mesh = shapes.sphere(25.0, faces=20000).mesh
    _, f = features_of(mesh, [[-25.0, 0, 0]], [[25.0, 0, 0]])
    assert np.isnan(f.curvature_axis_angle_deg).all()  # umbilic
    cyl = shapes.cylinder(20.0, 80.0, triangulation="regular", faces=20000).mesh
    _, f = features_of(cyl, [[0.0, 0, -40.0]], [[0.0, 0, 40.0]])
    assert np.isnan(f.curvature_axis_angle_deg).all()  # flat caps, axis along the normal


@pytest.mark.parametrize("seed", [0, 1])
def test_features_are_invariant_under_rigid_motion(seed):
    mesh = shapes.ellipsoid(triangulation="random", faces=20000).mesh
    props = object_properties(mesh, up=UP, watertight=True)
    base = sample_pinches(SurfaceContext(mesh), settings=PinchSettings(count=60, seed=seed))
    f0 = pinch_features(base, props)

    R, t = random_rigid(seed)
    moved = transformed(mesh, R, t)
    moved_props = object_properties(moved, up=R @ UP, watertight=True)
    p = base.points @ R.T + t
    pinches = check_pinches(SurfaceContext(moved), p[:, 0], p[:, 1])
    f1 = pinch_features(pinches, moved_props)

    np.testing.assert_allclose(f1.width_mm, f0.width_mm, atol=1e-6)
    np.testing.assert_allclose(f1.com_distance_mm, f0.com_distance_mm, atol=1e-6)
    np.testing.assert_allclose(f1.tilt_deg, f0.tilt_deg, atol=1e-5)
    # the moved points are snapped again and fitted in another frame: round-off only
    np.testing.assert_allclose(f1.normal_angle_deg, f0.normal_angle_deg, atol=0.2)
    np.testing.assert_allclose(f1.kappa_max_per_m, f0.kappa_max_per_m, rtol=0.02, atol=0.5)
    np.testing.assert_allclose(f1.kappa_min_per_m, f0.kappa_min_per_m, rtol=0.02, atol=0.5)
    both = ~np.isnan(f0.curvature_axis_angle_deg) & ~np.isnan(f1.curvature_axis_angle_deg)
    np.testing.assert_allclose(f1.curvature_axis_angle_deg[both], f0.curvature_axis_angle_deg[both], atol=1.5)


def test_com_distance_is_measured_along_the_axis_not_to_the_midpoint():
    mesh = trimesh.creation.box(extents=(80.0, 40.0, 20.0)).subdivide_to_size(4.0)
    props = object_properties(mesh, up=np.array([0.0, 0.0, 1.0]), watertight=True)
    # across y, 25 mm along the long axis (x) and 6 mm up: the midpoint is off the axis
    pinches = check_pinches(SurfaceContext(mesh), [[25.0, -20.0, 6.0]], [[25.0, 20.0, 6.0]])
    f = pinch_features(pinches, props)
    assert abs(f.com_distance_mm[0] - 25.0) < 1e-6  # not hypot(25, 6) = 25.7

