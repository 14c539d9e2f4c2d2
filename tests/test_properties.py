import numpy as np
import pytest
import trimesh

from pinchmatch import ConfigError, object_properties
from pinchmatch.mesh import shapes
from pinchmatch.mesh.shapes import cylinder, stacked_prop

from conftest import random_rigid, transformed


def test_solid_com_and_axis_of_a_moved_cylinder():
    R, t = random_rigid(3)
    mesh = transformed(cylinder(20.0, 80.0, triangulation="cad", faces=2000).mesh, R, t)
    props = object_properties(mesh, up=np.array([0.0, 0.0, 1.0]), watertight=True)
    np.testing.assert_allclose(props.com_mm, t, atol=1e-6)
    assert abs(props.principal_axis @ R[:, 2]) == pytest.approx(1.0, abs=1e-9)
    assert props.axis_source == "pca" and props.com_source == "solid"
    # variances of a solid cylinder: h²/12 along the axis, R²/4 across
    np.testing.assert_allclose(props.variances_mm2[0], 80.0**2 / 12, rtol=1e-9)


def test_com_of_the_solid_not_of_the_surface():
    """The study stack in closed form: a 64-gon prism (Ø40, z 0-40), a 40 mm cube (z 40-80) and a
    64-gon frustum (Ø60 -> Ø20, z 80-120). A 64-gon of circumradius r has area k·πr², k =
    64/(2π)·sin(2π/64); a frustum's centroid lies h(R² + 2Rr + 3r²) / (4(R² + Rr + r²)) above
    its base."""
    mesh = stacked_prop(sections=64)
    props = object_properties(mesh, up=np.array([0.0, 0.0, 1.0]), watertight=True)
    k = 64 / (2 * np.pi) * np.sin(2 * np.pi / 64)
    volumes = np.array([k * np.pi * 20.0**2 * 40.0, 40.0**3,
                        k * np.pi * 40.0 / 3 * (30.0**2 + 30.0 * 10.0 + 10.0**2)])
    heights = np.array([20.0, 60.0, 80.0 + 40.0 * (900.0 + 600.0 + 300.0) / (4 * 1300.0)])
    np.testing.assert_allclose(props.com_mm, [0.0, 0.0, volumes @ heights / volumes.sum()],
                               atol=1e-6)
    surface_centroid = (mesh.triangles_center * mesh.area_faces[:, None]).sum(axis=0) / mesh.area
    assert abs(surface_centroid[2] - props.com_mm[2]) > 0.5  # 58.3 mm: the shell's would be wrong
    np.testing.assert_allclose(props.principal_axis, [0, 0, 1], atol=1e-9)


@pytest.mark.parametrize("extents", [(40.0, 40.0, 40.0), (60.0, 60.0, 10.0)])
def test_ambiguous_axis_uses_up(extents):
    # a cube (all variances equal) and a disc (two largest equal): the axis is ill-defined
    mesh = trimesh.creation.box(extents=extents)
    up = np.array([0.0, 1.0, 0.0])
    props = object_properties(mesh, up=up, watertight=True)
    assert props.axis_source == "up"
    np.testing.assert_allclose(props.principal_axis, up)


def test_open_mesh_uses_the_surface():
    mesh = trimesh.creation.box(extents=(80.0, 20.0, 10.0))
    mesh.update_faces(np.arange(12) != 0)
    props = object_properties(mesh, up=np.array([0.0, 0.0, 1.0]), watertight=False)
    assert props.com_source == "surface" and props.volume_mm3 is None
    assert abs(props.principal_axis[0]) == pytest.approx(1.0, abs=1e-3)  # one face missing


def test_user_overrides():
    mesh = trimesh.creation.box(extents=(80.0, 20.0, 10.0))
    props = object_properties(mesh, up=np.array([0.0, 0.0, 1.0]), watertight=True,
                              com_mm=np.array([1.0, 2.0, 3.0]), axis=np.array([0.0, 2.0, 0.0]))
    np.testing.assert_allclose(props.com_mm, [1, 2, 3])
    np.testing.assert_allclose(props.principal_axis, [0, 1, 0])
    assert props.axis_source == "user" and props.com_source == "user"
    with pytest.raises(ConfigError, match="--axis"):
        object_properties(mesh, up=np.array([0.0, 0.0, 1.0]), watertight=True, axis=np.zeros(3))


SOLIDS = [
    lambda: shapes.sphere(20.0, triangulation="random", faces=20000),
    lambda: cylinder(20.0, 80.0, triangulation="regular", faces=20000),
    lambda: shapes.torus(30.0, 12.0, triangulation="regular", faces=20000),
    lambda: shapes.ellipsoid((40.0, 25.0, 18.0), triangulation="regular", faces=20000),
    lambda: shapes.box((60.0, 40.0, 20.0)),
]


