"""What in a level is furniture, not an object to pinch: left out of the match with one line
each."""

import json

import numpy as np
import pytest
import trimesh

from pinchmatch.mesh.furniture import furniture, principal_spans

from conftest import run_cli

TABLE_TOP_M = 0.76


def _table():
    """A table (metres, y up): a top 1.4 x 0.7 m, 40 mm thick, at 760 mm, on four legs."""
    parts = [trimesh.creation.box(extents=(1.4, 0.04, 0.7),
                                  transform=trimesh.transformations.translation_matrix([
                                      0, TABLE_TOP_M - 0.02, 0]))]
    for x in (-0.65, 0.65):
        for z in (-0.3, 0.3):
            parts.append(trimesh.creation.box(extents=(0.05, TABLE_TOP_M - 0.04, 0.05),
                                              transform=trimesh.transformations.translation_matrix(
                                                  [x, (TABLE_TOP_M - 0.04) / 2, z])))
    return trimesh.util.concatenate(parts)


def _on_table(mesh, x, z, sink_m=0.0):
    mesh = mesh.copy()
    mesh.apply_translation([x, TABLE_TOP_M - mesh.bounds[0, 1] - sink_m, z])
    return mesh


def _kitchen(turn_deg=0.0, offset=(0.0, 0.0, 0.0)):
    """A table, a wall behind it, a broom leaning on nothing, a saucer with a cup on it, a mug and a
    box standing on the table (one 3 mm into it, as scans do), all turned about the vertical and
    moved off the origin."""
    saucer = trimesh.creation.cylinder(radius=0.045, height=0.025, sections=32)
    saucer.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    cup = trimesh.creation.cylinder(radius=0.04, height=0.08, sections=32)
    cup.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    saucer = _on_table(saucer, 0.3, 0.1)
    cup.apply_translation([0.3, saucer.bounds[1, 1] - cup.bounds[0, 1], 0.1])
    broom = trimesh.creation.box(extents=(0.03, 0.03, 1.4))
    broom.apply_translation([1.2, 0.015, 0.0])  # lying on the floor, along z
    nodes = {"table": _table(),
             "wall": trimesh.creation.box(extents=(3.0, 2.0, 0.1),
                                          transform=trimesh.transformations.translation_matrix([
                                              0, 1.0, -0.6])),
             "saucer": saucer, "cup": cup, "broom": broom,
             "mug": _on_table(trimesh.creation.cylinder(radius=0.04, height=0.09).apply_transform(
                 trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0])), -0.3, 0.0,
                 sink_m=0.003),
             "box": _on_table(trimesh.creation.box(extents=(0.05, 0.07, 0.03)), 0.0, -0.1)}
    T = trimesh.transformations.rotation_matrix(np.radians(turn_deg), [0, 1, 0])
    T[:3, 3] = offset
    scene = trimesh.Scene()
    for name, mesh in nodes.items():
        scene.add_geometry(mesh, node_name=name, geom_name=f"{name}_mesh", transform=T)
    return scene


@pytest.mark.parametrize("turn_deg, offset", [(0.0, (0.0, 0.0, 0.0)), (35.0, (2.5, 0.4, -1.3))])
def test_tables_and_walls_are_furniture_objects_on_them_are_not(turn_deg, offset):
    survey = furniture(_kitchen(turn_deg, offset), mm_per_unit=1000.0, up=np.array([0.0, 1.0, 0.0]))
    found = survey.why
    assert set(found) == {"table", "wall"}, found
    assert "stand on it" in found["table"] and "mug" in found["table"] and "box" in found["table"]
    assert "cup" not in found["table"]  # on the saucer, not on the table
    assert "two directions" in found["wall"]
    # the table's top is the support of what stands on it, sunk or not; the cup stands on the saucer
    # (an object)
    top_mm = 1000.0 * (TABLE_TOP_M + offset[1])
    assert set(survey.tops_mm) == {"mug", "box", "saucer"}, survey.tops_mm
    for name in ("mug", "box", "saucer"):
        assert abs(survey.tops_mm[name] - top_mm) < 1e-6, (name, survey.tops_mm[name], top_mm)


def test_a_level_with_another_up_reads_its_own_up():
    """The same kitchen turned z-up (as a z-up exporter writes it): the same furniture with up =
    z."""
    scene = _kitchen()
    # y up -> z up
    scene.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    survey = furniture(scene, mm_per_unit=1000.0, up=np.array([0.0, 0.0, 1.0]))
    assert set(survey.why) == {"table", "wall"}, survey.why
    assert abs(survey.tops_mm["mug"] - 1000.0 * TABLE_TOP_M) < 1e-6
    sideways = furniture(scene, mm_per_unit=1000.0, up=np.array([0.0, 1.0, 0.0]))
    assert "stand" not in sideways.why.get("table", "") and not sideways.tops_mm


