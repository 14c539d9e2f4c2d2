"""pinchmatch design: the family of stacks (pinchmatch.mesh.stacks), the search
(pinchmatch.runner.design) and the command."""

import json
import re
import time

import numpy as np
import pytest
import trimesh
from conftest import run_cli

from pinchmatch.mesh import stacks
from pinchmatch.mesh.stacks import Part, Stack, stack_mesh, stack_problems
from pinchmatch.runner.design import DesignSettings, _repair, initial_stacks, mutate


def _every_kind():
    return [Stack((Part("cylinder", 30, 40),)), Stack((
        Part("box", 25, 30, turn_deg=20), Part("frustum", 40, 50, 20))),
            Stack((Part("barrel", 40, 60, 35), Part("cylinder", 20, 25), Part("box", 30, 20),
                   Part("frustum", 15, 18, 30)))]


@pytest.mark.parametrize("stack", _every_kind())
def test_every_stack_is_a_closed_manifold_solid_on_a_flat_base(stack):
    mesh = stack_mesh(stack)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    edges = np.sort(mesh.edges, axis=1)
    # manifold: each edge on two faces
    assert (np.unique(edges, axis=0, return_counts=True)[1] == 2).all()
    assert (mesh.bounds[0, 2] == pytest.approx(0.0) and mesh.bounds[1, 2]
            == pytest.approx(stack.height_mm))
    base = stacks.base_area_mm2(mesh)
    first = stack.parts[0]
    want = first.width_mm**2 if first.kind == "box" else np.pi * first.radius_at("bottom") ** 2
    assert base == pytest.approx(want, rel=0.01)  # the whole bottom face is flat on z = 0
    # the width at mid-height of each part is its own
    z = 0.0
    for part in stack.parts:
        section = mesh.section(plane_origin=[0, 0, z + part.height_mm / 2], plane_normal=[0, 0, 1])
        extent = 2.0 * np.linalg.norm(section.vertices[:, :2], axis=1).max()  # across the axis
        want = {"box": part.widest_mm, "barrel": part.width_mm}.get(
            part.kind, (part.width_mm + (part.top_width_mm or part.width_mm)) / 2)
        assert extent == pytest.approx(want, rel=0.02), part
        z += part.height_mm


def test_overhangs_are_measured_where_a_part_hangs_over_the_one_below():
    tower = stack_mesh(Stack((Part("cylinder", 30, 40), Part("frustum", 30, 40, 20))))
    assert stacks.overhang_area_mm2(tower) == pytest.approx(0.0, abs=1e-6)
    ledge = stack_mesh(Stack((Part("cylinder", 30, 20), Part("cylinder", 30, 40))))
    assert stacks.overhang_area_mm2(ledge) == pytest.approx(np.pi * (20**2 - 10**2), rel=0.01)


def test_supported_stacks_print_without_supports_and_only_shrink():
    """Random stacks of every kind, turned boxes on boxes, widening frusta and flat barrels
    included: reshaped, none has a downward face flatter than 45 degrees, each stays in the family's
    limits, and reshaping twice changes nothing."""
    rng = np.random.default_rng(11)
    for _ in range(120):
        parts = []
        for _ in range(int(rng.integers(1, 5))):
            kind, width, height = (str(rng.choice(stacks.PART_KINDS)), rng.uniform(12, 70),
                                   rng.uniform(12, 50))
            top = (rng.uniform(10, 0.9 * width) if kind == "barrel" else rng.uniform(10, 80)
                   if kind == "frustum" else None)
            parts.append(Part(kind, round(height, 1), round(width, 1),
                              None if top is None else round(top, 1),
                              rng.uniform(0, 90) if kind == "box" else 0.0))
        before = Stack(tuple(parts))
        after = stacks.supported(before)
        assert 1 <= len(after.parts) and stacks.supported(after) == after
        assert not stack_problems(after, max_height_mm=1e9, max_width_mm=1e9), after
        assert stacks.overhang_area_mm2(stack_mesh(after)) < 1e-6, after
        assert after.widest_mm <= before.widest_mm + 1e-9 and after.height_mm <= before.height_mm
    # what it keeps: a tower that already prints, and what it changes: a ledge, a box's corners, a
    # flat barrel
    tower = Stack((Part("cylinder", 30, 40), Part("box", 20, 28), Part("frustum", 30, 25, 12)))
    assert stacks.supported(tower) == tower
    assert stacks.supported(Stack((Part("cylinder", 30, 20),
                                   Part("cylinder", 30, 40)))).parts[1].width_mm < 20
    assert stacks.supported(Stack((Part("cylinder", 30, 40),
                                   Part("box", 20, 40)))).parts[1].width_mm <= 40 / 2**0.5
    flat = stacks.supported(Stack((Part("barrel", 20, 60, 20),))).parts[0]
    a, e = flat.width_mm / 2, (flat.top_width_mm or flat.width_mm) / 2
    assert a * a - e * e <= e * flat.height_mm / 2 + 1e-9


