"""The hand's distance queries: what the search leaves unqueried decides nothing.

The reach search asks the KD-tree only for the test spheres a decision needs: a cell whose centre is
already known not to fit skips the spheres that cannot lower its bound, and a direction whose hand
is stuck skips them all. Here each returned row is checked against the exact distances of every
sphere, on a mug turned at random, off the origin, standing on a table.
"""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from conftest import random_rigid, transformed
from pinchmatch.grasp import finger_spheres as spheres
from pinchmatch.grasp import hand as hand_module
from pinchmatch.grasp.hand import Hand, reach
from pinchmatch.mesh import vessels
from pinchmatch.mesh.support import SupportPlane
from pinchmatch.mesh.surface import SurfaceContext


@pytest.fixture(scope="module")
def standing_mug():
    R, t = random_rigid(23)
    up = R @ np.array([0.0, 0.0, 1.0])
    support = SupportPlane(normal=up, height_mm=float(up @ t) + 0.5, source="pose")
    return SurfaceContext(transformed(vessels.mug(), R, t), support=support)


def _batch(context, fingers, rng, m=3000):
    """Fingertips on the surface, each finger's direction at random or along the surface, cells of
    random size (δ up to a coarse cell's, some 0), a hint for some rows."""
    mesh = context.mesh
    faces = rng.integers(0, len(mesh.faces), (m, fingers))
    bary = rng.dirichlet(np.ones(3), (m, fingers))
    tips = np.einsum("mfk,mfkd->mfd", bary, mesh.triangles[faces]) + 8.0 * mesh.face_normals[faces]
    h = rng.normal(size=(m, fingers, 3))
    # a third slide along the surface, where every sphere lies near a finger's radius from it
    normal = mesh.face_normals[faces]
    along = rng.random(m) < 1.0 / 3.0
    h[along] -= np.einsum("mfd,mfd->mf", h[along], normal[along])[:, :, None] * normal[along]
    h /= np.linalg.norm(h, axis=2, keepdims=True)
    delta = rng.uniform(0.0, 0.32, (m, fingers)) * (rng.random((m, 1)) < 0.85)
    offsets = Hand().test_offsets_mm
    first = np.where(rng.random(m) < 0.5, rng.integers(0, fingers * len(offsets), m), -1)
    return tips, h, delta, first


def _exact(context, tips, h, offsets, cap):
    """(m, F, P) every sphere's distance, queried."""
    centres = tips[:, :, None, :] + offsets[None, None, :, None] * h[:, :, None, :]
    d, _ = cKDTree(context.sample.points).query(centres.reshape(-1, 3), distance_upper_bound=cap)
    d = np.minimum(d, cap).reshape(centres.shape[:3])
    return np.minimum(d, np.maximum(context.support.heights(centres), 0.0))


@pytest.mark.parametrize("fingers", [2, 3])
def test_the_spheres_left_unqueried_change_no_decision(standing_mug, fingers, monkeypatch):
    context = standing_mug
    hand = Hand()
    offsets, rho, cap = (hand.test_offsets_mm, hand.test_radius_mm,
                         hand.finger_radius_mm + hand_module.CLEARANCE_CAP_MM)
    tips, h, delta, first = _batch(context, fingers, np.random.default_rng(fingers))
    stuck = np.random.default_rng(40 + fingers).random(len(h)) < 0.3  # the gate refuses these
    asked = []
    query = spheres.query_tree

    def counting(tree, points, **options):
        asked.append(len(points))
        return query(tree, points, **options)

    monkeypatch.setattr(spheres, "query_tree", counting)
    d, refused = spheres.axis_distances(context, tips, h, offsets, cap, rho, delta, first=first,
                                          gate=lambda rows: ~stuck[rows])
    exact = _exact(context, tips, h, offsets, cap)
    term, exact_term = d + offsets * delta[:, :, None], exact + offsets * delta[:, :, None]
    ruled = (exact_term < rho).any(axis=(1, 2))
    fits = (exact >= rho).all(axis=(1, 2))
    # only rows the gate refused are refused, and each of those the gate refused is refused or ruled
    # out
    assert not (refused & ~stuck).any() and (refused | ruled)[stuck].all()
    open_ = ~refused
    np.testing.assert_array_equal((term < rho).any(axis=(1, 2))[open_], ruled[open_])
    np.testing.assert_array_equal((d >= rho).all(axis=(1, 2))[open_], fits[open_])
    # a fitting centre's clearance
    np.testing.assert_array_equal(d[open_ & fits], exact[open_ & fits])
    # and fitting rows near the surface
    assert ((exact[open_ & fits] < cap).any(axis=(1, 2))).sum() >= 20
    between = open_ & ~ruled & ~fits
    flat, exact_flat = (term[between].reshape(between.sum(), -1),
                        exact_term[between].reshape(between.sum(), -1))
    np.testing.assert_array_equal(flat.min(axis=1), exact_flat.min(axis=1))
    np.testing.assert_array_equal(flat.argmin(axis=1), exact_flat.argmin(axis=1))
    # not trivial: every kind of row is there, and far fewer spheres were queried than there are
    assert min(ruled[open_].sum(), fits[open_].sum(), between.sum(), refused.sum()) >= 20
    assert sum(asked) < 0.5 * d.size


def test_a_gate_that_refuses_every_row_leaves_only_the_hints_queried(standing_mug, monkeypatch):
    context = standing_mug
    hand = Hand()
    offsets, rho, cap = (hand.test_offsets_mm, hand.test_radius_mm,
                         hand.finger_radius_mm + hand_module.CLEARANCE_CAP_MM)
    tips, h, delta, first = _batch(context, 2, np.random.default_rng(7), m=500)
    asked = []
    query = spheres.query_tree
    monkeypatch.setattr(spheres, "query_tree",
                        lambda tree, points, **options: asked.append(len(points))
                        or query(tree, points, **options))
    _, refused = spheres.axis_distances(context, tips, h, offsets, cap, rho, delta, first=first,
                                          gate=lambda rows: np.zeros(len(rows), dtype=bool))
    assert sum(asked) <= (first >= 0).sum()
    # random directions mostly run into the mug: the rest are refused
    assert refused.sum() > 0.1 * len(h)


@pytest.mark.parametrize("fingers", [2, 3])
def test_the_reach_search_decides_as_if_every_sphere_were_queried(
    standing_mug, fingers, monkeypatch):
    """The whole search, quick directions and band, against one whose every direction has every
    sphere queried and the hand tested: the same verdicts, approaches and clearances."""
    context = standing_mug
    mesh, rng = context.mesh, np.random.default_rng(50 + fingers)
    faces = rng.integers(0, len(mesh.faces), (300, fingers))
    points = np.einsum("nfk,nfkd->nfd", rng.dirichlet(np.ones(3), (300, fingers)),
                       mesh.triangles[faces])
    normals = mesh.face_normals[faces]
    hand = Hand()
    found = reach(context, points, normals, hand)

    def every_sphere(context, tips, h, offsets, cap, rho, delta=None, first=None, gate=None):
        every = np.arange(len(h))
        return (_exact(context, tips, h, offsets, cap),
                np.zeros(len(h), dtype=bool) if gate is None else ~gate(every))

    monkeypatch.setattr(hand_module, "axis_distances", every_sphere)
    reference = reach(context, points, normals, hand)
    assert 0 < reference.ok.sum() < len(points)
    np.testing.assert_array_equal(found.ok, reference.ok)
    np.testing.assert_array_equal(found.approach, reference.approach)
    np.testing.assert_array_equal(found.clearance_mm, reference.clearance_mm)
