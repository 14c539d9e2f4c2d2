"""Props known by their sizes: a manifest's ``shape`` builds the solid, in mm with +Z up."""

import json
import math
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
import trimesh

from pinchmatch.mesh.described import read_shape, shape_file
from pinchmatch.mesh.manifest import read_manifest

from conftest import assert_bad_input, run_cli

DOCS = Path(__file__).parents[1] / "docs"


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize("shape, extents, volume", [
    ({"kind": "cylinder", "diameter_mm": 54, "height_mm": 66}, (54, 54, 66),
     math.pi * 27 ** 2 * 66),
    ({"kind": "sphere", "diameter_mm": 60}, (60, 60, 60), 4 / 3 * math.pi * 30 ** 3),
    ({"kind": "box", "size_mm": [40, 30, 25]}, (40, 30, 25), 40 * 30 * 25),
    ({"kind": "frustum", "diameter_mm": 40, "top_diameter_mm": 0, "height_mm": 30}, (40, 40, 30),
     math.pi * 20 ** 2 * 30 / 3),
    ({"kind": "frustum", "diameter_mm": 40, "top_diameter_mm": 20, "height_mm": 30}, (40, 40, 30),
     math.pi * 30 / 3 * (20 ** 2 + 20 * 10 + 10 ** 2)),
    # the middle of an ellipsoid: a = 30, through (20, ±25), so c² = 25² / (1 - (20/30)²)
    ({"kind": "barrel", "diameter_mm": 60, "end_diameter_mm": 40, "height_mm": 50}, (60, 60, 50),
     math.pi * 30 ** 2 * (50 - 50 ** 3 / (12 * 25 ** 2 / (1 - (20 / 30) ** 2)))),
])
def test_each_kind_is_a_closed_solid_of_its_sizes_standing_on_z0(shape, extents, volume):
    stack, problems = read_shape(shape, "object 1")
    assert problems == []
    mesh = trimesh.load(shape_file(stack))
    assert mesh.is_volume
    assert np.allclose(mesh.extents, extents, atol=1e-6 * max(extents) + 1e-9) or \
        np.allclose(mesh.extents, extents, rtol=2e-3)  # 96-gons: a round part's width to 0.05 %
    assert mesh.bounds[0, 2] == pytest.approx(0.0, abs=1e-9)
    # a sphere: 32 segments pole to pole, -0.43 %
    assert mesh.volume == pytest.approx(volume, rel=5e-3)


def test_a_stack_rests_part_on_part_and_its_centre_of_mass_is_the_parts():
    stack, _ = read_shape([{"kind": "box", "size_mm": [40, 30, 25]},
                           {"kind": "cylinder", "diameter_mm": 20, "height_mm": 40}], "object 1")
    mesh = trimesh.load(shape_file(stack))
    box, cyl = 40 * 30 * 25, math.pi * 10 ** 2 * 40
    assert mesh.extents[2] == pytest.approx(65.0)
    assert mesh.volume == pytest.approx(box + cyl, rel=2e-3)
    assert mesh.center_mass[2] == pytest.approx((box * 12.5 + cyl * 45.0) / (box + cyl), rel=2e-3)


def test_the_same_sizes_give_the_same_file_and_others_another():
    a, _ = read_shape({"kind": "cylinder", "diameter_mm": 54, "height_mm": 66}, "x")
    b, _ = read_shape({"kind": "cylinder", "diameter_mm": 54.0, "height_mm": 66.0}, "y")
    c, _ = read_shape({"kind": "cylinder", "diameter_mm": 54, "height_mm": 67}, "z")
    assert shape_file(a) == shape_file(b) != shape_file(c)
    first = shape_file(a).read_bytes()
    shape_file(a).unlink()
    assert shape_file(a).read_bytes() == first


def test_a_shape_is_read_in_mm_with_z_up_whatever_the_defaults_say(tmp_path):
    manifest = write(tmp_path / "props.toml", '[defaults]\nunits = "m"\nup = "y"\nmass_g = 200\n\n'
                     '[[object]]\nname = "can"\nshape = { kind = "cylinder", diameter_mm = 54, '
                     'height_mm = 66 }\n'
                     'com_mm = [0, 0, 20]\n')
    (can,) = read_manifest(manifest)
    assert (can.name, can.units, can.up, can.mass_g, can.com_mm) == (
        "can", "mm", "z", 200.0, (0.0, 0.0, 20.0))
    assert can.manifest == str(manifest)


def test_a_described_can_serves_the_same_can_as_a_mesh_in_metres(tmp_path, capsys):
    """The described prop is the solid its sizes say: a can modelled in metres finds its twin, at no
    cost."""
    write(tmp_path / "props.toml", '[[object]]\nname = "can"\n'
                                   'shape = { kind = "cylinder", diameter_mm = 54, height_mm = 66 '
                                   '}\n'
                                   '[[object]]\nname = "ball"\nshape = { kind = "sphere", '
                                   'diameter_mm = 90 }\n')
    can = trimesh.creation.cylinder(radius=0.027, height=0.066, sections=96)
    can.export(tmp_path / "can.stl")
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", tmp_path / "props.toml", "--virtual",
                           tmp_path / "can.stl", "--units", "m", "-o", out, "--no-view", "--jobs",
                           1, "--count", 300)
    assert code == 0, err
    (match,) = json.loads((out / "matches.json").read_text())["matches"]
    assert match["tangible"] == "can"
    assert match["cost"] < 0.3 and not match["noticeable"]