def test_repaired_and_mutated_stacks_stay_in_the_limits():
    s = DesignSettings(max_parts=3, max_height_mm=90.0, max_width_mm=60.0)
    rng = np.random.default_rng(4)
    stack = _repair(Stack((Part("box", 200, 90), Part("barrel", 5, 80, 90),
                           Part("frustum", 40, 3, 70), Part("cylinder", 40, 40))), s)
    for _ in range(300):
        assert not stack_problems(stack, max_height_mm=90.0, max_width_mm=60.0), stack
        assert len(stack.parts) <= 3
        stack = mutate(stack, rng, s)
    # seeded: the same changes in the same order
    a = [mutate(stack, np.random.default_rng(1), s) for _ in range(3)]
    b = [mutate(stack, np.random.default_rng(1), s) for _ in range(3)]
    assert a == b


def test_the_proxy_starts_from_the_scenes_pinch_widths():
    class V:  # candidates as the proxy reads them
        def __init__(self, widths):
            self.features = type("F", (), {"width_mm": np.asarray(widths, dtype=float)})()

        def __len__(self):
            return len(self.features.width_mm)

    starts = initial_stacks([V([20.0] * 50), V([60.0] * 5)], DesignSettings(max_parts=2))
    two = [s for s in starts if len(s.parts) == 2 and s.parts[0].kind == "cylinder"][0]
    # each object weighs the same, whatever its pose count
    assert [p.width_mm for p in two.parts] == [62.0, 22.0]


@pytest.fixture
def scene(tmp_path):
    """Two virtual objects that are themselves stacks of the family."""
    folder = tmp_path / "scene"
    folder.mkdir()
    for name, stack in {"tower": Stack((Part("cylinder", 40, 44), Part("cylinder", 40, 30))),
                        "post": Stack((Part("cylinder", 50, 32),
                                       Part("cylinder", 30, 44)))}.items():
        (folder / f"{name}.stl").write_bytes(stack_mesh(stack).export(file_type="stl"))
    return folder


def test_design_covers_a_scene_of_stacks_and_its_costs_are_a_match_runs(tmp_path, capsys, scene):
    out = tmp_path / "out"
    code, stdout, err = run_cli(capsys, "design", "--virtual", scene, "--count", 200,
                                "--evaluations", 12, "-o", out, "--jobs", 1, "--no-view")
    assert code == 0, err
    doc = json.loads((out / "design.json").read_text())
    assert doc["schema"] == "pinchmatch.design/1" and len(doc["props"]) == 1
    prop = doc["props"][0]
    assert prop["watertight"] and prop["winding_consistent"] and prop["height_mm"] <= 200.0
    assert prop["widest_mm"] <= 100.0 and prop["base_area_mm2"] > 100.0
    mesh = trimesh.load(out / prop["file"], force="mesh")
    assert mesh.is_watertight and mesh.bounds[0, 2] == pytest.approx(0.0)
    # near zero: the family holds the scene
    assert doc["mean_cost"] < 0.5 and doc["noticeable_count"] == 0
    # an independent match run of the scene against the written STL gives the same costs
    code, _, err = run_cli(capsys, "match", "--tangible", out / prop["file"], "--virtual", scene,
                           "--count", 200, "-o", tmp_path / "check", "--jobs", 1, "--no-view")
    assert code == 0, err
    check = {m["virtual"]: m["cost"]
             for m in json.loads((tmp_path / "check" / "matches.json").read_text())["matches"]}
    assert {o["virtual"]: o["cost"] for o in doc["objects"]} == pytest.approx(check, abs=1e-9)


