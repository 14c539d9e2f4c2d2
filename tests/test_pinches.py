import dataclasses

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from pinchmatch import (ConfigError, NoFeasiblePinchError, PinchSettings, check_pinches,
                        sample_pinches)
from pinchmatch.grasp.pinches import RULES
from pinchmatch.mesh.surface import SurfaceContext
from pinchmatch.mesh import shapes
from conftest import finger_axes


@pytest.fixture(scope="module")
def box_ctx():
    return SurfaceContext(trimesh.creation.box(extents=(60.0, 40.0, 20.0)).subdivide_to_size(4.0))


@pytest.fixture(scope="module")
def box_pinches(box_ctx):
    return sample_pinches(box_ctx, settings=PinchSettings(count=300, seed=1))


def _distance_to_surface(mesh, points):
    """Distance to a fine sample of the mesh of our own (about 0.4 mm apart): within 0.05 mm of the
    mesh's."""
    n = int(min(2_000_000, mesh.area / 0.15))
    sample, _ = trimesh.sample.sample_surface(mesh, n, seed=7)
    d, _ = cKDTree(np.vstack([sample, mesh.vertices])).query(points, workers=-1)
    return d


def assert_rules_hold(mesh, pinches, settings, support=None):
    """Every rule, re-checked independently of the code under test, with literal tolerances;
    ``support`` (normal, height_mm), the plane the object stands on, worked out by the test: nothing
    of the hand below it."""
    assert pinches.feasible.all()
    p1, p2 = pinches.points[:, 0], pinches.points[:, 1]
    seg = p2 - p1
    width = np.linalg.norm(seg, axis=1)
    u = seg / width[:, None]
    assert np.all((width >= settings.min_width_mm) & (width <= settings.max_width_mm))
    cos_cone = np.cos(np.radians(settings.friction_cone_deg)) - 1e-9
    assert np.all(np.einsum("ij,ij->i", u, -pinches.normals[:, 0]) >= cos_cone)
    assert np.all(np.einsum("ij,ij->i", -u, -pinches.normals[:, 1]) >= cos_cone)
    # clearance: exact distance from each fingertip centre to the mesh (0.3 mm pad, 0.5 mm sample
    # spacing)
    r = settings.fingertip_radius_mm
    centres = (pinches.points + r * pinches.normals).reshape(-1, 3)
    _, dist, _ = trimesh.proximity.closest_point(mesh, centres)
    assert np.all(dist >= r - 0.3 - 0.5)
    # reach: the reported approach is a unit vector within the tilt of the plane perpendicular to
    # the pinch line, and both finger axes along it keep the finger radius from the exact mesh
    h = pinches.approach
    np.testing.assert_allclose(np.linalg.norm(h, axis=1), 1.0, atol=1e-9)
    assert np.all(np.abs(np.einsum("ij,ij->i", h, u))
                  <= np.sin(np.radians(settings.approach_tilt_deg)) + 1e-9)
    s = np.linspace(0.0, settings.finger_length_mm, 46)  # every mm along the finger
    fingers = finger_axes(h, u, settings.finger_splay_deg, 2)  # each leaned away from the other
    axis = (pinches.points + r
            * pinches.normals)[:, :, None, :] + s[None, None, :, None] * fingers[:, :, None, :]
    assert np.all(_distance_to_surface(mesh, axis.reshape(-1, 3)) >= settings.finger_radius_mm
                  - 0.3 - 0.5)
    # contacts on the surface
    _, on, _ = trimesh.proximity.closest_point(mesh, pinches.points.reshape(-1, 3))
    assert on.max() < 1e-6
    if support is not None:  # fingertips and fingers above the table, no hand from below it
        normal, height = support
        assert np.all(centres @ normal - height >= r - 0.3 - 1e-9)
        assert np.all(axis.reshape(-1, 3) @ normal - height >= settings.finger_radius_mm - 0.3
                      - 1e-9)
        assert np.all(fingers @ normal >= -1e-9)


def test_every_rule_holds_on_every_pose(box_ctx, box_pinches):
    assert len(box_pinches) == 300 and box_pinches.feasible.all()
    assert_rules_hold(box_ctx.mesh, box_pinches, PinchSettings())


