"""A scanned cloud's normals turned toward the outside (pinchmatch.scan.orient), checked against the
analytic normals of the surfaces the clouds are drawn from: a cup with walls thinner than the
noise's reach, a box with gaps in its scan, a solid whose base is hollow underneath. Every cloud is
turned about its up (+Z, as a scan is read) by a random angle, moved off the origin and shuffled.
The normals come in as a propagated estimate gives them: the cup's walls both facing away from its
axis (the sign carried across the wall), a solid's all turned inward (one sign wrong throughout), or
each sign at random."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from pinchmatch.scan.orient import outward_normals

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from scans import cup  # noqa: E402 (benchmarks/ first)


def _cloud(mesh: trimesh.Trimesh, rng, *, points: int, noise_mm: float,
           open_bottom_mm: float = 0.0):
    """Points on ``mesh`` with their outward normals, the noise along them, none within
    ``open_bottom_mm`` of the lowest point but those facing up (the table hid the rest); turned
    about +Z, moved and shuffled."""
    p, face = trimesh.sample.sample_surface_even(mesh, points, seed=rng)
    n = mesh.face_normals[face]
    # near the table only what faces up is seen (a cup's inside floor, from above)
    keep = (p[:, 2] >= mesh.bounds[0, 2] + open_bottom_mm) | (n[:, 2] > 0.5)
    p, n = p[keep] + n[keep] * rng.normal(0.0, noise_mm, (keep.sum(), 1)), n[keep]
    turn = trimesh.transformations.rotation_matrix(rng.uniform(0, 2 * np.pi), [0, 0, 1])[:3, :3]
    order = rng.permutation(len(p))
    return p[order] @ turn.T + np.array([173.0, -61.0, 48.0]), n[order] @ turn.T


def _random_signs(normals, rng) -> np.ndarray:
    return np.where(rng.random(len(normals)) < 0.5, -1.0, 1.0)[:, None] * normals


def _outward_share(points, truth, given) -> float:
    """The share of ``points`` whose normal, turned from the ``given`` one, faces as ``truth``."""
    faced = outward_normals(points, given).normals
    assert np.allclose(np.abs(np.einsum("ij,ij->i", faced, truth)), 1.0)  # the lines are kept
    return float(np.mean(np.einsum("ij,ij->i", faced, truth) > 0))


@pytest.mark.parametrize("wall_mm, noise_mm, least", [(2.5, 0.3, 0.97), (1.5, 0.3, 0.93),
                                                      (2.5, 0.5, 0.9)])
def test_both_sides_of_a_thin_wall_face_out(wall_mm, noise_mm, least):
    """A cup whose wall is a few noise widths thick, its bottom unseen: both sides of the wall face
    their own air (the room and the cup's inside), the inside reached through the mouth. A point
    that the noise carried past the wall's middle cannot be told from the other side's, so the
    share expected falls with the wall's thickness over the noise."""
    rng = np.random.default_rng(11)
    points, truth = _cloud(cup(wall_mm), rng, points=60_000, noise_mm=noise_mm,
                           open_bottom_mm=2.0)
    radial = points - points.mean(axis=0)
    radial[:, 2] = 0.0
    away = np.where(np.einsum("ij,ij->i", truth, radial) < 0, -1.0, 1.0)[:, None] * truth
    assert _outward_share(points, truth, away) >= least
    assert _outward_share(points, truth, _random_signs(truth, rng)) >= least


def test_a_real_mugs_cloud_with_its_inside_floor_seen_faces_out(tmp_path):
    """The YCB mug (a scan nobody here made, 1 to 1.5 mm walls) as a cloud with 0.5 mm of noise,
    its lowest 3 mm unseen but for its inside floor, seen from above: the floor is the cloud's
    lowest point, below where the outer wall was last seen. Without the band under the object
    closed with the table, the room reaches under the floor through the gap below the wall
    (measured: 73 % of the normals right, 24 % of the points unsure); with it, at least 95 % face
    out and under 15 % are unsure (the import's limit). Given all facing in, as propagation can
    leave them."""
    from assets import ycb_objects
    from scans import clean_mesh

    (path,) = ycb_objects(tmp_path, ["025_mug"])
    rng = np.random.default_rng(8)
    points, truth = _cloud(clean_mesh(path), rng, points=100_000, noise_mm=0.5,
                           open_bottom_mm=3.0)
    faced = outward_normals(points, -truth)
    assert np.mean(np.einsum("ij,ij->i", faced.normals, truth) > 0) >= 0.95
    assert faced.unsure < 0.15


def test_a_scan_with_gaps_and_a_bottom_it_stood_on_faces_out():
    """A box scanned with a 2 mm band missing round it and its underside unseen: the gaps are
    sealed, so its inside is not taken for the outside, and every point faces out."""
    rng = np.random.default_rng(5)
    box = trimesh.creation.box([70.0, 50.0, 40.0])
    box = box.subdivide().subdivide()
    points, truth = _cloud(box, rng, points=40_000, noise_mm=0.3, open_bottom_mm=1.0)
    local = points - points.mean(axis=0)
    band = np.abs(local[:, 2] - 5.0) < 1.0
    for given in (-truth, _random_signs(truth, rng)):
        assert _outward_share(points[~band], truth[~band], given[~band]) >= 0.995


def test_a_hollow_base_scanned_from_below_faces_out():
    """A solid whose base is hollowed 4 mm deep, scanned all round, its underside too (the object
    turned over for a second pass): the table the lowest point stood on closes the hollow, so its
    points are probed again without it, and face the room below."""
    rng = np.random.default_rng(3)
    body = trimesh.creation.cylinder(radius=35.0, height=40.0, sections=96)
    pocket = trimesh.creation.cylinder(radius=25.0, height=8.0, sections=96)
    pocket.apply_translation([0.0, 0.0, -20.0])
    solid = body.difference(pocket, engine="manifold")
    points, truth = _cloud(solid, rng, points=50_000, noise_mm=0.3)
    for given in (-truth, _random_signs(truth, rng)):
        assert _outward_share(points, truth, given) >= 0.995


def test_points_the_probes_cannot_tell_take_their_neighbours_sign():
    """A flat sheet of points whose signs are known only along one edge: the votes carry that sign
    across the whole sheet, round after round."""
    from scipy.spatial import cKDTree

    from pinchmatch.scan.orient import _voted

    rng = np.random.default_rng(2)
    points = np.column_stack([rng.uniform(0, 40, 8000), rng.uniform(0, 20, 8000),
                              rng.normal(0, 0.05, 8000)])
    normals = np.tile([0.0, 0.0, 1.0], (8000, 1)) * np.where(rng.random(8000) < 0.5, -1, 1)[:, None]
    sign = np.where(points[:, 0] < 2.0, normals[:, 2], 0.0)  # +Z known along x < 2 mm only
    sign = _voted(cKDTree(points), normals, sign)
    assert np.all(sign * normals[:, 2] > 0)


@pytest.mark.parametrize("turn", [1.0, -1.0])
@pytest.mark.parametrize("misled_from_mm, kept", [(28.0, False), (26.0, True)])
def test_a_region_follows_its_probes_unless_they_split(misled_from_mm, kept, turn):
    """One sheet 30 mm wide whose given normals agree (+Z): its probes say ``turn``, but for a band
    2 mm wide that cannot tell (0) and, past it, a strip that the probes misled (-``turn``, as in
    a crevice narrower than the seal). The band joins them into one region. A strip of 2 mm (7 %
    of the decided points) follows the region's majority; one of 4 mm (14 %, past
    ``SPLIT_SHARE``) makes it a thin wall's two sides joined, and each decided point keeps its own
    probe. A second sheet far off, none of whose probes could tell, keeps the given sign."""
    from scipy.spatial import cKDTree

    from pinchmatch.scan.orient import _by_regions

    rng = np.random.default_rng(4)
    points = np.column_stack([rng.uniform(0, 30, 6000), rng.uniform(0, 30, 6000),
                              rng.normal(0, 0.05, 6000)])
    points[5000:, 2] += 100.0  # the second sheet
    normals = np.tile([0.0, 0.0, 1.0], (6000, 1))
    x = points[:, 0]
    sign = turn * np.where(x < misled_from_mm - 2.0, 1.0, np.where(x < misled_from_mm, 0.0, -1.0))
    sign[5000:] = 0.0
    settled = _by_regions(cKDTree(points), normals, sign)
    assert set(np.unique(settled)) <= {-1.0, 1.0}
    assert np.all(settled[5000:] == 1.0)
    first, decided = settled[:5000], sign[:5000] != 0
    if kept:
        assert np.array_equal(first[decided], sign[:5000][decided])
    else:
        assert np.all(first == turn)


def test_how_sure_falls_where_walls_are_as_thin_as_the_noise():
    """The share of points on walls too thin to tell their sides apart: under 2 % on a cup with
    2.5 mm walls and 0.3 mm of noise; over a fifth on a dish with 1 mm walls and 0.5 mm (whose
    normals are then right for barely four points in five: the import refuses such a cloud)."""
    rng = np.random.default_rng(11)
    points, truth = _cloud(cup(2.5), rng, points=60_000, noise_mm=0.3, open_bottom_mm=2.0)
    assert outward_normals(points, truth).unsure < 0.02
    points, truth = _cloud(cup(1.0, radius_mm=40.0, height_mm=30.0), rng, points=100_000,
                           noise_mm=0.5, open_bottom_mm=2.0)
    faced = outward_normals(points, truth)
    assert faced.unsure > 0.2
    assert np.mean(np.einsum("ij,ij->i", faced.normals, truth) > 0) < 0.9