def test_a_scene_in_metres_is_matched_on_the_props_designed_for_it(tmp_path, capsys, scene):
    """The props are written in mm standing on +Z and read back so, whatever the scene's --units and
    --up."""
    metres = tmp_path / "metres"
    metres.mkdir()
    for path in sorted(scene.glob("*.stl")):
        mesh = trimesh.load(path, force="mesh")
        mesh.apply_scale(0.001)
        mesh.export(metres / path.name)
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "design", "--virtual", metres, "--units", "m", "--count", 150,
                           "--evaluations", 8, "-o", out, "--jobs", 1, "--no-view")
    assert code == 0, err
    doc = json.loads((out / "design.json").read_text())
    assert len(doc["objects"]) == 2 and all(o["cost"] is not None for o in doc["objects"])
    # mm, as written
    assert trimesh.load(out / doc["props"][0]["file"], force="mesh").extents.max() > 20.0


def test_without_supports_every_candidate_and_the_output_print_standing(tmp_path, capsys, scene):
    s = DesignSettings(supports=False)
    rng = np.random.default_rng(2)
    stack = _repair(Stack((Part("cylinder", 30, 20), Part("box", 30, 60, turn_deg=30),
                           Part("barrel", 40, 60, 20))), s)
    for _ in range(100):
        assert stacks.overhang_area_mm2(stack_mesh(stack)) < 1e-6, stack
        stack = mutate(stack, rng, s)
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "design", "--virtual", scene, "--count", 150, "--evaluations", 8,
                           "--no-supports", "-o", out, "--jobs", 1, "--no-view")
    assert code == 0, err
    doc = json.loads((out / "design.json").read_text())
    assert doc["settings"]["supports"] is False
    assert all(p["overhang_area_mm2"] == 0 and p["printable_without_supports"]
               for p in doc["props"])


def test_design_is_deterministic_for_a_seed_and_a_count_of_evaluations(tmp_path, capsys, scene):
    written = []
    for run in ("a", "b"):
        code, _, err = run_cli(capsys, "design", "--virtual", scene, "--count", 120,
                               "--evaluations", 6, "-k", 2, "-o", tmp_path / run, "--jobs", 1,
                               "--no-view", "--seed", 3)
        assert code == 0, err
        written.append([(tmp_path / run / "props" / f"prop_{i}.stl").read_bytes() for i in (1, 2)])
    assert written[0] == written[1]


@pytest.mark.parametrize("argv, message", [
    (["-k", "0"], "-k 0"),
    (["--max-height-mm", "5"], "no part of the family is that low"),
    (["--max-width-mm", "4"], "no part of the family is that narrow"),
    (["--max-parts", "6"], "--max-parts 6"),
    (["--budget-s", "0.01"], "give more"),
    (["--normalize", "range"], "use --normalize jnd"),
])
def test_bad_design_options_end_in_one_line_and_write_nothing(
    tmp_path, capsys, scene, argv, message):
    out = tmp_path / "out"
    code, _, err = (run_cli(capsys, "design", "--virtual", scene, "--count", 100, *argv, "-o", out,
                            "--jobs", 1))
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()


