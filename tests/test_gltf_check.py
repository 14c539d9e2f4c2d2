"""Levels that are not trees, or too deep, are refused in one line before trimesh reads them."""

import json
import struct
import time
import urllib.parse

import numpy as np
import pytest
import trimesh

from pinchmatch.cli.main import main
from pinchmatch.errors import MeshError
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.mesh.gltf_check import MAX_DEPTH, check_hierarchy
from pinchmatch.mesh.load import read_level

from conftest import assert_one_line


def glb(nodes: list[dict], scenes_roots: list[int]) -> bytes:
    """A GLB of one box mesh (metres) and the given nodes (each may carry ``mesh`` and
    ``children``)."""
    box = trimesh.creation.box(extents=(0.05, 0.04, 0.03))
    v = np.asarray(box.vertices, np.float32).tobytes()
    f = np.asarray(box.faces, np.uint32).ravel().tobytes()
    blob = v + f
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": scenes_roots}],
           "nodes": nodes,
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
           "buffers": [{"byteLength": len(blob)}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(v)},
                           {"buffer": 0, "byteOffset": len(v), "byteLength": len(f)}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(box.vertices),
                          "type": "VEC3", "min": box.vertices.min(axis=0).tolist(),
                          "max": box.vertices.max(axis=0).tolist()},
                         {"bufferView": 1, "componentType": 5125, "count": box.faces.size,
                          "type": "SCALAR"}]}
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack(
        "<I4s", len(blob), b"BIN\0") + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def chain(depth: int) -> list[dict]:
    """Nodes 0 -> 1 -> ... -> depth-1, the last holding the mesh, each moved 1 cm."""
    nodes = [{"name": f"n{i}", "translation": [0.01, 0, 0], "children": [i + 1]}
             for i in range(depth - 1)]
    return nodes + [{"name": f"n{depth - 1}", "mesh": 0}]


@pytest.mark.parametrize("nodes, roots, words", [
    ([{"name": "a", "mesh": 0, "children": [1]}, {"name": "b", "children": [0]}], [0], "cycle"),
    ([{"name": "a", "mesh": 0, "children": [0]}], [0], "of itself"),
    ([{"name": "a", "children": [2]}, {"name": "b", "children": [2]}, {"name": "c", "mesh": 0}],
     [0, 1], "child of two nodes"),
    ([{"name": "a", "mesh": 0, "children": [7]}], [0], "names child node 7"),
    ([{"name": "a", "mesh": 0, "children": ["1"]}], [0], "not a list of node indices"),
    (chain(MAX_DEPTH + 1), [0], f"nest more than {MAX_DEPTH} deep"),
])
@pytest.mark.parametrize("split", [True, False])
def test_a_level_that_is_not_a_bounded_tree_is_one_line(
    tmp_path, capsys, nodes, roots, words, split):
    level = tmp_path / "level.glb"
    level.write_bytes(glb(nodes, roots))
    argv = ["match", "--tangible", str(level) if not split else str(tmp_path / "prop.stl"),
            "--virtual", str(level), "--count", "60", "-q", "--no-cache", "-o",
            str(tmp_path / "out")]
    trimesh.creation.box(extents=(40.0, 30.0, 20.0)).export(tmp_path / "prop.stl")
    if split:
        argv += ["--split", "nodes"]
    t0 = time.perf_counter()
    assert main(argv) == 2
    assert time.perf_counter() - t0 < 30
    assert_one_line(capsys.readouterr().err, str(level), words)
    assert not (tmp_path / "out").exists()


def test_a_deep_but_bounded_level_is_read_in_reasonable_time(tmp_path):
    level = tmp_path / "deep.glb"
    level.write_bytes(glb(chain(MAX_DEPTH), [0]))
    t0 = time.perf_counter()
    nodes = read_level(level)
    assert time.perf_counter() - t0 < 20
    assert [n.name for n in nodes] == [f"n{MAX_DEPTH - 1}"]


