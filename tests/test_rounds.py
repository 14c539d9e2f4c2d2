"""The sampler's rounds (:mod:`pinchmatch.grasp.rounds`), pinned with a grasp kind of our own: what
the loop draws, checks, counts and refuses, whatever the grasp."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh

from pinchmatch.errors import NoFeasiblePinchError
from pinchmatch.grasp import rounds
from pinchmatch.grasp.pinches import PinchSettings, Pinches
from pinchmatch.grasp.rounds import GraspKind, sample_rounds
from pinchmatch.mesh.surface import SurfaceContext

RULES = ("near", "reach")


def _pinches(points, faces):
    n = len(points)
    return Pinches(points=points, normals=np.zeros((n, 2, 3)), face_index=faces,
                   kappa_max_per_m=np.zeros((n, 2)), kappa_min_per_m=np.zeros((n, 2)),
                   dir_max=np.zeros((n, 2, 3)), feasible=np.ones(n, bool),
                   broken=np.zeros((n, 2), bool), snap_distance_mm=np.zeros((n, 2)),
                   approach=np.zeros((n, 3)), approach_clearance_mm=np.zeros(n))


class Recorder:
    """A grasp kind whose candidates are each contact and a point 20 mm above it; ``keep`` says
    which checked candidates are feasible; every draw and check is recorded."""

    def __init__(self, keep=lambda points: np.ones(len(points), bool), first=None):
        self.draws, self.checks, self.keep, self.first = [], [], keep, first

    def draw(self, context, contacts, faces, settings, rng, rejected):
        self.draws.append(len(contacts))
        if self.first is not None and len(self.draws) == 1:
            contacts, faces = contacts[:self.first], faces[:self.first]
        rejected["reach"] += 3  # the draw's own rejections pass through as counted
        points = np.stack([contacts, contacts + [0.0, 0.0, 20.0]], axis=1)
        return points, np.stack([faces, faces], axis=1)

    def check(self, context, points, faces, settings, rejected, precheck):
        self.checks.append(len(points))
        ok = self.keep(points)
        rejected["near"] += int((~ok).sum())
        return _pinches(points[ok], faces[ok])

    def kind(self, **changes):
        return dataclasses.replace(GraspKind(
            name="test grasp", rules=RULES, oversample=4, max_draw_factor=10, max_rounds=6,
            stream=(9,), draw=self.draw, check=self.check, first_contacts=lambda p: p[:, 0],
            refusal=lambda source, drawn, rejected, settings,
            standing: f"{source}: none of {drawn} ({rejected})"), **changes)


@pytest.fixture(scope="module")
def context():
    return SurfaceContext(trimesh.creation.box((120.0, 80.0, 60.0)).subdivide().subdivide())


def test_every_candidate_feasible_gives_the_count_and_the_draws_own_counts(context):
    rec = Recorder()
    found = sample_rounds(rec.kind(), context, PinchSettings(count=100, seed=1), "box")
    assert len(found) == 100
    # max(oversample x count, 2000) first contacts, enough for every round
    assert rec.draws == [2000]
    assert found.rejected == {"near": 0, "reach": 3}


def test_a_single_candidate_is_sampled_and_none_is_refused_in_the_kinds_words(context):
    one = Recorder(first=1)
    found = sample_rounds(one.kind(max_draw_factor=1), context, PinchSettings(count=50, seed=1),
                          "box")
    assert len(found) == 1
    none = Recorder(first=0)
    with pytest.raises(NoFeasiblePinchError,
                       match=r"^box: none of 2000 \(\{'near': 0, 'reach': 3\}\)$"):
        sample_rounds(none.kind(), context, PinchSettings(count=50, seed=1), "box")


def test_where_few_picks_are_feasible_more_contacts_are_drawn_by_the_rounds_need(context):
    """One candidate in ten feasible (by its contact's x): the rounds go local, and each further
    draw asks for ``oversample`` times the round's picks, within the budget of ``max_draw_factor`` x
    count contacts."""
    rec = Recorder(keep=lambda p: (np.floor(p[:, 0, 0] * 7.0) % 10) == 0)
    settings = PinchSettings(count=300, seed=2)
    found = sample_rounds(rec.kind(), context, settings, "box")
    assert 0 < len(found) <= 300
    budget = 10 * 300
    assert len(rec.draws) >= 2 and rec.draws[0] == 2000 and sum(rec.draws) <= max(budget, 2000)
    assert all(n > 0 for n in rec.draws[1:])
    assert all(n % 4 == 0 or sum(rec.draws[:i + 1]) == budget
               for i, n in enumerate(rec.draws[1:], start=1))


def test_the_rounds_stop_only_when_no_pick_is_left(context, monkeypatch):
    """A pool of three candidates, one checked per round: the loop goes on while a round picks one,
    and ends with all three."""
    rec = Recorder(first=3)
    monkeypatch.setattr(rounds, "round_plan", lambda need, n_feasible, n_checked, round_,
                        spent=(0, 0): (1, False))
    monkeypatch.setattr(rounds, "stratified_checks", lambda pool, count,
                        check: ([], np.zeros((0, 2, 3))))
    found = sample_rounds(rec.kind(max_draw_factor=1), context, PinchSettings(count=10, seed=3),
                          "box")
    assert rec.checks == [1, 1, 1] and len(found) == 3
