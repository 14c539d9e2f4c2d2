"""Object manifests (per-object units, up, centre of mass, axis, mass, contact regions) and game
levels split into their nodes."""

import json
import textwrap

import numpy as np
import pytest
import trimesh

from pinchmatch import ConfigError, PinchSettings
from pinchmatch.grasp.analysis import analyze_spec
from pinchmatch.grasp.sampling import sample_pinches
from pinchmatch.match.candidates import candidate_poses
from pinchmatch.match.scene import match_scene
from pinchmatch.match.search import MatchSettings, evaluate_pairs
from pinchmatch.mesh.load import mesh_files
from pinchmatch.mesh.manifest import object_specs, read_manifest
from pinchmatch.mesh.shapes import stacked_prop

from conftest import assert_bad_input, run_cli
from levels import game_level


def write(path, text):
    path.write_text(textwrap.dedent(text))
    return path


@pytest.fixture
def props(tmp_path):
    """A box prop in mm and the same box as an asset in metres, y up."""
    box = trimesh.creation.box(extents=(60.0, 40.0, 20.0))
    box.export(tmp_path / "box_mm.stl")
    metres = box.copy()
    metres.apply_scale(0.001)
    # z up -> y up
    metres.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    metres.export(tmp_path / "box_m.obj")
    return tmp_path


