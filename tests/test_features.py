import numpy as np
import pytest
import trimesh

from pinchmatch import (PinchSettings, check_pinches, object_properties, pinch_features,
                        sample_pinches)
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
    np.testing.assert_allclose(f1.curvature_axis_angle_deg[both], f0.curvature_axis_angle_deg[both],
                               atol=1.5)


def test_com_distance_is_measured_along_the_axis_not_to_the_midpoint():
    mesh = trimesh.creation.box(extents=(80.0, 40.0, 20.0)).subdivide_to_size(4.0)
    props = object_properties(mesh, up=np.array([0.0, 0.0, 1.0]), watertight=True)
    # across y, 25 mm along the long axis (x) and 6 mm up: the midpoint is off the axis
    pinches = check_pinches(SurfaceContext(mesh), [[25.0, -20.0, 6.0]], [[25.0, 20.0, 6.0]])
    f = pinch_features(pinches, props)
    assert abs(f.com_distance_mm[0] - 25.0) < 1e-6  # not hypot(25, 6) = 25.7



def _pinches(points, normals, kappa_max, kappa_min, dir_max):
    """Pinches built directly from contacts, normals and curvatures (no mesh: exact inputs)."""
    from pinchmatch.grasp.pinches import RULES, Pinches

    n = len(points)
    return Pinches(np.asarray(points, float), np.asarray(normals, float),
                   np.zeros((n, 2), np.int64), np.asarray(kappa_max, float),
                   np.asarray(kappa_min, float), np.asarray(dir_max, float), np.ones(n, bool),
                   np.zeros((n, len(RULES)), bool), np.zeros((n, 2)), np.zeros((n, 3)), np.zeros(n))


def _props(com_mm, axis=(0.0, 0.0, 1.0)):
    return object_properties(trimesh.creation.box(extents=(60.0, 40.0, 20.0)),
                             up=np.array([0.0, 0.0, 1.0]), watertight=True, com_mm=np.array(com_mm),
                             axis=np.array(axis))


def test_mass_offsets_along_the_pinch_line_and_the_lever_arm_in_closed_form():
    # pinch from (-30, 5, 2) to (30, 5, 2), centre of mass at (5, 3, 0): offset from the midpoint
    # (5, -2, -2), so 5 mm along the line from p1 (-5 from p2) and a lever arm of sqrt(8) mm
    x = np.array([1.0, 0.0, 0.0])
    pinches = _pinches([[[-30, 5, 2], [30, 5, 2]]], [[-x, x]], [[0.0, 0.0]], [[0.0, 0.0]],
                       [[[0, 1, 0], [0, 1, 0]]])
    f = pinch_features(pinches, _props([5.0, 3.0, 0.0]))
    np.testing.assert_allclose(f.mass_along_mm, [[5.0, -5.0]], atol=1e-12)
    np.testing.assert_allclose(f.mass_perp_mm, [np.sqrt(8.0)], atol=1e-12)
    np.testing.assert_allclose(f.com_distance_mm, [2.0], atol=1e-12)  # along the z axis: |2 - 0|


@pytest.mark.parametrize("anisotropy, defined", [(2.5, True), (1.5, False)])
def test_the_curvature_axis_angle_needs_2_per_m_of_anisotropy(anisotropy, defined):
    # perception.md: curvature differences below about 2 /m are not felt, so no direction of
    # kappa_max either; the axis (z) lies in both patches' tangent planes, at 90 deg to dir_max (y)
    x = np.array([1.0, 0.0, 0.0])
    pinches = _pinches([[[-30, 0, 0], [30, 0, 0]]], [[-x, x]], [[10.0 + anisotropy] * 2],
                       [[10.0, 10.0]], [[[0, 1, 0], [0, 1, 0]]])
    rho = pinch_features(pinches, _props([0.0, 0.0, 0.0])).curvature_axis_angle_deg
    if defined:
        np.testing.assert_allclose(rho, [[90.0, 90.0]], atol=1e-9)
    else:
        assert np.isnan(rho).all()


def test_a_normal_exactly_along_the_pinch_line_is_0_deg_not_nan():
    # for this pinch line the unit vector's dot product with itself rounds to 1 + 2e-16
    seg = np.array([-23.3, -2.2, -12.5])
    u = seg / np.linalg.norm(seg)
    assert abs(u @ u) > 1.0
    pinches = _pinches([[[0, 0, 0], seg]], [[-u, u]], [[0.0, 0.0]], [[0.0, 0.0]],
                       [[[0, 0, 1], [0, 0, 1]]])
    psi = pinch_features(pinches, _props([5.0, 5.0, 5.0])).normal_angle_deg
    np.testing.assert_array_equal(psi, [[0.0, 0.0]])


def test_a_pinch_exactly_along_the_axis_is_tilted_90_deg_not_nan():
    # for this line and this axis the rounded dot product of the unit vectors is -1 - 2e-16
    seg = np.array([6.0, 0.4, -2.9])
    x = seg / np.linalg.norm(seg)
    pinches = _pinches([[[0, 0, 0], seg]], [[-x, x]], [[0.0, 0.0]], [[0.0, 0.0]],
                       [[[0, 0, 1], [0, 0, 1]]])
    tilt = pinch_features(pinches, _props([0.0, 0.0, 0.0], axis=seg)).tilt_deg
    np.testing.assert_array_equal(tilt, [90.0])


def test_each_finger_sees_the_centre_of_mass_along_its_own_pinch_direction():
    """mass_along_mm per finger: the centre of mass's offset from the midpoint along the finger's
    own pinch direction (p1 -> p2 for the thumb, p2 -> p1 for the index): a pinch reversed swaps and
    negates them."""
    from pinchmatch.grasp.pinches import check_pinches
    from pinchmatch.mesh.surface import SurfaceContext
    from pinchmatch.mesh.properties import object_properties

    mesh = trimesh.creation.box(extents=(60.0, 40.0, 20.0))
    context = SurfaceContext(mesh)
    props = object_properties(mesh, up=np.array([0.0, 0.0, 1.0]), watertight=True)
    a, b = np.array([[25.0, 0.0, 10.0]]), np.array([[5.0, 0.0, -10.0]])  # top to bottom, slanted
    ahead = pinch_features(check_pinches(context, a, b), props).mass_along_mm[0]
    back = pinch_features(check_pinches(context, b, a), props).mass_along_mm[0]
    assert ahead[0] == pytest.approx(-ahead[1]) and abs(ahead[0]) > 1.0
    np.testing.assert_allclose(back, ahead[::-1], atol=1e-12)
    u = (b - a)[0] / np.linalg.norm(b - a)
    assert ahead[0] == pytest.approx((props.com_mm - (a + b)[0] / 2) @ u)
