"""The lowest point along many directions (pinchmatch.mesh.lowest): the same as trying every point,
on sets of every shape, along directions of every kind, with a fraction of the points tried."""

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from pinchmatch.mesh import lowest
from pinchmatch.mesh.lowest import direction_cells, lowest_along, lowest_table


def _sets():
    rng = np.random.default_rng(3)
    turn = Rotation.from_euler("zyx", [37, -61, 113], degrees=True)
    return {
        "sphere off the origin": trimesh.creation.icosphere(4, radius=40.0).vertices
        + [120.0, -35.0, 480.0],
        "thin turned ellipsoid": turn.apply(trimesh.creation.icosphere(3, radius=1.0).vertices
                                            * [160.0, 20.0, 8.0]) + [5.0, 6.0, -7.0],
        "box (ties)": trimesh.creation.box([60.0, 40.0, 20.0]).vertices,
        "noisy cloud": rng.normal(size=(2000, 3)) * [30.0, 10.0, 50.0],
        "one point": np.array([[1.0, 2.0, 3.0]]),
    }


def _directions():
    rng = np.random.default_rng(4)
    random = Rotation.random(3000, random_state=5).apply([0.0, 0.0, 1.0])
    axes = np.concatenate([np.eye(3), -np.eye(3)])
    edges = np.array([[1.0, 1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, -1.0], [-1.0, 0.0, 1.0]])
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
    scaled = random[:50] * rng.uniform(0.01, 100.0, size=(50, 1))  # not unit: the same cells
    return np.concatenate([random, axes, edges, corners, scaled])


@pytest.mark.parametrize("name", list(_sets()))
def test_the_lowest_point_is_the_one_of_every_point(name):
    points = _sets()[name]
    directions = _directions()
    got = lowest_along(lowest_table(points), directions)
    want = (points @ directions.T).min(axis=0)
    scale = np.abs(points).max() * np.abs(directions).max(axis=1)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * scale.max())


def test_directions_that_are_not_finite_or_zero_try_every_point():
    points = _sets()["noisy cloud"]
    d = np.array([[0.0, 0.0, 1.0], [np.nan, 0.0, 1.0], [0.0, 0.0, 0.0], [np.inf, 1.0, 0.0]])
    got = lowest_along(lowest_table(points), d)
    with np.errstate(invalid="ignore"):
        want = (points @ d.T).min(axis=0)
    np.testing.assert_allclose(got[[0, 2]], want[[0, 2]], atol=1e-9)
    assert np.isnan(got[1]) and np.isnan(want[1]) and got[3] == want[3]


@pytest.mark.parametrize("cells", [1, 3, 12])
def test_a_direction_falls_in_the_cell_whose_centre_it_is_and_each_cell_keeps_its_lowest_points(
        cells):
    centres, radii = lowest._cell_directions(cells)
    assert len(centres) == 6 * cells * cells
    np.testing.assert_array_equal(direction_cells(centres, cells), np.arange(len(centres)))
    np.testing.assert_array_equal(direction_cells(3.5 * centres, cells), np.arange(len(centres)))
    assert (radii > 0).all() and (radii < np.radians(55.0)).all()
    points = _sets()["thin turned ellipsoid"]
    table = lowest_table(points, cells)
    for c in range(len(centres)):
        kept = table.candidates[table.starts[c]:table.starts[c + 1]]
        assert (np.diff(kept) > 0).all()
        assert int(np.argmin(points @ centres[c])) in kept


def test_a_round_set_tries_a_fraction_of_its_points():
    points = _sets()["sphere off the origin"]
    table = lowest_table(points)
    per_cell = np.diff(table.starts)
    assert per_cell.min() >= 1 and per_cell.mean() < 0.25 * len(points), per_cell.mean()