def test_box_widths_are_its_extents(box_pinches):
    n1, n2 = box_pinches.normals[:, 0], box_pinches.normals[:, 1]
    np.testing.assert_allclose(n1, -n2, atol=1e-6)  # opposite faces
    seg = box_pinches.points[:, 1] - box_pinches.points[:, 0]
    across = np.abs(np.einsum("ij,ij->i", seg, n1))  # width measured along the face normal
    assert np.all(np.min(np.abs(across[:, None] - [60.0, 40.0, 20.0]), axis=1) < 1e-6)
    # every pair of opposite faces is used
    axis = np.argmax(np.abs(n1), axis=1)
    assert set(axis) == {0, 1, 2}


def test_same_seed_same_pinches_other_seed_other_pinches(box_ctx, box_pinches):
    again = sample_pinches(box_ctx, settings=PinchSettings(count=300, seed=1))
    np.testing.assert_array_equal(again.points, box_pinches.points)
    other = sample_pinches(box_ctx, settings=PinchSettings(count=300, seed=2))
    assert not np.array_equal(other.points, box_pinches.points)


def test_pinches_spread_over_the_whole_sphere():
    ctx = SurfaceContext(shapes.sphere(30.0, triangulation="regular", faces=20000).mesh)
    pinches = sample_pinches(ctx, settings=PinchSettings(count=400, seed=0))
    contacts = pinches.points.reshape(-1, 3) / 30.0
    probes = trimesh.creation.icosphere(subdivisions=2).vertices  # 162 directions
    nearest = np.degrees(np.arccos(np.clip(probes @ contacts.T, -1, 1))).min(axis=1)
    assert nearest.max() < 12.0  # nothing graspable left out
    # no clumps: no two pinches nearly the same (either finger order)
    a = pinches.points.reshape(len(pinches), 6)
    b = pinches.points[:, ::-1].reshape(len(pinches), 6)
    d = np.minimum(np.linalg.norm(a[:, None] - a[None], axis=-1),
                   np.linalg.norm(a[:, None] - b[None], axis=-1))
    d[np.diag_indices(len(d))] = np.inf
    assert d.min() > 2.0


def _slotted_block():
    block = trimesh.creation.box(extents=(60.0, 40.0, 40.0))
    slot = trimesh.creation.box(extents=(10.0, 60.0, 30.0))  # 10 mm wide: narrower than a finger
    slot.apply_translation((0, 0, 10.0))
    return trimesh.boolean.difference([block, slot], engine="manifold")


def test_no_pinch_inside_a_slot_narrower_than_a_finger():
    mesh = _slotted_block()
    ctx = SurfaceContext(mesh)
    pinches = sample_pinches(ctx, settings=PinchSettings(count=300, seed=0))
    inside_slot = (np.abs(pinches.points[..., 0]) <= 5.0 + 1e-6) & (
        pinches.points[..., 2] > -5.0 + 1e-6)
    assert not inside_slot.any()
    assert_rules_hold(mesh, pinches, PinchSettings())
    # the slot walls themselves, pinched from inside the slot: the fingertips do not fit
    given = check_pinches(ctx, [[-5.0, 0, 10]], [[5.0, 0, 10]])
    assert not given.feasible[0]
    assert "clearance" in given.broken_rules(0)


def test_two_parts_are_squeezed_together_but_no_finger_enters_the_gap():
    a = trimesh.creation.box(extents=(20.0, 20.0, 20.0))
    b = a.copy()
    b.apply_translation((23.0, 0, 0))  # 3 mm gap
    mesh = trimesh.util.concatenate([a, b])
    pinches = sample_pinches(SurfaceContext(mesh), settings=PinchSettings(count=200, seed=0))
    x = pinches.points[:, :, 0]
    assert not ((x > 10.0 + 1e-6) & (x < 13.0 - 1e-6)).any()  # no contact on a face inside the gap
    across = (x.min(axis=1) < -9.0) & (x.max(axis=1) > 32.0)  # the two outer faces: 43 mm apart
    assert across.any()
    np.testing.assert_allclose(np.abs(pinches.points[across, 1, 0] - pinches.points[across, 0, 0]),
                               43.0, atol=1e-6)
    assert_rules_hold(mesh, pinches, PinchSettings())


def test_no_feasible_pinch_says_which_rule():
    ctx = SurfaceContext(shapes.sphere(80.0, faces=5000).mesh)
    with pytest.raises(NoFeasiblePinchError,
                       match=r"ball: no feasible pinch .*width \d+.*--max-width-mm"):
        sample_pinches(ctx, settings=PinchSettings(count=50), source="ball")


