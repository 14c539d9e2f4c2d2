"""pinchmatch select: the best K props of a shelf for a scene (pinchmatch.match.select) and its
command."""

import itertools
import json
import math

import numpy as np
import pytest

from pinchmatch.match import select
from pinchmatch.mesh.shapes import ellipsoid

from conftest import run_cli


def _brute(cost, noticeable, k, objective):
    """The best k-subset by trying every one, written independently of the module: (value, mean,
    subset)."""
    servable = np.isfinite(cost).any(axis=1)
    c, q = cost[servable], noticeable[servable]
    best = None
    for subset in itertools.combinations(range(cost.shape[1]), k):
        sub = c[:, subset]
        pick = np.argmin(sub, axis=1)
        if objective == "noticeable":
            # a quiet prop first, when the object has one among the chosen
            for j in range(len(sub)):
                quiet = [i for i in range(k) if not q[j, subset[i]] and np.isfinite(sub[j, i])]
                if quiet:
                    pick[j] = min(quiet, key=lambda i: (sub[j, i], i))
        own = sub[np.arange(len(sub)), pick]
        mean = own.mean()
        if objective == "mean":
            value = mean
        elif objective == "max":
            value = own.max()
        else:
            value = (float(q[:, subset][np.arange(len(sub)), pick].sum()) if np.isfinite(own).all()
                     else np.inf)
        if best is None or (value, mean) < best[:2]:
            best = (value, mean, subset)
    return best


def _random_case(seed, m=9, n=7):
    rng = np.random.default_rng(seed)
    cost = rng.gamma(2.0, 1.0, (m, n))
    cost[rng.random((m, n)) < 0.1] = np.inf  # some registrations refused
    cost[0] = np.inf  # an object no prop serves
    return cost, rng.random((m, n)) < cost / 4.0


@pytest.mark.parametrize("objective", select.OBJECTIVES)
@pytest.mark.parametrize("seed", range(6))
def test_the_exhaustive_answer_is_the_brute_force_one(objective, seed):
    cost, loud = _random_case(seed)
    for k in range(1, cost.shape[1] + 1):
        s = select.select_props(cost, loud, k, objective=objective)
        value, mean, subset = _brute(cost, loud, k, objective)
        assert s.exact and s.value == pytest.approx(value) and s.mean_cost == pytest.approx(mean)
        assert tuple(s.props) == subset  # the first of equals, in lexicographic order
        served = s.assigned >= 0
        assert (not served[0] and served[1:].all()
                == np.isfinite(cost[1:][:, s.props]).any(axis=1).all())
        if objective != "noticeable":  # each object's prop is its cheapest chosen one
            assert np.allclose(s.cost[served], cost[served][:, s.props].min(axis=1))


@pytest.mark.parametrize("objective", select.OBJECTIVES)
@pytest.mark.parametrize("seed", range(6))
def test_greedy_and_swaps_near_the_best_with_the_stated_guarantee(objective, seed, monkeypatch):
    cost, loud = _random_case(seed, m=14, n=9)
    monkeypatch.setattr(select, "EXACT_SUBSETS", 0)  # as for a shelf too large to try every subset
    for k in (2, 3, 4):
        s = select.select_props(cost, loud, k, objective=objective)
        value, mean, _ = _brute(cost, loud, k, objective)
        assert not s.exact and s.method == "greedy + swaps" and len(s.props) == k
        assert (s.value, s.mean_cost) >= (value - 1e-12, mean - 1e-12) or s.value > value
        if objective == "mean":  # facility location: the saving is at least (1 - 1/e) of the best
            c = cost[np.isfinite(cost).any(axis=1)]
            worst = np.where(np.isfinite(c), c, -np.inf).max(axis=1)
            saving = lambda v: (worst.mean() - v)  # noqa: E731
            if np.isfinite(s.value) and np.isfinite(value):
                assert saving(s.value) >= (1 - 1 / math.e) * saving(value) - 1e-12