def test_a_budget_shorter_than_a_candidate_is_refused_after_it_and_a_longer_one_is_the_searchs(
        tmp_path, capsys, scene, monkeypatch):
    """Each judged candidate takes 20 s of a fake clock. A 15 s budget cannot hold one: the run says
    so after judging it, and writes nothing. A 50 s budget is the search's own: two candidates fit
    in it (the second ends at 40 s, a third would end at 60 s); the finalists' ranking and the final
    match come after it."""
    from types import SimpleNamespace

    from pinchmatch.runner import design

    offset = [0.0]
    judged = []
    real_rows = design.Judge.prop_rows

    def slow_rows(self, stack, bound=float("inf"), order=None):
        if design._key(stack) not in self.rows:
            judged.append(stack)
            offset[0] += 20.0
        return real_rows(self, stack, bound, order)

    monkeypatch.setattr(design, "time",
                        SimpleNamespace(perf_counter=lambda: time.perf_counter() + offset[0]))
    monkeypatch.setattr(design.Judge, "prop_rows", slow_rows)
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "design", "--virtual", scene, "--count", 100, "--budget-s", 15,
                           "-o", out, "--jobs", 1)
    # the fake 20 s and the real judging time, which a loaded machine can stretch past a second
    said = re.search(r"judging one candidate takes (\d+\.\d) s", err)
    assert code == 2 and said and 20.0 <= float(said.group(1)) < 30.0, err
    assert len(judged) == 1
    assert not out.exists()
    judged.clear()
    code, _, err = run_cli(capsys, "design", "--virtual", scene, "--count", 100, "--budget-s", 50,
                           "-o", out, "--jobs", 1)
    assert code == 0, err
    # two on target within the budget, then both ranked again as finalists on top
    assert len(judged) == 4
    assert json.loads((out / "design.json").read_text())["search"]["evaluations"] == 2


def test_a_scene_with_no_usable_object_ends_in_one_line(tmp_path, capsys):
    empty = tmp_path / "empty.stl"
    empty.write_bytes(b"")
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "design", "--virtual", empty, "-o", out)
    assert (code == 2 and "empty.stl" in err and len(err.strip().splitlines()) == 1
            and not out.exists())


def test_giving_up_hopeless_candidates_keeps_the_search_s_answer(tmp_path, monkeypatch):
    """Four scene objects (stacks of the family and a ball), twelve candidates: the search that
    gives up a candidate once its objects' costs pass the finalists' bound finds the same best
    stack, with the same costs, as the search that judges every object of every candidate; and it
    does give some up."""
    from pinchmatch import MatchSettings, PinchSettings, analyze_object, candidate_poses
    from pinchmatch.runner import design

    shapes = {"tower": stack_mesh(Stack((Part("cylinder", 40, 44), Part("cylinder", 40, 30)))),
              "post": stack_mesh(Stack((Part("cylinder", 50, 32), Part("cylinder", 30, 44)))),
              "block": stack_mesh(Stack((Part("box", 30, 26),))),
              "ball": trimesh.creation.icosphere(subdivisions=3, radius=22.0)}
    settings = PinchSettings(count=120, seed=0)
    virtuals = []
    for name, mesh in shapes.items():
        mesh.export(tmp_path / f"{name}.stl")
        virtuals.append(candidate_poses(analyze_object(tmp_path / f"{name}.stl"),
                                        settings=settings))
    options = DesignSettings(evaluations=12, search_count=120)
    pruned = design.design_props(virtuals, options, match=MatchSettings(refine=False),
                                 pinch=settings)
    full_judge = design.Judge.judge
    monkeypatch.setattr(design.Judge, "judge", lambda self, stacks,
                        prune=False: full_judge(self, stacks))
    full = design.design_props(virtuals, options, match=MatchSettings(refine=False), pinch=settings)
    assert pruned.best.stacks == full.best.stacks
    np.testing.assert_array_equal(pruned.best.cost, full.best.cost)
    assert pruned.pruned > 0 and full.pruned == 0