def test_user_pinches_are_snapped_and_checked(box_ctx):
    given = check_pinches(box_ctx, [[-30.3, 0, 0], [-30.0, 0, 0]], [[30.2, 0, 0], [0, 20.0, 0]])
    np.testing.assert_allclose(given.points[0], [[-30, 0, 0], [30, 0, 0]], atol=1e-9)
    np.testing.assert_allclose(given.snap_distance_mm[0], [0.3, 0.2], atol=1e-9)
    assert given.feasible[0]
    assert given.broken_rules(1) == ["antipodal"]
    assert given.broken.shape == (2, len(RULES))


def test_without_embree_the_numpy_engine_gives_feasible_pinches(monkeypatch, caplog):
    import builtins

    from pinchmatch.mesh import surface

    real_import = builtins.__import__

    def no_embree(name, *args, **kwargs):
        if name.startswith("trimesh.ray.ray_pyembree") or name.startswith("embreex"):
            raise ImportError(name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_embree)
    monkeypatch.setattr(surface, "_EMBREE", None)
    mesh = trimesh.creation.box(extents=(30.0, 20.0, 10.0)).subdivide_to_size(5.0)
    with caplog.at_level("WARNING", logger="pinchmatch.mesh.surface"):
        ctx = SurfaceContext(mesh)
        assert SurfaceContext(mesh).ray_engine_name == "numpy"
    assert ctx.ray_engine_name == "numpy"
    assert caplog.text.count("embreex is not installed") == 1  # said once, at warning level
    pinches = sample_pinches(ctx, settings=PinchSettings(count=40, seed=0))
    assert len(pinches) == 40
    assert_rules_hold(mesh, pinches, PinchSettings())


# the documented bounds of every pinch setting (README, --help), at and just beyond each end
BOUNDS = [
    ("patch_radius_mm", [0.5, 50.0], [0.49, 50.1]),
    # with a 1 mm finger, which it must not be thinner than
    ("fingertip_radius_mm", [2.0, 25.0], [1.9, 25.1]),
    ("count", [1, 100_000], [0, 100_001, 3.0, True]),
    ("seed", [0, 2**63 - 1], [-1, 2**63, 1.5, False]),
    ("finger_radius_mm", [0.31, 8.0], [0.3, 8.01]),
    ("finger_length_mm", [5.0, 150.0], [4.9, 151.0]),
    ("approach_tilt_deg", [0.0, 89.9], [-0.1, 90.0]),
    ("finger_splay_deg", [0.0, 45.0], [-0.1, 45.1]),
    ("friction_cone_deg", [0.1, 89.9], [0.0, 90.0]),
    ("max_width_mm", [0.6, 300.0], [0.5, 300.1]),
    ("min_width_mm", [0.0], [-0.1]),
    ("snap_tolerance_mm", [0.01], [0.0]),
]


@pytest.mark.parametrize("name, good, bad", BOUNDS, ids=[b[0] for b in BOUNDS])
def test_every_setting_takes_its_documented_range_and_nothing_beyond(name, good, bad):
    other = {"finger_radius_mm": 1.0} if name == "fingertip_radius_mm" else {}
    for value in good:
        assert getattr(PinchSettings(**other, **{name: value}), name) == value
    for value in bad:
        with pytest.raises(ConfigError, match=f"--{name.replace('_', '-')}: got"):
            PinchSettings(**other, **{name: value})


def test_concatenated_pinches_keep_the_last_parts_rejections():
    from pinchmatch.grasp.pinches import concat_pinches

    box = SurfaceContext(trimesh.creation.box(extents=(60.0, 40.0, 20.0)).subdivide_to_size(4.0))
    parts = [check_pinches(box, [[-30.0, 0, 0]], [[30.0, 0, 0]]) for _ in range(3)]
    parts = [dataclasses.replace(p, rejected={"width": k}) for k, p in enumerate(parts)]
    assert concat_pinches(parts).rejected == {"width": 2}
    assert concat_pinches(parts, {"patch": 7}).rejected == {"patch": 7}
    assert len(concat_pinches(parts)) == 3


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_posed_prop_is_pinched_above_its_table_whatever_its_tilt(tmp_path, seed):
    """A box standing in a level at a generic pose (a random rotation, off the origin), and the same
    box held at a given height above a block (support_mm): every rule holds with the table worked
    out here from the pose and the vertices, and without the table some pinch would reach under
    it."""
    from scipy.spatial.transform import Rotation

    from pinchmatch import analyze_spec, candidate_poses
    from pinchmatch.mesh.manifest import ObjectSpec

    mesh = trimesh.creation.box(extents=(50.0, 34.0, 70.0))
    path = tmp_path / "box.stl"
    mesh.export(path)
    turn = Rotation.random(random_state=seed)
    pose = ((120.0, 40.0, -80.0), tuple(turn.as_quat()))
    normal = turn.inv().apply([0.0, 1.0, 0.0])  # the level's up, seen from the box's frame
    lowest = float((mesh.vertices @ normal).min())
    settings = PinchSettings(count=150, seed=seed)
    for support, height in (("auto", lowest), (lowest + 13.7, lowest + 13.7)):
        candidates = candidate_poses(analyze_spec(ObjectSpec(
            str(path), pose=pose, support=support)),
                                     settings=settings)
        assert len(candidates) > 40
        assert_rules_hold(mesh, candidates.pinches, settings, support=(normal, height))
    free = candidate_poses(analyze_spec(ObjectSpec(str(path), pose=pose)),
                           settings=settings).pinches
    tips = (free.points + settings.fingertip_radius_mm * free.normals) @ normal - lowest
    assert (tips.min(axis=1) < settings.fingertip_radius_mm - 0.3).any() or (
        free.approach @ normal < 0).any()