@pytest.mark.parametrize("objective", select.OBJECTIVES)
def test_a_prop_added_to_the_shelf_never_makes_the_best_worse(objective):
    for seed in range(5):
        cost, loud = _random_case(seed)
        extra_cost, extra_loud = _random_case(seed + 100)
        bigger_cost = np.column_stack([cost, extra_cost[:, :1]])
        bigger_loud = np.column_stack([loud, extra_loud[:, :1]])
        for k in range(1, cost.shape[1] + 1):
            a = select.select_props(cost, loud, k, objective=objective)
            b = select.select_props(bigger_cost, bigger_loud, k, objective=objective)
            assert (b.value, b.mean_cost) <= (a.value, a.mean_cost)


@pytest.mark.parametrize("exact_limit", [200_000, 0])
@pytest.mark.parametrize("objective", select.OBJECTIVES)
def test_the_coverage_curve_never_rises(objective, exact_limit, monkeypatch):
    monkeypatch.setattr(select, "EXACT_SUBSETS", exact_limit)
    for seed in range(5):
        cost, loud = _random_case(seed, m=12, n=8)
        curve = select.coverage_curve(cost, loud, objective=objective)
        scores = [(s.value, s.mean_cost) for s in curve]
        assert [len(s.props) for s in curve] == list(range(1, 9))
        assert all(b <= a for a, b in zip(scores, scores[1:])), scores


def test_the_best_addition_and_the_props_that_would_help():
    cost = np.array([[1.0, 5.0, 0.2], [1.0, 0.5, 3.0], [2.0, 2.0, 2.0]])
    loud = cost >= 1.0
    s = select.select_props(cost, loud, 1, objective="mean")
    assert list(s.props) == [0]
    add, with_it = select.best_addition(cost, loud, s, "mean")
    assert add == 2 and with_it.mean_cost == pytest.approx((0.2 + 1.0 + 2.0) / 3)
    assert list(select.helpful_props(cost, s)) == [2, 1, -1]
    everything = select.select_props(cost, loud, 3, objective="mean")
    assert select.best_addition(cost, loud, everything, "mean") is None


@pytest.fixture
def shelf_and_scene(tmp_path):
    shelf, scene = tmp_path / "shelf", tmp_path / "scene"
    shelf.mkdir()
    scene.mkdir()
    # (a disc thick enough to be pinched at its rim as it lies on the table: its equator above a
    # fingertip's radius)
    for name, axes in {"long": (40, 12, 12), "ball": (20, 20, 20), "disc": (30, 30, 10)}.items():
        ellipsoid(axes, faces=900).mesh.export(shelf / f"{name}.stl")
    for name, axes in {"egg": (30, 20, 12), "orb": (22, 22, 22)}.items():
        ellipsoid(axes, faces=900).mesh.export(scene / f"{name}.stl")
    return shelf, scene


def test_select_writes_the_selection_and_the_chosen_props_matches(
    tmp_path, capsys, shelf_and_scene):
    shelf, scene = shelf_and_scene
    out = tmp_path / "out"
    code, stdout, err = run_cli(capsys, "select", "--tangible", shelf, "--virtual", scene, "-k", 2,
                                "--count", 120, "-o", out, "--jobs", 1)
    assert code == 0, err
    doc = json.loads((out / "selection.json").read_text())
    assert doc["schema"] == "pinchmatch.selection/1" and doc["selection"]["exact"]
    chosen = doc["selection"]["props"]
    assert len(chosen) == 2 and set(chosen) <= {"long.stl", "ball.stl", "disc.stl"}
    values = [c["value"] for c in doc["coverage"]]
    assert [c["k"] for c in doc["coverage"]] == [1, 2, 3] and values == sorted(values, reverse=True)
    matches = json.loads((out / "matches.json").read_text())
    assert [t["name"] for t in matches["tangibles"]] == sorted(
        chosen, key=["long.stl", "ball.stl", "disc.stl"].index) \
        or sorted(t["name"] for t in matches["tangibles"]) == sorted(chosen)
    # the chosen props' match gives every object the prop and cost the selection says
    by_name = {m["virtual"]: m for m in matches["matches"]}
    for o in doc["objects"]:
        assert by_name[o["virtual"]]["tangible"] == o["tangible"]
        assert by_name[o["virtual"]]["cost"] == pytest.approx(o["cost"], abs=1e-6)
    served = np.array([[np.inf if x is None else x for x in row]
                       for row in doc["served_matrix"]["values"]])
    columns = [doc["served_matrix"]["columns_tangible"].index(p) for p in chosen]
    assert doc["selection"]["mean_cost"] == pytest.approx(served[:, columns].min(axis=1).mean(),
                                                          abs=1e-5)
    assert (out / "figures"
            / "coverage.png").stat().st_size > 10_000 and (out / "index.html").is_file()
    assert "chosen props" in stdout