def test_a_fitted_stack_follows_a_stacks_profile_wherever_it_stands_on_its_base():
    """A stack of a cylinder, a frustum and a narrower cylinder, turned about its up axis and moved:
    the fitted stack is as tall, and at every height its width is the original's within 1.5 mm (the
    profile's bins are 2.5 mm tall: a step between parts may fall inside one)."""
    from pinchmatch.mesh.stack_fit import fitted_stack

    truth = Stack((Part("cylinder", 40.0, 60.0), Part("frustum", 50.0, 60.0, 30.0),
                   Part("cylinder", 30.0, 30.0)))
    mesh = stack_mesh(truth)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(0.7, [0, 0, 1]))
    mesh.apply_translation([120.0, -45.0, 300.0])
    fitted = fitted_stack(mesh)

    def width_at(stack, z):
        bottom = 0.0
        for part in stack.parts:
            if z <= bottom + part.height_mm:
                share = (z - bottom) / part.height_mm
                return part.width_mm + share * ((part.top_width_mm or part.width_mm)
                                                - part.width_mm)
            bottom += part.height_mm
        return np.nan

    assert fitted.height_mm == pytest.approx(truth.height_mm, abs=0.5) and len(fitted.parts) <= 4
    heights = np.linspace(1.0, truth.height_mm - 1.0, 200)
    near_steps = np.isclose(heights[:, None], [40.0, 90.0], atol=3.0).any(axis=1)
    errors = np.abs([width_at(fitted, z) - width_at(truth, z) for z in heights])
    assert errors[~near_steps].max() < 1.5, errors.max()


def test_an_oblong_section_is_fitted_by_a_box_of_both_widths_and_repaired_within_the_limit():
    """A box 80 x 40 mm under a cylinder 30 mm across, turned 25 degrees about its up: the fit's
    lower part is a box of about 80 by 40 mm turned as the section is, the upper a round part;
    repaired for a 70 mm limit, the box keeps its proportions with its diagonal at the limit."""
    from pinchmatch.mesh.stack_fit import fitted_stack

    truth = Stack((Part("box", 40.0, 80.0, depth_mm=40.0), Part("cylinder", 40.0, 30.0)))
    mesh = stack_mesh(truth)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.radians(25.0), [0, 0, 1]))
    fitted = fitted_stack(mesh)
    low, high = fitted.parts[0], fitted.parts[-1]
    assert low.kind == "box" and abs(low.width_mm - 80.0) < 6.0 and abs(low.depth_mm - 40.0) < 4.0
    assert min(abs(low.turn_deg - 25.0), abs(low.turn_deg - 205.0)) < 3.0
    assert high.kind in ("cylinder", "frustum") and abs(high.width_mm - 30.0) < 2.0
    repaired = _repair(fitted, DesignSettings(max_width_mm=70.0))
    box = repaired.parts[0]
    assert np.hypot(box.width_mm, box.depth_mm) == pytest.approx(70.0, abs=0.2)
    assert box.width_mm / box.depth_mm == pytest.approx(low.width_mm / low.depth_mm, rel=0.01)


def test_the_search_starts_from_its_seeds(tmp_path, scene):
    """A seed stack is the first candidate judged: with one evaluation it is the design (repaired
    into the limits), and with more, the best found on target is never worse than it."""
    from pinchmatch import MatchSettings, PinchSettings, analyze_object, candidate_poses
    from pinchmatch.runner import design

    settings = PinchSettings(count=100, seed=0)
    virtuals = [candidate_poses(analyze_object(p), settings=settings)
                for p in sorted(scene.glob("*.stl"))]
    seed = Stack((Part("cylinder", 40, 44), Part("cylinder", 40, 30)))
    one = design.design_props(virtuals, DesignSettings(evaluations=1, search_count=100),
                              match=MatchSettings(refine=False, rank="nominal"), pinch=settings,
                              seeds=(seed,))
    assert one.best.stacks == (_repair(seed, DesignSettings()),)
    more = design.design_props(virtuals, DesignSettings(evaluations=6, search_count=100),
                               match=MatchSettings(refine=False, rank="nominal"), pinch=settings,
                               seeds=(seed,))
    assert more.best.score <= one.best.score