def test_principal_spans_do_not_depend_on_the_turn():
    rng = np.random.default_rng(2)
    v = rng.uniform(-1, 1, (500, 3)) * [700.0, 20.0, 150.0]
    R = trimesh.transformations.random_rotation_matrix(rng.random(3))[:3, :3]
    spans = principal_spans(v @ R.T + [300.0, -40.0, 9.0])
    np.testing.assert_allclose(spans, principal_spans(v), rtol=1e-9)
    assert spans[0] > 1300.0 and 250.0 < spans[1] < 350.0 and spans[2] < 50.0  # largest first


def test_a_side_table_under_400_mm_is_furniture_a_tray_under_300_is_not():
    """Things standing on a surface make it furniture once it spans more than SURFACE_SPAN_MM (300
    mm) in two directions: a 450 x 350 mm side table is, a 280 x 200 mm tray is not."""
    scene = trimesh.Scene()
    for name, extents, x in (("side_table", (0.45, 0.02, 0.35), 0.0),
                             ("tray", (0.28, 0.02, 0.20), 1.0)):
        top = trimesh.creation.box(extents=extents)
        top.apply_translation([x, 0.5, 0.0])
        scene.add_geometry(top, node_name=name, geom_name=name)
        cup = trimesh.creation.cylinder(radius=0.04, height=0.09).apply_transform(
            trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
        cup.apply_translation([x, 0.51 - cup.bounds[0, 1], 0.0])
        scene.add_geometry(cup, node_name=f"cup_on_{name}", geom_name=f"cup_on_{name}")
    found = furniture(scene, mm_per_unit=1000.0, up=np.array([0.0, 1.0, 0.0]))
    assert set(found.why) == {"side_table"}, found.why


def test_a_level_with_its_table_and_wall_left_in_matches_neither_and_names_both(tmp_path, capsys):
    _kitchen(20.0, (0.5, 0.0, 0.2)).export(tmp_path / "kitchen.glb")
    prop = trimesh.creation.cylinder(radius=30.0, height=100.0, sections=48)
    prop.export(tmp_path / "prop.stl")
    code, out, err = run_cli(capsys, "match", "--tangible", tmp_path / "prop.stl", "--virtual",
                             tmp_path / "kitchen.glb", "--split", "nodes", "--count", 100,
                             "--no-view", "--no-figures", "--jobs", 1, "--no-cache", "-o",
                             tmp_path / "out")
    assert code == 0, err
    doc = json.loads((tmp_path / "out" / "matches.json").read_text())
    matched = {m["virtual"] for m in doc["matches"]}
    assert matched == {"saucer", "cup", "broom", "mug", "box"}, matched
    # what stands on the table stands on its top: the mug sunk 3 mm into it too, the cup on its
    # saucer on its own
    supports = {o["name"]: o["support"] for o in doc["virtuals"]}
    top_mm = 1000.0 * TABLE_TOP_M
    for name in ("mug", "box", "saucer"):
        assert supports[name]["source"] == "furniture top", supports[name]
        np.testing.assert_allclose(supports[name]["normal"], [0.0, 1.0, 0.0], atol=1e-6)
        assert abs(supports[name]["height_mm"] - top_mm) < 1e-3, (name, supports[name])
    assert (supports["cup"]["source"] == "lowest point" and supports["cup"]["height_mm"] > top_mm
            + 20.0)
    said = " ".join((out + err).split())  # the console wraps long lines
    for name in ("table", "wall"):
        assert f"node {name} left out" in said and f"--nodes '{name}'" in said, said
    # named, the table comes back (and is matched or fails on its own merits)
    code, out, err = run_cli(capsys, "match", "--tangible", tmp_path / "prop.stl", "--virtual",
                             tmp_path / "kitchen.glb", "--split", "nodes", "--nodes", "table",
                             "--nodes", "mug", "--count", 100, "--no-view", "--no-figures",
                             "--jobs", 1, "--no-cache", "-o", tmp_path / "named")
    doc = json.loads((tmp_path / "named" / "matches.json").read_text())
    assert {m["virtual"] for m in doc["matches"]} | {f["path"].split("node ")[-1].rstrip(")")
                                                     for f in doc["failed"]} >= {"table", "mug"}