@pytest.mark.parametrize("argv, message", [
    (["-k", "0"], "choose between 1 and the 3 props"),
    (["-k", "4"], "choose between 1 and the 3 props"),
    (["-k", "1", "--normalize", "range"], "use --normalize jnd"),
    (["-k", "1", "--max-k", "0"], "--max-k 0"),
    (["-k", "1", "--one-to-one"], "unknown option --one-to-one"),
])
def test_bad_options_end_in_one_line_and_write_nothing(
    tmp_path, capsys, shelf_and_scene, argv, message):
    shelf, scene = shelf_and_scene
    out = tmp_path / "out"
    code, _, err = (run_cli(capsys, "select", "--tangible", shelf, "--virtual", scene, *argv, "-o",
                            out))
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()


def test_a_scene_with_no_usable_object_ends_in_one_line(tmp_path, capsys, shelf_and_scene):
    shelf, _ = shelf_and_scene
    flat = tmp_path / "flat.stl"
    flat.write_bytes(b"solid x\nendsolid x\n")
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "select", "--tangible", shelf, "--virtual", flat, "-k", 1,
                           "--count", 60, "-o", out, "--jobs", 1)
    assert code == 2 and "flat.stl" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()


def test_under_noticeable_the_matches_place_each_object_where_the_selection_does(
    tmp_path, capsys, shelf_and_scene):
    shelf, scene = shelf_and_scene
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "select", "--tangible", shelf, "--virtual", scene, "-k", 2,
                           "--count", 120, "--objective", "noticeable", "--max-k", 2, "-o", out,
                           "--jobs", 1, "--no-view")
    assert code == 0, err
    doc = json.loads((out / "selection.json").read_text())
    assert doc["selection"]["objective"] == "noticeable" and len(doc["coverage"]) == 2
    assert isinstance(doc["selection"]["value"], int)
    matches = {m["virtual"]: m for m in json.loads((out / "matches.json").read_text())["matches"]}
    for o in doc["objects"]:
        assert matches[o["virtual"]]["tangible"] == o["tangible"]
        assert matches[o["virtual"]]["cost"] == pytest.approx(o["cost"], abs=1e-6)
        # the pooled difference, noticed or not
        assert matches[o["virtual"]]["noticeable"] == o["noticeable"]


def test_the_coverage_table_shows_the_mean_once_under_the_mean_objective():
    from pinchmatch.export.selection import coverage_rows

    curve = [{"k": 1, "value": 2.5, "mean_cost": 2.5, "noticeable_count": 3, "exact": True,
              "props": ["a"]}]
    mean = coverage_rows({"settings": {"objective": "mean"}, "coverage": curve})
    assert mean[0] == ("K", "mean_cost", "noticeable", "exact", "props") and mean[1] == (
        1, 2.5, 3, "yes", "a")
    worst = coverage_rows({"settings": {"objective": "max"}, "coverage": curve})
    assert worst[0] == ("K", "max", "mean_cost", "noticeable", "exact", "props")


def test_one_prop_and_an_object_it_cannot_serve():
    cost = np.array([[0.4], [np.inf]])
    loud = np.array([[False], [True]])
    pick = select.select_props(cost, loud, 1)
    assert pick.props.tolist() == [0] and pick.assigned.tolist() == [0, -1]
    # an object served by no prop is not a noticed match
    assert pick.noticeable.tolist() == [False, False]


def test_an_object_noticed_on_the_first_prop_is_counted_noticed():
    cost = np.array([[0.4, 2.0], [1.5, 3.0]])
    loud = np.array([[False, True], [True, True]])
    pick = select.select_props(cost, loud, 1)
    assert pick.props.tolist() == [0] and pick.noticeable.tolist() == [False, True]