def test_the_hierarchy_walk_is_linear_in_the_nodes():
    """100,000 nodes, a forest of short chains, checked in well under a second each way."""
    nodes = [{"children": [i + 1]} if i % 10 != 9 else {} for i in range(100_000)]
    t0 = time.perf_counter()
    check_hierarchy("big.glb", {"nodes": nodes})
    assert time.perf_counter() - t0 < 2.0
    with pytest.raises(MeshError, match="more than 100000"):
        check_hierarchy("big.glb", {"nodes": nodes + [{}]})


def test_a_gltf_buffer_uri_is_percent_decoded_as_the_specification_says(tmp_path):
    from pinchmatch.mesh.load import load_mesh

    files = trimesh.exchange.gltf.export_gltf(trimesh.Scene(trimesh.creation.box(extents=(
        0.04, 0.03, 0.02))))
    doc = json.loads(files["model.gltf"])
    for i, buffer in enumerate(doc["buffers"]):
        (tmp_path / f"a b{i}.bin").write_bytes(files[buffer["uri"]])
        buffer["uri"] = f"a%20b{i}.bin"
    (tmp_path / "m.gltf").write_text(json.dumps(doc))
    mesh = load_mesh(tmp_path / "m.gltf")
    # metres read as mm
    np.testing.assert_allclose(mesh.mesh.extents, [40.0, 30.0, 20.0], atol=1e-4)


def test_a_gltf_buffer_outside_its_folder_is_one_clear_line(tmp_path):
    from pinchmatch.mesh.load import load_mesh

    files = trimesh.exchange.gltf.export_gltf(trimesh.Scene(trimesh.creation.box(extents=(
        0.04, 0.03, 0.02))))
    doc = json.loads(files["model.gltf"])
    (tmp_path / "inner").mkdir()
    for i, buffer in enumerate(doc["buffers"]):
        (tmp_path / f"b{i}.bin").write_bytes(files[buffer["uri"]])
        buffer["uri"] = f"../b{i}.bin"
    (tmp_path / "inner" / "m.gltf").write_text(json.dumps(doc))
    with pytest.raises(MeshError, match="lies outside the file's folder"):
        load_mesh(tmp_path / "inner" / "m.gltf")


def test_a_bad_node_mesh_index_speaks_of_indices_not_of_vertices(tmp_path):
    from pinchmatch.mesh.load import load_mesh

    level = tmp_path / "bad.glb"
    level.write_bytes(glb([{"name": "a", "mesh": 5}], [0]))
    with pytest.raises(MeshError) as info:
        load_mesh(level)
    assert "a face refers to a vertex" not in str(info.value) and str(level) in str(info.value)


def test_a_level_whose_mesh_nodes_share_a_name_is_not_split_under_made_up_names(tmp_path):
    level = tmp_path / "dup.glb"
    level.write_bytes(glb([{"name": "crate", "mesh": 0, "translation": [0.1, 0, 0]},
                           {"name": "crate", "mesh": 0}],
                          [0, 1]))
    with pytest.raises(MeshError, match="several mesh nodes are named 'crate'"):
        read_level(level)


def _external_buffers(folder, uri, extents):
    """A box's glTF document whose buffers are external files, each named by the percent-encoded
    ``uri`` with its number (``a%20b0.bin`` is the file ``a b0.bin``)."""
    files = trimesh.exchange.gltf.export_gltf(trimesh.Scene(trimesh.creation.box(extents=extents)))
    doc = json.loads(files["model.gltf"])
    for i, buffer in enumerate(doc["buffers"]):
        name = uri.replace(".bin", f"{i}.bin")
        (folder / urllib.parse.unquote(name)).write_bytes(files[buffer["uri"]])
        buffer["uri"] = name
    return doc


def _box_gltf(folder, uri, extents):
    """A box as a .gltf with percent-encoded external buffers."""
    (folder / "m.gltf").write_text(json.dumps(_external_buffers(folder, uri, extents)))
    return folder / "m.gltf"


def _glb_with_external_buffer(folder, uri, extents):
    """A .glb whose JSON names its buffers as external files (no BIN chunk), as some exporters
    write."""
    chunk = json.dumps(_external_buffers(folder, uri, extents)).encode()
    chunk += b" " * (-len(chunk) % 4)
    body = struct.pack("<I4s", len(chunk), b"JSON") + chunk
    (folder / "m.glb").write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)
    return folder / "m.glb"