@pytest.mark.parametrize("shape, words", [
    ('{ kind = "cylindre", diameter_mm = 54, height_mm = 66 }', "kind 'cylindre' is not a shape"),
    ('{ kind = "cylinder", diameter_mm = 54 }', "(missing: height_mm)"),
    ('{ kind = "cylinder", diameter_mm = 54, height_mm = 66, colour = 1 }', "(unknown: colour)"),
    ('{ kind = "cylinder", diameter_mm = -5, height_mm = 66 }',
     "diameter_mm must be from 1 to 1000 mm"),
    ('{ kind = "box", size_mm = [40, 30] }', "size_mm must be [across X, across Y, tall]"),
    ('{ kind = "barrel", diameter_mm = 40, end_diameter_mm = 50, height_mm = 30 }',
     "must be below its diameter"),
    ('[{ kind = "sphere", diameter_mm = 40 }, { kind = "sphere", diameter_mm = 40 }]',
     "a sphere stands alone"),
    ('[]', "give 1 to 8 parts"),
])
def test_a_bad_shape_is_one_line_naming_the_manifest_object_and_fix(tmp_path, capsys, shape, words):
    manifest = write(tmp_path / "props.toml", f'[[object]]\nname = "p"\nshape = {shape}\n')
    trimesh.creation.box(extents=(30, 30, 30)).export(tmp_path / "v.stl")
    out = tmp_path / "out"
    code, _, err = (run_cli(capsys, "match", "--tangible", manifest, "--virtual",
                            tmp_path / "v.stl", "-o", out))
    assert_bad_input(code, err, str(manifest), words)
    assert "object 1 (p): shape" in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()


@pytest.mark.parametrize("extra, words",
                         [('units = "m"\n', "drop units"), ('file = "a.stl"\n', "drop file"),
                                          ("", "a shape needs a name")])
def test_a_shape_with_a_file_s_keys_or_no_name_is_refused(tmp_path, extra, words):
    name = "" if not extra else 'name = "p"\n'
    manifest = write(tmp_path / "props.toml",
                     f'[[object]]\n{name}{extra}shape = {{ kind = "sphere", diameter_mm = 40 }}\n')
    with pytest.raises(Exception, match=re.escape(words)):
        read_manifest(manifest)


def test_the_documented_shapes_follow_the_schema_and_read(tmp_path):
    import jsonschema

    schema = json.loads((DOCS / "manifest.schema.json").read_text())
    text = (DOCS / "manifest.md").read_text()
    block = re.search(r"## A prop known by its sizes.*?```toml\n(.*?)```", text, re.S).group(1)
    jsonschema.validate(tomllib.loads(block), schema)
    can, tower = read_manifest(write(tmp_path / "props.toml", block))
    assert trimesh.load(tower.path).extents == pytest.approx((40, 30, 65), abs=1e-6)
    assert can.mass_g == 350.0
    for bad in ('[[object]]\nname = "p"\nunits = "m"\nshape = { kind = "sphere", diameter_mm = 4 '
                '}\n',
                '[[object]]\nshape = { kind = "sphere", diameter_mm = 4 }\n',
                '[[object]]\nname = "p"\nshape = { kind = "cylinder", diameter_mm = 4 }\n'):
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate(tomllib.loads(bad), schema)


def test_a_turned_box_is_the_box_turned_about_its_up(tmp_path):
    """A box of 40 x 30 x 25 mm turned 27 degrees: its corners are the unturned corners turned by
    +27 degrees about +Z (counter-clockwise seen from above), standing on z = 0; an oracle by
    trimesh's own rotation."""
    stack, problems = read_shape({"kind": "box", "size_mm": [40, 30, 25], "turn_deg": 27}, "a prop")
    assert not problems
    mesh = trimesh.load(shape_file(stack), force="mesh")
    oracle = trimesh.creation.box(extents=(40, 30, 25))
    oracle.apply_transform(trimesh.transformations.rotation_matrix(math.radians(27), [0, 0, 1]))
    oracle.apply_translation([0, 0, 12.5])
    corners = oracle.vertices
    # every corner of the oracle is a corner of the solid, and the solid's extents are the oracle's
    distance = np.linalg.norm(mesh.vertices[:, None, :] - corners[None], axis=2).min(axis=0)
    assert distance.max() < 1e-4, distance
    assert np.allclose(mesh.bounds, oracle.bounds, atol=1e-4)
    assert mesh.volume == pytest.approx(40 * 30 * 25, rel=1e-6)  # the STL holds float32


def test_a_described_solid_is_kept_per_user_checked_and_named_by_the_code_that_builds_it(
    tmp_path, monkeypatch):
    """The solid lives in a 0700 folder of this user's; a damaged file there is written again (not
    blamed on the manifest); a folder others may write is not used; other code gives another
    file."""
    import os
    import stat
    import tempfile

    from pinchmatch.mesh import described
    from pinchmatch.mesh.described import read_shape, shape_file

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    stack, problems = (read_shape({"kind": "cylinder", "diameter_mm": 54, "height_mm": 66},
                                  "props.toml"))
    assert not problems
    path = shape_file(stack)
    info = os.lstat(path.parent)
    assert (path.parent.name == f"pinchmatch-shapes-{os.getuid()}" and stat.S_IMODE(info.st_mode)
            == 0o700)
    whole = path.read_bytes()
    path.write_bytes(whole[:1000])  # a damaged file: rewritten
    assert shape_file(stack) == path and path.read_bytes() == whole
    path.unlink()
    os.chmod(path.parent, 0o777)  # a folder others may write: not trusted
    elsewhere = shape_file(stack)
    assert elsewhere.parent != path.parent and elsewhere.read_bytes() == whole and not path.exists()
    os.chmod(path.parent, 0o700)
    monkeypatch.setattr(described, "code_digest", lambda: "other code")
    assert shape_file(stack).name != path.name
