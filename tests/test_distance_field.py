"""The distance field's bounds are certain, and the hand decides the same with and without it."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from conftest import random_rigid, transformed
from pinchmatch import PinchSettings, sample_pinches
from pinchmatch.grasp import finger_spheres
from pinchmatch.grasp.hand import Hand, reach
from pinchmatch.mesh import vessels
from pinchmatch.mesh.distance_field import DistanceField
from pinchmatch.mesh.support import SupportPlane
from pinchmatch.mesh.surface import FIELD_MARGIN_MM, SurfaceContext


@pytest.fixture(scope="module")
def turned_mug():
    R, t = random_rigid(11)
    return transformed(vessels.mug(), R, t), R, t


def _queries(points, rng, n=60_000, spread_mm=14.0):
    """Points near the sample (most within a finger's radius), some far out, some beyond the
    grid."""
    near = points[rng.integers(0, len(points), n)] + rng.normal(0.0, spread_mm / 2.0, (n, 3))
    far = points.mean(axis=0) + rng.uniform(-300.0, 300.0, (n // 10, 3))
    return np.vstack([near, far])


def test_the_bounds_hold_the_exact_distance_at_a_random_rotation_off_the_origin(turned_mug):
    mesh, _, _ = turned_mug
    points = SurfaceContext(mesh).sample.points
    field = DistanceField.of(points, margin_mm=FIELD_MARGIN_MM)
    x = _queries(points, np.random.default_rng(3))
    exact, _ = cKDTree(points).query(x)
    lower, upper = field.bounds(x)
    assert (lower <= exact).all() and (exact <= upper).all()
    inside = np.isfinite(upper)
    # not trivial: inside the grid the interval is at most the voxel's diagonal plus twice the
    # offset
    width = upper[inside] - lower[inside]
    assert width.max() <= 2.0 * np.sqrt(3.0) * field.voxel_mm + 1e-6
    assert field.voxel_mm == pytest.approx(1.5)
    # far points are known to be far: the cap the hand asks for (9 mm) is decided for most beyond 12
    # mm
    assert (lower[exact > 12.0] >= 9.0).mean() > 0.95
    # and the outside of the grid is at least the margin from every sample
    assert (exact[~inside] >= FIELD_MARGIN_MM).all() and (lower[~inside] == FIELD_MARGIN_MM).all()


def test_a_large_object_gets_a_coarser_grid_within_the_voxel_limit():
    rng = np.random.default_rng(5)
    R, t = random_rigid(6)
    points = (rng.uniform([0, 0, 0], [2000.0, 600.0, 900.0], (20_000, 3))) @ R.T + t
    field = DistanceField.of(points, margin_mm=20.0, max_voxels=200_000)
    assert field.distance_mm.size <= 200_000 and field.voxel_mm > 1.5
    x = _queries(points, rng, n=20_000, spread_mm=60.0)
    exact, _ = cKDTree(points).query(x)
    lower, upper = field.bounds(x)
    assert (lower <= exact).all() and (exact <= upper).all()


class _Undecided:
    """A field that decides nothing: every distance goes to the KD-tree."""

    def bounds(self, points):
        return np.zeros(len(points)), np.full(len(points), np.inf)


@pytest.mark.parametrize("fingers", [2, 3])
def test_the_reach_search_decides_the_same_with_and_without_the_field(turned_mug, fingers):
    mesh, R, t = turned_mug
    up = R @ np.array([0.0, 0.0, 1.0])
    support = SupportPlane(normal=up, height_mm=float(up @ t) + 0.5, source="pose")
    context = SurfaceContext(mesh, support=support)
    rng = np.random.default_rng(8)
    # contacts anywhere on the surface, feasible or not: the inside, the handle, the bottom on the
    # table
    faces = rng.integers(0, len(mesh.faces), (400, fingers))
    bary = rng.dirichlet(np.ones(3), (400, fingers))
    points = np.einsum("nfk,nfkd->nfd", bary, mesh.triangles[faces])
    normals = mesh.face_normals[faces]
    hand = Hand()
    with_field = reach(context, points, normals, hand)
    exact_context = SurfaceContext(mesh, support=support)
    exact_context.__dict__["distance_field"] = _Undecided()
    exact_context.__dict__["sample"] = context.sample
    without = reach(exact_context, points, normals, hand)
    assert 0 < with_field.ok.sum() < len(points)
    np.testing.assert_array_equal(with_field.ok, without.ok)
    np.testing.assert_array_equal(with_field.approach, without.approach)
    np.testing.assert_array_equal(with_field.clearance_mm, without.clearance_mm)


def test_the_field_spares_most_queries_of_a_sampling_run(turned_mug, monkeypatch):
    mesh, _, _ = turned_mug
    context = SurfaceContext(mesh)
    asked, total = [], []
    query = finger_spheres.query_tree

    def counting(tree, points, **options):
        asked.append(len(points))
        return query(tree, points, **options)

    bounds = type(context.distance_field).bounds

    def seen(self, points):
        total.append(len(points))
        return bounds(self, points)

    monkeypatch.setattr(finger_spheres, "query_tree", counting)
    monkeypatch.setattr(DistanceField, "bounds", seen)
    sample_pinches(context, settings=PinchSettings(count=300, seed=0))
    assert sum(asked) < 0.9 * sum(total)


def test_points_beyond_any_grid_or_not_numbers_read_as_outside(turned_mug):
    mesh, _, _ = turned_mug
    points = SurfaceContext(mesh).sample.points
    field = DistanceField.of(points, margin_mm=FIELD_MARGIN_MM)
    x = np.array([[np.nan, 0.0, 0.0], [np.inf, 0.0, 0.0], [-np.inf, 1.0, 2.0], [1e6, -1e6, 0.0],
                  points[0] + [0.0, np.nan, 0.0]])
    lower, upper = field.bounds(x)
    assert (lower == FIELD_MARGIN_MM).all() and np.isinf(upper).all()
    # and a point on the surface among those that are not finite keeps its own bounds
    lower, upper = field.bounds(np.vstack([x[[0, 1, 2, 4]], points[:1]]))
    assert lower[-1] == 0.0 and upper[-1] < 2.0 * np.sqrt(3.0) * field.voxel_mm