@pytest.mark.parametrize("kind", ["gltf", "glb"])
def test_the_cache_key_covers_every_buffer_the_loader_reads(tmp_path, kind):
    """A .gltf whose buffer URIs are percent-encoded, and a .glb with external buffers: another
    buffer under the same names (the document's bytes unchanged) gives another cache key, and the
    loader reads it."""
    from pinchmatch.mesh.load import load_mesh
    from pinchmatch.mesh.manifest import ObjectSpec
    from pinchmatch.runner.cache import FeatureCache

    cache, settings = FeatureCache(tmp_path / "cache"), PinchSettings(count=50)
    path = (_box_gltf if kind == "gltf" else _glb_with_external_buffer)(
        tmp_path, "a%20b.bin", (0.04, 0.03, 0.02))
    document = path.read_bytes()
    before = cache.key(ObjectSpec(str(path)), settings=settings)
    np.testing.assert_allclose(np.sort(load_mesh(path).mesh.extents), [20.0, 30.0, 40.0], atol=1e-3)
    # the buffers only: same names, same sizes
    _external_buffers(tmp_path, "a%20b.bin", (0.04, 0.03, 0.05))
    assert path.read_bytes() == document
    assert cache.key(ObjectSpec(str(path)), settings=settings) != before
    np.testing.assert_allclose(np.sort(load_mesh(path).mesh.extents), [30.0, 40.0, 50.0], atol=1e-3)


def test_a_glb_buffer_outside_its_folder_is_refused_as_a_gltfs(tmp_path):
    from pinchmatch.mesh.load import load_mesh

    (tmp_path / "inner").mkdir()
    (tmp_path / "victim").mkdir()
    path = _glb_with_external_buffer(tmp_path / "inner", "../victim/ext.bin", (0.04, 0.03, 0.02))
    with pytest.raises(MeshError, match="lies outside the file's folder"):
        load_mesh(path)


@pytest.mark.parametrize("damage, message", [
    ("huge chunk", "JSON chunk is over 64 MiB"),
    ("latin-1 name", "its JSON is not UTF-8"),
    ("cut chunk", "JSON chunk is cut short"),
])
def test_a_document_the_checks_cannot_read_is_refused_not_handed_on(tmp_path, damage, message):
    """The hierarchy check reads a level before trimesh does; what it cannot read (a JSON chunk
    declared over 64 MiB, a node name in Latin-1, a chunk cut short) is one line naming the file,
    never read unchecked."""
    from pinchmatch.mesh.load import load_mesh

    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           # a cycle, which the check would refuse
           "nodes": [{"name": "caf\u00e9", "children": [0]}]}
    chunk = json.dumps(doc, ensure_ascii=False).encode(
        "latin-1" if damage == "latin-1 name" else "utf-8")
    chunk += b" " * (-len(chunk) % 4)
    length = (65 * 2**20 if damage == "huge chunk" else len(chunk)
              + (64 if damage == "cut chunk" else 0))
    body = struct.pack("<I4s", length, b"JSON") + chunk
    (tmp_path / "level.glb").write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)
    with pytest.raises(MeshError, match=message) as info:
        load_mesh(tmp_path / "level.glb")
    assert "level.glb" in str(info.value) and "\n" not in str(info.value)


def _changed(data: bytes, change) -> bytes:
    """A GLB with its JSON document changed by ``change(doc)``, its binary chunk kept."""
    length = struct.unpack("<I", data[12:16])[0]
    doc = json.loads(data[20:20 + length])
    change(doc)
    rest = data[20 + length:]
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + rest
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