def test_each_object_has_its_own_units_up_centre_of_mass_axis_and_mass(props):
    manifest = write(props / "props.toml", """
        [defaults]
        units = "m"
        up = "y"

        [[object]]
        file = "box_mm.stl"
        name = "box in mm"
        units = "mm"
        up = "z"
        com_mm = [5, 0, -2]
        axis = [0, 1, 0]
        mass_g = 350

        [[object]]
        file = "box_m.obj"
    """)
    mm, m = read_manifest(manifest)
    assert (mm.units, mm.up, mm.com_mm, mm.axis, mm.mass_g) == (
        "mm", "z", (5.0, 0.0, -2.0), (0.0, 1.0, 0.0), 350.0)
    assert (m.units, m.up, m.mass_g, m.name) == ("m", "y", None, None)
    a, b = analyze_spec(mm), analyze_spec(m)
    assert (a.name == "box in mm" and b.name == "box_m.obj" and a.mass_g == 350.0
            and b.mass_g is None)
    # both read as the same 60 x 40 x 20 mm box, the metre asset with y up
    np.testing.assert_allclose(np.ptp(a.loaded.mesh.vertices, axis=0), [60, 40, 20], atol=1e-6)
    np.testing.assert_allclose(np.ptp(b.loaded.mesh.vertices, axis=0), [60, 20, 40], atol=1e-6)
    np.testing.assert_allclose(b.loaded.up, [0, 1, 0])
    np.testing.assert_allclose(a.props.com_mm, [5, 0, -2])
    np.testing.assert_allclose(a.props.principal_axis, [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(b.props.com_mm, [0, 0, 0], atol=1e-9)


def test_every_problem_of_a_manifest_is_one_line_naming_file_object_and_key(props, capsys):
    manifest = write(props / "bad.toml", """
        [[object]]
        file = "box_mm.stl"
        name = "lid"
        unit = "mm"
        mass_g = -3
        exclude = [{ center_mm = [0, 0], radius_mm = 5 }]

        [[object]]
        file = "missing.stl"
        up = "sideways"
        only = [{ min_mm = [0, 0, 0], max_mm = [1, -1, 1] }]

        [[object]]
        file = "box_m.obj"
        split = "nodes"
    """)
    with pytest.raises(ConfigError) as info:
        read_manifest(manifest)
    lines = str(info.value).splitlines()
    want = [("object 1 (lid): unit", "did you mean 'units'?"),
            ("object 1 (lid): mass_g", "above 0"),
            ("object 1 (lid): exclude[0]", "center_mm = [x, y, z]"), ("object 2: up", "'sideways'"),
            ("object 2: only[0]", "below max_mm"), ("object 2: file", "no such file"),
            ("object 3: split", "only a glTF or GLB scene")]
    assert len(lines) == len(want), lines
    for line, (where, what) in zip(lines, want):
        assert line.startswith(f"{manifest}: {where}:") and what in line, line
    # the command line says the same, exit 2, before any work
    code, out, err = run_cli(capsys, "match", "--tangible", str(manifest), "--virtual",
                             str(props / "box_m.obj"), "-o", str(props / "out"))
    assert code == 2 and "Traceback" not in err and len(err.strip().splitlines()) == len(want)
    assert not (props / "out").exists()


@pytest.mark.parametrize("text, words", [
    ("[[object]\nfile = 'a.stl'", ["not valid TOML"]),
    ("[defaults]\nunits = 'mm'\n", ["lists no object"]),
    ("[[object]]\nname = 'x'\n", ["object 1 (x): file", "missing"]),
])
def test_malformed_manifests_are_refused_in_one_line(tmp_path, capsys, text, words):
    manifest = tmp_path / "m.toml"
    manifest.write_text(text)
    code, _, err = run_cli(capsys, "match", "--tangible", str(manifest), "--virtual", str(manifest),
                           "-o", str(tmp_path / "out"))
    assert_bad_input(code, err, str(manifest), *words)


def _box_context(regions_toml, tmp_path):
    trimesh.creation.box(extents=(60.0, 40.0,
                                  20.0)).subdivide_to_size(4.0).export(tmp_path / "box.stl")
    manifest = write(tmp_path / "box.toml", f"""
        [[object]]
        file = "box.stl"
        {regions_toml}
    """)
    (spec,) = read_manifest(manifest)
    return analyze_spec(spec)


def test_no_contact_falls_in_an_exclude_region(tmp_path):
    obj = _box_context("exclude = [{ center_mm = [30, 0, 0], radius_mm = 15 }, "
                       "{ min_mm = [-31, -25, -11], max_mm = [-20, 0, 11] }]", tmp_path)
    pinches = sample_pinches(obj.context, settings=PinchSettings(count=200))
    p = pinches.points.reshape(-1, 3)
    assert len(pinches) >= 150
    assert (np.linalg.norm(p - [30.0, 0.0, 0.0], axis=1) > 15.0).all()
    in_box = (p >= [-31, -25, -11]).all(axis=1) & (p <= [-20, 0, 11]).all(axis=1)
    assert not in_box.any()
    # without the regions, many pinches would use those places
    free = sample_pinches(analyze_spec(read_manifest(write(
        tmp_path / "free.toml", '[[object]]\nfile = "box.stl"\n'))[0]).context,
                          settings=PinchSettings(count=200)).points.reshape(-1, 3)
    assert (np.linalg.norm(free - [30.0, 0.0, 0.0], axis=1) <= 15.0).sum() > 20


def test_every_contact_falls_in_the_only_regions(tmp_path):
    # "the handle": only the two 60 x 20 mm side faces near x = 20..30, y = +-20
    obj = _box_context("only = [{ min_mm = [18, -21, -11], max_mm = [31, -19, 11] }, "
                       "{ min_mm = [18, 19, -11], max_mm = [31, 21, 11] }]", tmp_path)
    pinches = sample_pinches(obj.context, settings=PinchSettings(count=100))
    assert len(pinches) >= 50
    p = pinches.points.reshape(-1, 3)
    assert ((p[:, 0] >= 18) & (p[:, 0] <= 31) & (np.abs(np.abs(p[:, 1]) - 20.0) <= 1.0)).all()
    # most pinches go across the 40 mm between the two regions (the rest across the 20 mm
    # thickness, within one region's strip of the top and bottom faces)
    across = np.sign(pinches.points[:, 0, 1]) != np.sign(pinches.points[:, 1, 1])
    assert across.mean() > 0.5


def test_regions_that_leave_no_surface_say_so(tmp_path, capsys):
    # inside the box
    obj = _box_context("only = [{ center_mm = [0, 0, 0], radius_mm = 5 }]", tmp_path)
    with pytest.raises(Exception, match="contact regions leave no surface"):
        sample_pinches(obj.context, settings=PinchSettings(count=50))


def _with_mass(tmp_path, name, mass_g):
    text = f'[[object]]\nfile = "prop.stl"\nname = "{name}"\n' + (
        f"mass_g = {mass_g}\n" if mass_g else "")
    return candidate_poses(analyze_spec(read_manifest(write(tmp_path / f"{name}.toml", text))[0]),
                           settings=PinchSettings(count=120))


def test_the_mass_criterion_compares_torques_where_both_masses_are_known(tmp_path):
    stacked_prop(sections=48).export(tmp_path / "prop.stl")
    light, heavy, unknown = _with_mass(tmp_path, "light", 100), _with_mass(
        tmp_path, "heavy", 200), \
        _with_mass(tmp_path, "unknown", None)
    model = match_scene([light], [light], settings=MatchSettings()).model
    i = np.arange(len(light))
    # each pose on itself: identity, no offset mismatch
    same = evaluate_pairs(light, light, i, i, model=model)
    np.testing.assert_allclose(same.terms[:, 7], 0.0, atol=1e-12)
    np.testing.assert_allclose(evaluate_pairs(light, unknown, i, i, model=model).terms[:, 7], 0.0,
                               atol=1e-12)
    # twice the mass seen: the felt offset must double, so the mismatch is the offset itself,
    # |o_T|^2 / s^2 with s = max(22 % of |o_T|, 20 mm)
    doubled = evaluate_pairs(light, heavy, i, i, model=model)
    offset = np.linalg.norm(light.obj.props.com_mm - light.pinches.points.mean(axis=1), axis=1)
    scale = np.maximum(0.22 * offset, 20.0)
    np.testing.assert_allclose(doubled.terms[:, 7], offset**2 / scale**2, rtol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(doubled.mass_delta_mm, axis=1), offset, rtol=1e-6,
                               atol=1e-9)


def test_a_level_splits_into_its_nodes_in_world_coordinates(tmp_path):
    glb, expected = game_level()
    (tmp_path / "level.glb").write_bytes(glb)
    specs = object_specs([str(tmp_path / "level.glb")], option="--virtual", split="nodes")
    assert len(specs) == len(expected) >= 20
    assert sorted(s.node for s in specs) == sorted(expected)
    for spec in specs:
        path, world_m, _ = expected[spec.node]
        assert spec.node_path == path and spec.display_name == spec.node
        obj = analyze_spec(spec)
        got = np.unique(np.round(obj.loaded.mesh.vertices, 3), axis=0)
        np.testing.assert_allclose(got, np.unique(np.round(world_m * 1000.0, 3), axis=0), atol=2e-3)
        assert obj.loaded.watertight and obj.props.volume_mm3 > 0  # the mirrored crate too
    # the same file, not split, is one object
    assert len(object_specs([str(tmp_path / "level.glb")], option="--virtual")) == 1


def test_a_level_run_names_each_node_and_its_path(tmp_path, capsys):
    glb, expected = game_level(crates=3, jars=2)
    (tmp_path / "level.glb").write_bytes(glb)
    stacked_prop(sections=48).export(tmp_path / "prop.stl")
    write(tmp_path / "props.toml", """
        [[object]]
        file = "prop.stl"
        name = "stack"
        mass_g = 120
    """)
    code, out, err = run_cli(capsys, "match", "--tangible", str(tmp_path / "props.toml"),
                             "--virtual", str(tmp_path / "level.glb"), "--split", "nodes",
                             "--count", "80", "-q", "--no-view", "--no-figures", "--jobs", "1",
                             "-o", str(tmp_path / "out"))
    assert code == 0, err
    doc = json.loads((tmp_path / "out" / "matches.json").read_text())
    virtuals = {v["name"]: v for v in doc["virtuals"]}
    assert set(virtuals) == set(expected)
    for name, (path, _, _) in expected.items():
        assert virtuals[name]["node"] == name and virtuals[name]["node_path"] == path
    assert doc["tangibles"][0]["name"] == "stack" and doc["tangibles"][0]["mass_g"] == 120.0
    assert {m["virtual"] for m in doc["matches"]} == set(expected)
    assert all(m["tangible"] == "stack" for m in doc["matches"])


def test_a_folder_holding_a_pinchmatch_result_is_not_read_as_input(tmp_path, capsys):
    trimesh.creation.box(extents=(60.0, 40.0, 20.0)).export(tmp_path / "box.stl")
    out = tmp_path / "pinchmatch-out"
    argv = ["match", "--tangible", str(tmp_path / "box.stl"), "--virtual", str(tmp_path), "--count",
            "60", "-q", "--no-view", "--no-figures", "-o", str(out)]
    assert run_cli(capsys, *argv)[0] == 0
    assert list((out / "scenes").glob("*.glb"))  # outputs that a folder search would find
    assert mesh_files([tmp_path], option="--virtual") == [tmp_path / "box.stl"]
    assert run_cli(capsys, *argv)[0] == 0
    assert ([v["name"] for v in json.loads((out / "matches.json").read_text())["virtuals"]]
            == ["box.stl"])
    code, _, err = run_cli(capsys, "match", "--tangible", str(tmp_path / "box.stl"), "--virtual",
                           str(out), "-o", str(tmp_path / "again"))
    assert_bad_input(code, err, str(out), "holds a pinchmatch result")


def test_the_documented_manifest_follows_the_schema_and_reads(tmp_path):
    import re
    import tomllib
    from pathlib import Path

    import jsonschema

    docs = Path(__file__).parents[1] / "docs"
    block = re.search(r"```toml\n(.*?)```", (docs / "manifest.md").read_text(), re.S).group(1)
    schema = json.loads((docs / "manifest.schema.json").read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    jsonschema.validate(tomllib.loads(block), schema)
    for name in re.findall(r'file = "([^"]+)"', block):  # the files it names, here
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        if name.endswith(".glb"):
            (tmp_path / name).write_bytes(game_level(crates=1, jars=1)[0])
        else:
            trimesh.creation.box(extents=(60.0, 40.0, 20.0)).export(tmp_path / name)
    write(tmp_path / "props.toml", block)
    can, mug, level = read_manifest(tmp_path / "props.toml")
    assert (can.name, can.mass_g, can.units, mug.units, level.split) == (
        "can", 350.0, "mm", "m", "nodes")
    assert len(can.regions.exclude) == 1 and len(mug.regions.only) == 1
    # what read_manifest refuses, the schema refuses too
    for bad in ('[[object]]\nfile = "a.stl"\nunit = "mm"\n',
                '[[object]]\nfile = "a.stl"\nmass_g = 0\n',
                '[[object]]\nfile = "a.stl"\naxis = [0, 0, 0]\n',
                '[[object]]\nfile = "a.stl"\nsplit = "parts"\n',
                '[[object]]\nfile = "a.stl"\nonly = [{ center_mm = [0, 0, 0] }]\n',
                '[defaults]\nunits = "mm"\n'):
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate(tomllib.loads(bad), schema)


def test_the_readme_python_example_runs(tmp_path, monkeypatch):
    import re
    from pathlib import Path

    code = re.search(r"## From Python\n\n```python\n(.*?)```",
                     (Path(__file__).parents[1] / "README.md").read_text(), re.S).group(1)
    mug = trimesh.creation.cylinder(radius=0.04, height=0.09, sections=32)  # metres, as glTF is
    mug.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))  # y up
    mug.export(tmp_path / "mug.glb")
    trimesh.creation.box(extents=(60.0, 40.0, 30.0)).export(tmp_path / "block.stl")
    # metres
    trimesh.creation.cylinder(radius=0.03, height=0.2, sections=32).export(tmp_path / "bottle.obj")
    stacked_prop(sections=32).export(tmp_path / "stack.stl")
    write(tmp_path / "props.toml", '[[object]]\nfile = "stack.stl"\nname = "stack"\nmass_g = 90\n')
    monkeypatch.chdir(tmp_path)
    scope = {}
    exec(compile(code, "README.md", "exec"), scope)
    best = scope["best"]
    assert best.tangible_name == ["block.stl", "bottle.obj", "stack"][best.tangible]
    assert scope["scene"].matches[0].name == "mug.glb"
    # the choice carries its pinches: the same points as the candidates it indexes (refined ones
    # included)
    vm = scope["scene"].matches[0]
    tangibles, virtual = scope["scene"].objects(vm)
    t_points = tangibles[best.tangible].pinches.points[best.t_pose]
    v_points = virtual.pinches.points[best.v_pose][::-1 if best.swapped else 1]
    assert np.array_equal([best.tangible_pose.p1_mm, best.tangible_pose.p2_mm], t_points)
    assert np.array_equal([best.virtual_pose.p1_mm, best.virtual_pose.p2_mm], v_points)
    assert scope["obj"].mass_g == 350.0


def test_a_file_key_that_is_not_text_is_not_called_missing(tmp_path):
    from pinchmatch.mesh.manifest import read_manifest

    manifest = tmp_path / "m.toml"
    manifest.write_text("[[object]]\nfile = 42\n")
    with pytest.raises(ConfigError, match="42 is not a path; give the mesh file as text"):
        read_manifest(manifest)


def test_a_bad_node_of_a_level_is_named_with_its_file(tmp_path, capsys):
    """One node of a split level is a flat sheet: the run goes on with the others, and the failure
    names the file and the node."""
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box(extents=(0.05, 0.04, 0.03)), node_name="crate",
                       geom_name="crate")
    sheet = trimesh.Trimesh([[0, 0, 0], [0.05, 0, 0], [0, 0.05, 0], [0.05, 0.05, 0]],
                            [[0, 1, 2], [1, 3, 2]])
    scene.add_geometry(sheet, node_name="sheet", geom_name="sheet")
    (tmp_path / "level.glb").write_bytes(scene.export(file_type="glb"))
    stacked_prop().export(tmp_path / "prop.stl")
    code, _, err = run_cli(capsys, "match", "--tangible", str(tmp_path / "prop.stl"), "--virtual",
                           str(tmp_path / "level.glb"), "--split", "nodes", "-o",
                           str(tmp_path / "out"), "--count", "60", "--no-cache", "--no-figures",
                           "--no-view", "-q", "--jobs", "1")
    assert code == 3, err  # a result, with a failed object
    assert f"{tmp_path / 'level.glb'}#sheet" in err and "flat" in err
    doc = json.loads((tmp_path / "out" / "matches.json").read_text())
    assert [m["virtual"] for m in doc["matches"]] == ["crate"]
    assert "#sheet: the mesh is flat" in doc["failed"][0]["error"]


