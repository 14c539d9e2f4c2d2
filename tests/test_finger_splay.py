"""The hand's fingers form a V: each leans from the hand's approach, away from the other, and the
hand's web joins their ends. Checked at a random rotation, off the origin."""

import numpy as np
import pytest
import trimesh

from conftest import finger_axes, random_rigid, transformed
from pinchmatch import PinchSettings, sample_pinches
from pinchmatch.grasp.hand import Hand, _hand_free, finger_directions
from pinchmatch.mesh.surface import SurfaceContext
from test_pinches import assert_rules_hold


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _grasps(seed, fingers, n=40):
    """Random contacts off the origin and, for each, an approach within 30 deg of the plane across
    its pinch line (the thumb towards the others' middle)."""
    rng = np.random.default_rng(seed)
    points = rng.uniform(-150.0, 150.0, 3) + rng.normal(scale=30.0, size=(n, fingers, 3))
    u = _unit(points[:, 1:].mean(axis=1) - points[:, 0])
    across = _unit(np.cross(u, rng.normal(size=(n, 3))))
    lean = np.radians(rng.uniform(-30.0, 30.0, n))[:, None]
    return points, u, np.cos(lean) * across + np.sin(lean) * u


@pytest.mark.parametrize("fingers", [2, 3])
def test_each_finger_leans_the_splay_from_the_approach_away_from_the_thumb_or_the_others(fingers):
    points, u, h = _grasps(4, fingers)
    axes = finger_directions(points, h, Hand(finger_splay_deg=15.0))
    np.testing.assert_allclose(axes, finger_axes(h, u, 15.0, fingers), atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(axes, axis=2), 1.0, atol=1e-12)
    angle = np.degrees(np.arccos(np.clip(np.einsum("nfd,nd->nf", axes, h), -1.0, 1.0)))
    np.testing.assert_allclose(angle, 15.0, atol=1e-6)
    between = np.degrees(np.arccos(np.clip(np.einsum("nd,nd->n", axes[:, 0], axes[:, 1]), -1.0,
                                           1.0)))
    np.testing.assert_allclose(between, 30.0, atol=1e-6)
    # each in the plane of h and u; the thumb leans away from u, the others towards it
    np.testing.assert_allclose(np.einsum("nfd,nd->nf", axes, np.cross(h, u)), 0.0, atol=1e-9)
    along = np.einsum("nfd,nd->nf", axes, u) - np.einsum("nd,nd->n", h, u)[:, None]
    assert np.all(along[:, 0] < 0.0) and np.all(along[:, 1:] > 0.0)
    # side by side at 0; turned with the grasp
    np.testing.assert_allclose(finger_directions(points, h, Hand(finger_splay_deg=0.0)),
                               np.repeat(h[:, None], fingers, axis=1), atol=1e-12)
    R, t = random_rigid(9)
    np.testing.assert_allclose(finger_directions(points @ R.T + t, h @ R.T, Hand()), axes @ R.T,
                               atol=1e-9)


def test_the_web_between_the_fingers_ends_may_not_pass_through_the_object():
    # a sheet between the fingers: their ends past its edge, the hand gets out; ends over the sheet,
    # it does not
    R, t = random_rigid(11)
    sheet = transformed(trimesh.creation.box(extents=(200.0, 200.0, 2.0)), R, t)
    context = SurfaceContext(sheet)
    for inside, free in [(60.0, False), (30.0, True)]:
        # the contacts this far in from the edge at x = 100
        tips = np.array([[[100.0 - inside, 0.0, 9.0], [100.0 - inside, 0.0, -9.0]]])
        h = np.array([[1.0, 0.0, 0.0]])  # outwards, past the edge: the ends 45 mm on
        fingers = finger_directions(tips, h, Hand(finger_splay_deg=15.0))
        np.testing.assert_allclose(fingers[0, :, 2] * np.array([1.0, -1.0]),
                                   np.sin(np.radians(15.0)), atol=1e-12)
        got = _hand_free(context, tips @ R.T + t, fingers @ R.T, 45.0)[0]
        assert got == (inside < 45.0 * np.cos(np.radians(15.0))) == free, inside


def test_a_sheet_is_pinched_no_further_in_from_its_edge_than_a_finger_reaches():
    R, t = random_rigid(12)
    plate = trimesh.creation.box(extents=(240.0, 240.0, 2.5))
    settings = PinchSettings(count=200, seed=0)
    pinches = sample_pinches(SurfaceContext(transformed(plate, R, t)), settings=settings)
    local = (pinches.points - t) @ R
    across = np.abs(local[:, 0, 2] - local[:, 1, 2]) > 2.0  # one finger on each face
    assert across.sum() >= 50
    inside = 120.0 - np.abs(local[across][..., :2]).max(axis=2)  # from the nearest edge
    # the web at the fingers' ends lies past the edge: within a finger and a fingertip of it
    assert inside.max() <= settings.finger_length_mm + settings.fingertip_radius_mm
    assert inside.max() > settings.finger_length_mm / 2.0  # not only at the edge
    assert_rules_hold(transformed(plate, R, t), pinches, settings)