@pytest.mark.parametrize("change, words", [
    (lambda d: d.update(extensionsRequired=["KHR_draco_mesh_compression"]),
     "KHR_draco_mesh_compression (Draco"),
    (lambda d: d.update(extensionsRequired=["EXT_meshopt_compression"]),
     "EXT_meshopt_compression (meshopt"),
    (lambda d: d.update(extensionsRequired=["KHR_mesh_quantization"]),
     "KHR_mesh_quantization (quantized"),
    (lambda d: d.update(extensionsRequired=["VENDOR_unknown_thing"]),
     "the required extension VENDOR_unknown_thing"),
    (lambda d: d["nodes"][0].update(extensions={"EXT_mesh_gpu_instancing": {"attributes": {}}}),
     "GPU instancing"),
    (lambda d: d["nodes"][0].update(skin=0), "a skinned mesh on node 'box'"),
    (lambda d: d["nodes"][0].update(weights=[0.5]), "morph weights of its own on node 'box'"),
])
def test_gltf_features_the_reader_does_not_apply_are_refused_by_name(
    tmp_path, capsys, change, words):
    path = tmp_path / "level.glb"
    path.write_bytes(_changed(glb([{"name": "box", "mesh": 0}], [0]), change))
    with pytest.raises(MeshError, match="which pinchmatch does not apply") as info:
        read_level(path)
    assert words in str(info.value) and "\n" not in str(info.value)


def test_extensions_that_change_no_geometry_are_read():
    data = _changed(glb([{"name": "box", "mesh": 0}], [0]),
                    lambda d: d.update(extensionsRequired=[
                        "KHR_materials_unlit", "KHR_texture_transform"]))
    import tempfile
    from pathlib import Path
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "level.glb"
        path.write_bytes(data)
        (node,) = read_level(path)
        assert node.name == "box" and node.faces == 12


def _box_with_extra(extra_arrays, change):
    """The box GLB of :func:`glb` with ``extra_arrays`` appended to its binary chunk (a bufferView
    each, numbered from 2) and its document changed by ``change(doc)``."""
    data = glb([{"name": "box", "mesh": 0}], [0])
    length = struct.unpack("<I", data[12:16])[0]
    doc = json.loads(data[20:20 + length])
    blob = bytearray(data[20 + length + 8:])
    for array in extra_arrays:
        raw = np.ascontiguousarray(array).tobytes()
        doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(raw)})
        blob += raw + b"\0" * (-len(raw) % 4)
    doc["buffers"][0]["byteLength"] = len(blob)
    change(doc)
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack(
        "<I4s", len(blob), b"BIN\0") + bytes(blob)
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def test_sparse_accessors_and_default_morph_weights_are_applied(tmp_path):
    """A sparse accessor that moves every vertex to twice its place, and a morph target whose
    default weight 0.5 moves every vertex half its own offset again: the geometry read is the one
    the specification says (0.05 x 0.04 x 0.03 m box: doubled, then 1.5 times), not the base trimesh
    alone would read."""
    from pinchmatch.mesh.load import load_mesh

    box = trimesh.creation.box(extents=(0.05, 0.04, 0.03))
    n = len(box.vertices)
    indices = np.arange(n, dtype=np.uint16)
    doubled = np.asarray(2.0 * box.vertices, np.float32)
    delta = np.asarray(box.vertices, np.float32)

    def sparse(doc):
        doc["accessors"][0]["sparse"] = {"count": n,
                                         "indices": {"bufferView": 2, "componentType": 5123},
                                         "values": {"bufferView": 3}}
        doc["accessors"][0].update(min=(2 * box.vertices.min(axis=0)).tolist(),
                                   max=(2 * box.vertices.max(axis=0)).tolist())

    def morph(doc):
        doc["accessors"].append({"bufferView": 2, "componentType": 5126, "count": n, "type": "VEC3",
                                 "min": delta.min(axis=0).tolist(),
                                 "max": delta.max(axis=0).tolist()})
        doc["meshes"][0]["primitives"][0]["targets"] = [{"POSITION": 2}]
        doc["meshes"][0]["weights"] = [0.5]

    for name, arrays, change, scale in (("sparse", [indices, doubled], sparse, 2.0),
                                        ("morph", [delta], morph, 1.5)):
        path = tmp_path / f"{name}.glb"
        path.write_bytes(_box_with_extra(arrays, change))
        mesh = load_mesh(path).mesh
        np.testing.assert_allclose(np.sort(mesh.extents), scale * np.array([30.0, 40.0, 50.0]),
                                   atol=1e-3)