def test_a_support_is_reported_in_plain_rounded_numbers():
    from pinchmatch.mesh.support import SupportPlane

    plane = SupportPlane(np.array([0.1234567891, 0.99, 0.0]), np.float64(-33.123456), "pose")
    record = plane.as_dict()
    assert record == {"normal": [0.123457, 0.99, 0.0], "height_mm": -33.123, "source": "pose"}
    assert all(type(c) is float for c in record["normal"]) and type(record["height_mm"]) is float


def test_the_clearance_rule_decides_as_the_unbounded_distance_does():
    """The fingertip test asks the KD-tree only up to its threshold: the verdicts are those of the
    exact distance, on a mug turned at random, off the origin, at contacts anywhere (inside, the
    handle)."""
    from conftest import random_rigid, transformed
    from pinchmatch.config import CLEARANCE_TOLERANCE_MM
    from pinchmatch.grasp.pinches import clearance_broken
    from pinchmatch.mesh import vessels

    R, t = random_rigid(31)
    context = SurfaceContext(transformed(vessels.mug(), R, t))
    rng = np.random.default_rng(4)
    faces = rng.integers(0, len(context.mesh.faces), (3000, 2))
    points = np.einsum("nfk,nfkd->nfd", rng.dirichlet(np.ones(3), (3000, 2)),
                       context.mesh.triangles[faces])
    normals = context.mesh.face_normals[faces]
    settings = PinchSettings()
    broken = clearance_broken(context, points, normals, settings)
    centres = (points + settings.fingertip_radius_mm * normals).reshape(-1, 3)
    exact, _ = cKDTree(context.sample.points).query(centres)
    expected = ~(exact >= settings.fingertip_radius_mm - CLEARANCE_TOLERANCE_MM).reshape(
        -1, 2).all(axis=1)
    np.testing.assert_array_equal(broken, expected)
    assert 0.05 < broken.mean() < 0.95


def test_too_wide_refuses_a_wide_convex_object_and_leaves_a_wide_ring_to_sampling():
    from conftest import random_rigid, transformed
    from pinchmatch.grasp.analysis import _inner_hull_volume, too_wide

    R, t = random_rigid(23)
    settings = PinchSettings()  # the largest pinch: 100 mm
    # 140 mm across in every direction
    ball = transformed(shapes.sphere(70.0, faces=20_000).mesh, R, t)
    with pytest.raises(NoFeasiblePinchError,
                       match=r"ball: no feasible pinch: 1[34]\d x 1[34]\d x 1[34]\d mm"):
        too_wide(ball, settings, "ball")
    # a 200 mm ring whose tube a hand pinches (24 mm): its oriented box's least extent is 24 mm, and
    # a thick ring 104 mm across its tube and 264 mm wide is not convex either: sampling decides for
    # both
    too_wide(transformed(shapes.torus(88.0, 12.0, faces=20_000).mesh, R, t), settings, "ring")
    thick = transformed(shapes.torus(80.0, 52.0, faces=20_000).mesh, R, t)
    assert np.sort(thick.bounding_box_oriented.primitive.extents)[0] > 100.0
    too_wide(thick, settings, "thick ring")
    # the hull of a few thousand vertices bounds the whole hull's volume from below, closely on a
    # fine mesh
    for mesh in (ball, thick):
        inner, whole = _inner_hull_volume(mesh.vertices), mesh.convex_hull.volume
        assert 0.95 * whole < inner <= whole * (1.0 + 1e-9)
