"""Where a guided tripod's fingers land (:mod:`pinchmatch.match.felt`): the thumb on each of its
points, the index and middle finger together on each of theirs (one offset for both), weighed by the
product of the thumb's and the pair's ring weights within the axis tolerance; at a turn and off the
origin, a tripod matched with a copy of itself feels nothing wherever the fingers land."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pinchmatch.grasp.analysis import analyze_object
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.match.candidates import candidate_poses
from pinchmatch.match.felt import FeltTables, felt_cost, landing_combos, landing_table, ring_weights
from pinchmatch.match.landing import LANDING_AXIS_DEG, disc_offsets
from pinchmatch.match.scene import match_scene
from pinchmatch.match.search import MatchSettings
from pinchmatch.mesh.shapes import box

SETTINGS = PinchSettings(count=100, seed=0, grasp="tripod")
#: thumb on the -y face of a 60 x 40 x 50 box, index and middle about 21 mm apart on the +y face (no
#: symmetry of the box maps it to itself)
TRIPOD_MM = np.array([[-2.0, -20.0, 0.0], [-12.0, 20.0, 3.0], [8.0, 20.0, -3.0]])
TURN = Rotation.from_euler("zyx", [-52.0, 33.0, 118.0], degrees=True).as_matrix()
SHIFT = np.array([-210.0, 95.0, 460.0])


def _tripod_on(tmp_path, name, mesh, points):
    path = tmp_path / f"{name}.stl"
    mesh.export(path)
    return candidate_poses(analyze_object(path), settings=SETTINGS,
                           given=(np.asarray(points)[None],))


def test_the_combinations_pair_every_point_and_couple_a_tripods_fingers():
    pinch, tripod = landing_combos(25, 2), landing_combos(25, 3)
    assert pinch.shape == (2, 625) and len({tuple(c) for c in pinch.T}) == 625
    assert tripod.shape == (3, 625)
    # index and middle finger on the same point of their discs
    np.testing.assert_array_equal(tripod[1], tripod[2])
    np.testing.assert_array_equal(tripod[:2], pinch)  # the thumb slowest, as a pinch's first finger
    assert landing_combos(1, 3).shape == (3, 1)


def test_a_tripods_fingers_land_with_one_offset_and_the_thumb_with_its_own(tmp_path):
    """On flat faces each finger lands where it is aimed: the thumb at its target plus its disc
    offset, the index and middle finger each at its own target plus one shared offset. The weights
    are the thumb's ring weight times the pair's where the axis from the thumb to the fingers'
    middle is within 14 degrees of the target's (worked out here from the offsets), else 0."""
    block = _tripod_on(tmp_path, "block", box((60.0, 40.0, 50.0), subdivide_mm=3.0).mesh, TRIPOD_MM)
    table = landing_table(block, 0, 5.0, SETTINGS)
    offsets = disc_offsets(5.0) @ table.frame  # (25, 3) in the object's frame
    a, b = np.divmod(np.arange(625), 25)
    assert table.hit.all()
    np.testing.assert_allclose(table.points[:, 0], TRIPOD_MM[0] + offsets[a], atol=1e-6)
    np.testing.assert_allclose(table.points[:, 1], TRIPOD_MM[1] + offsets[b], atol=1e-6)
    np.testing.assert_allclose(table.points[:, 2], TRIPOD_MM[2] + offsets[b], atol=1e-6)
    middle = TRIPOD_MM[1:].mean(axis=0)
    axis = middle + offsets[b] - (TRIPOD_MM[0] + offsets[a])
    target = (middle - TRIPOD_MM[0]) / np.linalg.norm(middle - TRIPOD_MM[0])
    within = axis @ target / np.linalg.norm(axis,
                                            axis=1) >= np.cos(np.radians(LANDING_AXIS_DEG)) - 1e-12
    assert 0 < (~within).sum() < 100
    w = ring_weights(5.0)
    np.testing.assert_allclose(table.weights, np.where(within, w[a] * w[b], 0.0), rtol=1e-12,
                               atol=1e-15)


@pytest.mark.parametrize("swapped", [False, True])
def test_a_tripod_on_a_turned_moved_copy_feels_nothing_wherever_it_lands(tmp_path, swapped):
    """The virtual object is the block turned and moved, its tripod the prop's carried along (the
    fingers given in the other order where ``swapped``): every one of the 625 landings lands on the
    same spot of the prop once placed, so the felt cost is nothing at every landing and none is
    missed."""
    mesh = box((60.0, 40.0, 50.0), subdivide_mm=3.0).mesh
    prop = _tripod_on(tmp_path, "prop", mesh, TRIPOD_MM)
    moved = mesh.copy()
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = TURN, SHIFT
    moved.apply_transform(M)
    seen = TRIPOD_MM @ TURN.T + SHIFT
    virtual = _tripod_on(tmp_path, "virtual", moved, seen[[0, 2, 1]] if swapped else seen)
    scene = match_scene([prop], [virtual], settings=MatchSettings(top_k=0), pinch_settings=SETTINGS)
    best = scene.matches[0].best
    assert best.swapped == swapped
    np.testing.assert_allclose(best.transform[:3, :3], TURN.T, atol=1e-6)
    felt = felt_cost(prop, virtual, best, scene.model, FeltTables(5.0, SETTINGS))
    assert felt.landings > 500 and felt.missed == 0 and felt.criteria_noticeable == ()
    # the nominal: about 2e-4, from the STL's float32 vertices
    assert felt.worst < 1e-3 and felt.expected < 1e-3
