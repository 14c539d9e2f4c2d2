"""The compiled patch fit agrees with a batched numpy version of the same method."""

import numpy as np
import pytest
import trimesh

from jet_reference import reference_patch_geometry
from pinchmatch.mesh import shapes, vessels
from pinchmatch.grasp.curvature import patch_geometry
from pinchmatch.mesh.surface import SurfaceContext


def _noisy_scan():
    mesh = shapes.ellipsoid(triangulation="random", faces=8000, seed=2).mesh.copy()
    rng = np.random.default_rng(5)
    mesh.vertices = mesh.vertices + rng.normal(0.0, 0.15, mesh.vertices.shape)
    return mesh


def _holed_sphere():
    mesh = shapes.sphere(25.0, triangulation="random", faces=6000).mesh.copy()
    keep = mesh.triangles_center[:, 2] < 15.0  # an open surface: contacts near the rim are lopsided
    mesh.update_faces(keep)
    return mesh


CASES = {
    "sphere, random": lambda: shapes.sphere(30.0, triangulation="random", faces=20000).mesh,
    "torus, regular": lambda: shapes.torus(triangulation="regular", faces=5000).mesh,
    "cylinder, coarse": lambda: shapes.cylinder(triangulation="regular", faces=800).mesh,
    "box edges": lambda: shapes.box().mesh,
    "noisy scan": _noisy_scan,
    "open surface": _holed_sphere,
    "thin wall (cup)": lambda: vessels.cup(),
}


@pytest.mark.parametrize("case", list(CASES))
def test_kernel_matches_numpy_reference(case):
    mesh = CASES[case]()
    context = SurfaceContext(mesh)
    rng = np.random.default_rng(0)
    faces = rng.integers(0, len(mesh.faces), 600)
    bary = rng.dirichlet(np.ones(3), 600)
    points = np.einsum("nk,nkd->nd", bary, mesh.triangles[faces])
    normals = mesh.face_normals[faces]
    got = patch_geometry(context, points, normals)
    want = reference_patch_geometry(context, points, normals, context.patch_radius_mm)
    np.testing.assert_array_equal(got.valid, want.valid)
    np.testing.assert_array_equal(got.n_samples, want.n_samples)
    np.testing.assert_allclose(got.point_mm, want.point_mm, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got.normal, want.normal, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got.rms_mm, want.rms_mm, rtol=1e-7, atol=1e-12)
    for field in ("kappa_max_per_m", "kappa_min_per_m"):
        np.testing.assert_allclose(getattr(got, field), getattr(want, field), rtol=1e-7, atol=1e-6)
    # principal directions are defined where the curvatures differ (not at umbilics), up to sign
    distinct = np.abs(want.kappa_max_per_m - want.kappa_min_per_m) > 1.0
    for field in ("dir_max", "dir_min"):
        cos = np.abs(np.einsum("ij,ij->i", getattr(got, field), getattr(want, field)))[distinct]
        assert np.all(cos > 1.0 - 1e-9)


def test_results_do_not_depend_on_chunking_or_threads(monkeypatch):
    from pinchmatch.grasp import curvature

    mesh = shapes.ellipsoid(triangulation="random", faces=6000).mesh
    context = SurfaceContext(mesh)
    points, faces = trimesh.sample.sample_surface(mesh, 700, seed=1)
    normals = mesh.face_normals[faces]
    together = patch_geometry(context, points, normals)
    from pinchmatch.cores import set_thread_budget

    monkeypatch.setattr(curvature, "CHUNK", 37)
    before = set_thread_budget(1)
    try:
        apart = patch_geometry(context, points, normals)
    finally:
        set_thread_budget(before)
    for field in together.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(together, field), getattr(apart, field))


def test_the_quartic_ridge_is_the_weighted_norm_over_the_disc():
    # c^T G c against the integral of (1 - rho^2)^2 q(u, v)^2 over the unit disc, divided by that
    # of (1 - rho^2)^2, by Gauss-Legendre in rho and equal steps in theta (exact for polynomials)
    from pinchmatch.grasp.jets import EXPONENTS, QUARTIC_GRAM

    x, w = np.polynomial.legendre.leggauss(12)
    rho, w_rho = 0.5 * (x + 1.0), 0.5 * w
    theta = np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False)
    r, t = np.meshgrid(rho, theta, indexing="ij")
    u, v = r * np.cos(t), r * np.sin(t)
    weight = (1.0 - r**2) ** 2 * r * w_rho[:, None] * (2.0 * np.pi / len(theta))
    rng = np.random.default_rng(3)
    for _ in range(5):
        c = rng.normal(size=len(EXPONENTS)) * np.array([i + j == 4 for i, j in EXPONENTS])
        q = sum(ck * u**i * v**j for ck, (i, j) in zip(c, EXPONENTS))
        assert c @ QUARTIC_GRAM @ c == pytest.approx(
            (weight * q**2).sum() / weight.sum(), rel=1e-10)