def test_a_sphere_region_meets_the_boxes_within_its_radius_wherever_it_is():
    from pinchmatch.mesh.regions import Region

    sphere = Region.sphere((10.0, 20.0, 30.0), 5.0)
    # unit boxes whose nearest corner or face is 0, 3, 4.9, 5.1 and 8 mm from the centre
    gaps = np.array([0.0, 3.0, 4.9, 5.1, 8.0])
    lo = np.stack([10.0 + gaps, np.full(5, 19.5), np.full(5, 29.5)], axis=1)
    hi = lo + [1.0, 1.0, 1.0]
    assert sphere.overlaps_boxes(lo, hi).tolist() == [True, True, True, False, False]
    corner = np.array([[13.0, 24.0, 30.0]])  # the nearest corner 3-4-0 from the centre: 5 mm
    assert sphere.overlaps_boxes(corner, corner + 1.0).tolist() == [True]
    assert sphere.overlaps_boxes(corner + 0.1, corner + 1.1).tolist() == [False]
    assert sphere.contains(np.array([[13.0, 24.0, 30.0], [13.1, 24.0, 30.0]])).tolist() == [
        True, False]


@pytest.mark.parametrize("entry, support",
                         [('support = "none"', "none"), ('support = "auto"', "auto"),
                                            ("support_mm = 12.5", 12.5), ("", None)])
def test_a_manifest_says_what_a_prop_stands_on(tmp_path, entry, support):
    trimesh.creation.box(extents=(60.0, 40.0, 20.0)).export(tmp_path / "box.stl")
    (spec,) = read_manifest(write(tmp_path / "m.toml", f'[[object]]\nfile = "box.stl"\n{entry}\n'))
    assert spec.support == support
    assert spec.standing("auto").support == (support if support is not None else "auto")


@pytest.mark.parametrize("entry, words", [('support = "table"', ["support", "none"]),
                                          ('support = "none"\nsupport_mm = 3', ["not both"]),
                                          ('support_mm = "low"', ["support_mm", "height in mm"])])
def test_a_bad_support_is_one_line(tmp_path, capsys, entry, words):
    trimesh.creation.box(extents=(60.0, 40.0, 20.0)).export(tmp_path / "box.stl")
    manifest = write(tmp_path / "m.toml", f'[[object]]\nfile = "box.stl"\n{entry}\n')
    code, _, err = run_cli(capsys, "match", "--tangible", str(manifest), "--virtual",
                           str(tmp_path / "box.stl"), "-o", str(tmp_path / "out"))
    assert_bad_input(code, err, str(manifest), *words)
