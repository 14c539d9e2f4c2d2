"""Property-based fuzzing of the newer readers: manifests, weights files, ratings tables and levels.

Whatever they are given, they return a value or raise the reader's one-line error (ConfigError or
MeshError): never another exception, never a hang. ``PINCHMATCH_FUZZ_EXAMPLES`` lengthens the run.
"""

import json
import os

import pytest
import trimesh
from hypothesis import HealthCheck, given, settings, strategies as st

from pinchmatch.errors import PinchmatchError
from pinchmatch.match.calibrate import calibrate, read_ratings, read_weights_file
from pinchmatch.mesh.gltf_check import check_hierarchy
from pinchmatch.mesh.load import read_level
from pinchmatch.mesh.manifest import read_manifest

from test_fuzz import mutated
from test_gltf_check import glb

EXAMPLES = int(os.environ.get("PINCHMATCH_FUZZ_EXAMPLES", "0")) or None
FUZZ = settings(max_examples=EXAMPLES or 40, deadline=None, derandomize=EXAMPLES is None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

json_values = st.recursive(st.none() | st.booleans() | st.floats() | st.integers()
                           | st.text(max_size=8),
                           lambda inner: st.lists(inner, max_size=4)
                           | st.dictionaries(st.text(max_size=8), inner, max_size=4),
                           max_leaves=12)


@FUZZ
@given(doc=st.dictionaries(st.sampled_from(["weights", "pooling", "schema", "fit"]), json_values,
                           max_size=4)
       | json_values)
def test_weights_files(doc):
    try:
        weights, pooling, _ = read_weights_file(json.dumps(doc), "w.json")
    except PinchmatchError:
        return
    assert all(isinstance(v, float) for v in weights.values()) and pooling in (None, "quick", "sum")


RATINGS = ("rating,width_jnd,kmax_jnd,object\n6.2,0.1,0.2,a\n5.0,0.5,0.9,b\n3.1,1.2,0.3,c\n"
           "2.0,1.5,1.4,d\n4.4,0.8,0.4,e\n6.5,0.0,0.1,f\n").encode()


@FUZZ
@given(data=mutated(RATINGS))
def test_ratings_tables(data):
    try:
        table = read_ratings(data.decode("utf-8", errors="replace"), "r.csv")
        calibrate(table)
    except PinchmatchError:
        pass


MANIFEST = (b'[defaults]\nunits = "mm"\n\n[[object]]\nfile = "prop.stl"\nname = "prop"\n'
            b'mass_g = 120\ncom_mm = [0, 0, 10]\n'
            b'exclude = [{ center_mm = [0, 0, 20], radius_mm = 5 }]\n')


@FUZZ
@given(data=mutated(MANIFEST))
def test_manifests(tmp_path_factory, data):
    folder = tmp_path_factory.mktemp("m")
    trimesh.creation.box(extents=(40.0, 30.0, 20.0)).export(folder / "prop.stl")
    (folder / "m.toml").write_bytes(data)
    try:
        read_manifest(folder / "m.toml")
    except PinchmatchError:
        pass


@FUZZ
@given(children=st.lists(st.lists(st.integers(-2, 12), max_size=3), min_size=1, max_size=12))
def test_level_hierarchies(children):
    nodes = [{"children": c} for c in children]
    try:
        check_hierarchy("l.glb", {"nodes": nodes})
    except PinchmatchError:
        return
    # accepted: a forest, so every node has at most one parent and the walk reached all of them
    parents = [k for c in children for k in c]
    assert len(parents) == len(set(parents)) and all(0 <= k < len(children) for k in parents)


LEVEL = glb([{"name": "root", "children": [1, 2]},
             {"name": "crate", "mesh": 0, "translation": [0.1, 0, 0]}, {"name": "jar", "mesh": 0}],
             [0])


@FUZZ
@given(data=mutated(LEVEL))
def test_levels(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("l") / "level.glb"
    path.write_bytes(data)
    try:
        read_level(path)
    except PinchmatchError:
        pass


EXTENSIONS = ["KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_mesh_quantization",
              "EXT_mesh_gpu_instancing", "KHR_materials_unlit", "KHR_texture_transform", "VENDOR_x"]


@FUZZ
@given(required=st.lists(st.sampled_from(EXTENSIONS) | st.text(max_size=12) | json_values,
                         max_size=3),
       node_extras=st.dictionaries(st.sampled_from(["extensions", "skin", "weights", "matrix"]),
                                   json_values, max_size=2),
       mesh_extras=st.dictionaries(st.sampled_from(["weights", "extensions"]), json_values,
                                   max_size=2),
       sparse=st.booleans())
def test_levels_with_extensions(tmp_path_factory, required, node_extras, mesh_extras, sparse):
    """Required extensions, node and mesh extras and sparse accessors in any combination: the level
    is read or refused in one line (the features the reader does not apply are named, never read as
    geometry)."""
    from test_gltf_check import _changed

    def change(doc):
        doc["extensionsRequired"] = required
        doc["nodes"][1].update(node_extras)
        doc["meshes"][0].update(mesh_extras)
        if sparse:
            doc["accessors"][0]["sparse"] = {"count": 1}

    path = tmp_path_factory.mktemp("x") / "level.glb"
    path.write_bytes(_changed(LEVEL, change))
    try:
        read_level(path)
    except PinchmatchError as exc:
        assert "\n" not in str(exc)


@FUZZ
@given(journal=json_values, manifest=json_values, run=json_values)
def test_received_control_folders(tmp_path_factory, journal, manifest, run):
    """A result folder received with any journal, manifest and run record in its control folder:
    finishing it touches nothing outside OUT and ends in a result or a one-line refusal."""
    from pinchmatch.export.folder import recover

    root = tmp_path_factory.mktemp("r")
    out, outside = root / "out", root / "outside"
    (out / ".pinchmatch" / "staging").mkdir(parents=True)
    outside.mkdir()
    (outside / "victim.txt").write_text("keep me")
    for name, value in (("commit.json", journal), ("manifest.json", manifest), ("run.json", run)):
        (out / ".pinchmatch" / name).write_text(json.dumps(value))
    try:
        recover(out)
    except PinchmatchError as exc:
        assert "\n" not in str(exc)
    assert (outside / "victim.txt").read_text() == "keep me" and outside.exists()


def test_a_received_key_with_a_line_break_is_named_on_one_line():
    """The example the fuzzing below found: a key holding a line break, under a number's field."""
    from pinchmatch.export.view import _checked_values

    with pytest.raises(PinchmatchError) as refused:
        _checked_values("matches.json: matches[0].cost", {"\n": ""}, "cost")
    assert "\n" not in str(refused.value) and "'\\n'" in str(refused.value)


@FUZZ
@given(value=json_values,
       field=st.sampled_from(["cost", "criteria", "landing", "alternatives", "position_mm",
                                                 "equivalent_tangibles", "redirection",
                                                 "p_noticed"]))
def test_received_matches_documents(tmp_path_factory, value, field):
    """Any JSON value in a field of a received matches.json: the page's data is made with numbers
    where the page shows numbers, or the document is refused in one line."""
    from pinchmatch.export.view import _checked_values

    try:
        _checked_values(f"matches.json: matches[0].{field}", value, field)
    except PinchmatchError as exc:
        assert "\n" not in str(exc)
        return
    text = json.dumps(value)
    assert ("<" not in text
            or field in ("criteria", "equivalent_tangibles", "landing", "redirection"))
