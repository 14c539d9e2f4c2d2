"""Property-based fuzzing of the newer readers: manifests, weights files, ratings tables and levels.

Whatever they are given, they return a value or raise the reader's one-line error (ConfigError or
MeshError): never another exception, never a hang. ``PINCHMATCH_FUZZ_EXAMPLES`` lengthens the run.
"""

import json
import os

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

json_values = st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=8),
                           lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner,
                                                                                        max_size=4), max_leaves=12)


@FUZZ
@given(doc=st.dictionaries(st.sampled_from(["weights", "pooling", "schema", "fit"]), json_values, max_size=4)
       | json_values)
def test_weights_files(doc):
    try:
        weights, pooling, _ = read_weights_file(json.dumps(doc), "w.json")
    except PinchmatchError:
        return
    assert all(isinstance(v, float) for v in weights.values()) and pooling in (None, "quick", "sum")


RATINGS = ("rating,width_jnd,kmax_jnd,object\n6.2,0.1,0.2,a\n5.0,0.5,0.9,b\n3.1,1.2,0.3,c\n2.0,1.5,1.4,d\n"
           "4.4,0.8,0.4,e\n6.5,0.0,0.1,f\n").encode()


@FUZZ
@given(data=mutated(RATINGS))
def test_ratings_tables(data):
    try:
        table = read_ratings(data.decode("utf-8", errors="replace"), "r.csv")
        calibrate(table)
    except PinchmatchError:
        pass


MANIFEST = b'[defaults]\nunits = "mm"\n\n[[object]]\nfile = "prop.stl"\nname = "prop"\nmass_g = 120\n' \
           b'com_mm = [0, 0, 10]\nexclude = [{ center_mm = [0, 0, 20], radius_mm = 5 }]\n'


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


LEVEL = glb([{"name": "root", "children": [1, 2]}, {"name": "crate", "mesh": 0, "translation": [0.1, 0, 0]},
             {"name": "jar", "mesh": 0}], [0])


@FUZZ
@given(data=mutated(LEVEL))
def test_levels(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("l") / "level.glb"
    path.write_bytes(data)
    try:
        read_level(path)
    except PinchmatchError:
        pass