@pytest.mark.parametrize("make", SOLIDS, ids=["sphere", "cylinder", "torus", "ellipsoid", "box"])
def test_centre_of_mass_and_volume_of_moved_solids(make):
    shape = make()
    R, t = random_rigid(11)
    mesh = transformed(shape.mesh, R, t)
    props = object_properties(mesh, up=np.array([0.0, 0.0, 1.0]), watertight=True)
    # a random triangulation is not exactly symmetric: its centre of mass moves by microns
    np.testing.assert_allclose(props.com_mm, R @ shape.com_mm + t, atol=0.01)
    # faceting makes the mesh a little smaller than the solid it stands for (one-sided)
    assert 0.985 * shape.volume_mm3 <= props.volume_mm3 <= shape.volume_mm3 * (1 + 1e-9)


def test_an_open_tube_has_the_closed_form_moments_of_a_thin_shell():
    """A uniform cylindrical shell without caps, radius R and height H: centroid on the axis at
    mid-height, variance H²/12 along the axis and R²/2 across (no caps, so not the solid's
    R²/4)."""
    radius, height = 20.0, 100.0
    tube = trimesh.creation.cylinder(radius=radius, height=height, sections=720)
    tube.update_faces(np.abs(tube.face_normals[:, 2]) < 0.5)  # drop both caps: an open surface
    tube.remove_unreferenced_vertices()
    tube.apply_translation((5.0, -3.0, 60.0))
    props = object_properties(tube, up=np.array([0.0, 0.0, 1.0]), watertight=False)
    assert props.com_source == "surface"
    np.testing.assert_allclose(props.com_mm, [5.0, -3.0, 60.0], atol=1e-9)
    np.testing.assert_allclose(np.abs(props.principal_axis), [0.0, 0.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(props.variances_mm2[0], height**2 / 12.0, rtol=1e-9)
    # the 720-gon's shell differs from the circle's by (1 - cos(pi/720))-order terms
    np.testing.assert_allclose(sorted(props.variances_mm2[1:]), [radius**2 / 2.0] * 2, rtol=1e-4)


@pytest.mark.parametrize("ratio, source", [(0.93, "pca"), (0.97, "up")])
def test_the_axis_is_ambiguous_within_5_percent_of_the_largest_variance(ratio, source):
    # a box's variances along its sides are a^2/12: the two largest differ by 1 - ratio
    b = 100.0 * np.sqrt(ratio)
    box = trimesh.creation.box(extents=(b, 100.0, 30.0))
    props = object_properties(box, up=np.array([0.0, 0.0, 1.0]), watertight=True)
    assert props.axis_source == source
    np.testing.assert_allclose(np.abs(props.principal_axis),
                               [0, 1, 0] if source == "pca" else [0, 0, 1], atol=1e-9)


@pytest.mark.parametrize("text, ok",
                         [("1,2,3", True), ("-1, 0.5 ,2", True), ("1,2,nan", False), ("1,2", False),
                                      ("1,2,3,4", False), ("a,b,c", False), ("1,2,inf", False),
                                      ("0,0,1.5e6", False), ("0,0,999999", True)])
def test_vectors_are_three_finite_numbers(text, ok):
    from pinchmatch.mesh.properties import parse_vector

    if ok:
        assert parse_vector(text, option="--com").shape == (3,)
    else:
        with pytest.raises(ConfigError, match="--com"):
            parse_vector(text, option="--com")


@pytest.mark.parametrize("axis",
                         [(float("nan"), 0.0, 1.0), (0.0, 0.0, float("inf")), (0.0, 0.0, 0.0)])
def test_a_given_axis_must_be_a_finite_non_zero_vector(axis):
    mesh = trimesh.creation.box(extents=(60.0, 40.0, 20.0))
    with pytest.raises(ConfigError, match="non-zero vector"):
        object_properties(mesh, up=np.array([0.0, 0.0, 1.0]), watertight=True, axis=np.array(axis))


def test_a_small_elongated_object_keeps_its_long_axis():
    """A 3 mm rod (variances well under 1 mm²) has a principal axis as clear as a large one's."""
    mesh = trimesh.creation.box(extents=(3.0, 0.6, 0.6))
    props = object_properties(mesh, up=np.array([0.0, 0.0, 1.0]), watertight=True)
    assert props.axis_source == "pca" and props.variances_mm2[0] < 1.0
    np.testing.assert_allclose(np.abs(props.principal_axis), [1.0, 0.0, 0.0], atol=1e-9)
