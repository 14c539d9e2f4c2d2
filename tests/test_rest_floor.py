"""The least that a placement's rest gap can add to a pair's cost, which the search pools by: never
more than the exact charge of either finger order (pinches and tripods, both poolings, a prop
standing turned and off the origin), above zero for many pairs, and a search that pools by it
finds the brute-force best while evaluating fewer pairs."""

import numpy as np
import pytest

from pinchmatch.config import MatchSettings
from pinchmatch.grasp.analysis import analyze_object, analyze_prop
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.match import search as search_module
from pinchmatch.match.candidates import candidate_poses
from pinchmatch.match.rest import grasp_reach, hull_points, rest_floor
from pinchmatch.match.search import Search, cost_model, evaluate_pairs
from pinchmatch.mesh.shapes import cylinder, ellipsoid

from conftest import random_rigid, transformed


def _files(tmp):
    """A tall cylinder standing along the file's -y (the prop, read with that up), turned about it
    at random and moved off the origin; an ellipsoid turned at random and moved."""
    from scipy.spatial.transform import Rotation

    R = (Rotation.from_euler("y", 2.1) * Rotation.from_euler("x", np.pi / 2)).as_matrix()
    prop = transformed(cylinder(22.0, 150.0, faces=3000).mesh, R, np.array([130.0, -40.0, 75.0]))
    R, t = random_rigid(71)
    virtual = transformed(ellipsoid((30.0, 22.0, 14.0), faces=1300).mesh, R, t)
    for name, mesh in (("prop", prop), ("virtual", virtual)):
        mesh.export(tmp / f"{name}.stl")
    return tmp / "prop.stl", tmp / "virtual.stl"


@pytest.fixture(scope="module")
def pairs(tmp_path_factory):
    """{grasp: (the prop's candidates, standing on its table, the virtual object's)}."""
    prop, virtual = _files(tmp_path_factory.mktemp("floor"))
    out = {}
    for grasp, count in (("pinch", 70), ("tripod", 40)):
        settings = PinchSettings(count=count, seed=3, grasp=grasp)
        out[grasp] = (candidate_poses(analyze_prop(prop, up="-y"), settings=settings),
                      candidate_poses(analyze_object(virtual), settings=settings))
    return out


def _every_pair(T, V):
    return np.repeat(np.arange(len(T)), len(V)), np.tile(np.arange(len(V)), len(T))


@pytest.mark.parametrize("grasp", ["pinch", "tripod"])
@pytest.mark.parametrize("pooling", ["quick", "sum"])
def test_the_floor_is_at_most_the_exact_charge_of_either_finger_order(pairs, grasp, pooling):
    T, V = pairs[grasp]
    assert T.obj.context.support is not None
    model = cost_model(MatchSettings(pooling=pooling), [T, V])
    floor = rest_floor(T, V, model)
    bound = floor.block(0, len(T)).ravel()
    it, iv = _every_pair(T, V)
    orders = (False, True) if grasp == "pinch" else (False,)
    for swapped in orders:
        result = evaluate_pairs(T, V, it, iv, model=model, swapped=swapped)
        charge = result.rest_jnd ** 2 if pooling == "sum" else result.rest_jnd
        assert (bound <= charge * (1 + 1e-9) + 1e-12).all()
        # the exact cost holds the charge: the floor bounds the cost less its haptic part
        assert (result.cost >= bound * (1 - 1e-9)).all()
    # not vacuous: the tall prop's high pinches hold the small object well above the table
    assert (bound > 0).mean() > 0.2
    held = rest_floor(T, V, model, redirect=object())  # a fixed placement is charged nothing
    assert held is None


def test_the_reach_bounds_the_support_function_in_every_direction(pairs):
    """Against the hull's support function about each grasp's centroid, taken in 2,000 random
    directions: inside [inner, outer] always, and the inner bound met closely somewhere (the
    largest ball about the centroid touches a facet)."""
    _, V = pairs["pinch"]
    centroids = V.pinches.points.mean(axis=1)
    inner, outer = grasp_reach(V.obj, centroids)
    rng = np.random.default_rng(5)
    d = rng.normal(size=(2000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    points = hull_points(V.obj)
    support = (points @ d.T)[None].max(axis=1) - centroids @ d.T  # (k, directions)
    assert (support >= inner[:, None] - 1e-9).all() and (support <= outer[:, None] + 1e-9).all()
    assert (inner > 0).all()  # a pinch's centroid lies inside the ellipsoid
    assert np.median(support.min(axis=1) - inner) < 2.0


def test_a_search_pooled_by_the_floor_finds_the_brute_force_best_with_fewer_pairs(pairs,
                                                                                 monkeypatch):
    T, V = pairs["pinch"]
    settings = MatchSettings(distinct_mm=6.0)
    model = cost_model(settings, [T, V])
    monkeypatch.setattr(search_module, "MIN_POOL", 16)
    monkeypatch.setattr(search_module, "MAX_POOL", 16)
    asked = []
    real = search_module.evaluate_pairs

    def counted(*args, **kw):
        asked.append(len(args[2]))
        return real(*args, **kw)

    monkeypatch.setattr(search_module, "evaluate_pairs", counted)
    it, iv = _every_pair(T, V)
    brute = np.sort(real(T, V, it, iv, model=model).cost)

    def search():
        asked.clear()
        found = Search([T], [V], model, settings).choices(0, [0], 5)
        return [c.cost for c in found], sum(asked)

    costs, with_floor = search()
    assert costs[0] == pytest.approx(brute[0], rel=1e-12)
    assert costs == sorted(costs)
    monkeypatch.setattr(search_module, "rest_floor", lambda *a, **k: None)
    plain, without = search()
    assert plain == costs  # the same choices, bit for bit
    assert with_floor < without
