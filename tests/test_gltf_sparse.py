"""Sparse accessors applied as the glTF specification says, over a grid of layouts: the base in
either of two buffers or none (zeros), buffer views and accessors at offsets, strided or packed,
index types, and sparse counts from one element to all; each read through the loader and compared
with positions composed here."""

import itertools
import json
import struct

import numpy as np
import pytest
import trimesh

from pinchmatch.mesh.gltf_apply import buffer_bytes, dense_accessor
from pinchmatch.mesh.load import load_mesh

INDEX_TYPES = {5121: "<u1", 5123: "<u2", 5125: "<u4"}


def _document(base_buffer, view_offset, accessor_offset, stride, index_type, changed, tmp_path):
    """A .gltf of one box whose positions are a sparse accessor; its buffers are files beside it.
    Returns (path, the positions expected)."""
    box = trimesh.creation.box(extents=(0.04, 0.05, 0.06))
    true = np.asarray(box.vertices, np.float32)
    n = len(true)
    rng = np.random.default_rng(changed * 7 + view_offset)
    at = np.sort(rng.choice(n, size=changed, replace=False))
    base = true.copy()
    if base_buffer is None:
        base[:] = 0.0
        at = np.arange(n) if changed == n else at
        if changed < n:  # zeros where not replaced: the expected positions follow
            true = base.copy()
            true[at] = np.asarray(box.vertices, np.float32)[at]
    else:
        base[at] += 0.5  # wrong where the sparse values replace them
    buffers = [bytearray(b"\x11" * 13), bytearray(b"\x22" * 5)]  # junk first: no view starts at 0
    views, accessors = [], []

    def put(buffer, data, view_stride=None):
        pad = view_offset
        buffers[buffer].extend(b"\x00" * (-len(buffers[buffer]) % 4) + b"\x33" * pad)
        view = {"buffer": buffer, "byteOffset": len(buffers[buffer]), "byteLength": len(data)}
        if view_stride:
            view["byteStride"] = view_stride
        buffers[buffer].extend(data)
        views.append(view)
        return len(views) - 1

    position = {"componentType": 5126, "count": n, "type": "VEC3", "min": true.min(0).tolist(),
                "max": true.max(0).tolist()}
    if base_buffer is not None:
        row = 12 if stride is None else stride
        raw = bytearray(b"\x44" * accessor_offset)
        for v in base:
            raw += v.tobytes() + b"\x55" * (row - 12)
        position.update(bufferView=put(base_buffer, bytes(raw), stride), byteOffset=accessor_offset)
    other = 1 - (base_buffer or 0)
    position["sparse"] = {"count": len(at),
                          "indices": {"bufferView": put(
                              other, b"\x66" * 4 + at.astype(INDEX_TYPES[index_type])
                                                        .tobytes()), "byteOffset": 4,
                                                        "componentType": index_type},
                          "values": {"bufferView": put(1 - other, b"\x77" * 8 + true[at].tobytes()),
                                     "byteOffset": 8}}
    accessors.append(position)
    faces = np.asarray(box.faces, "<u4").ravel()
    accessors.append({"bufferView": put(1 - (base_buffer or 0), faces.tobytes()),
                      "componentType": 5125, "count": len(faces), "type": "SCALAR"})
    for k, data in enumerate(buffers):
        (tmp_path / f"b{k}.bin").write_bytes(bytes(data))
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
           "accessors": accessors, "bufferViews": views,
           "buffers": [{"uri": f"b{k}.bin", "byteLength": len(b)} for k, b in enumerate(buffers)]}
    path = tmp_path / "box.gltf"
    path.write_text(json.dumps(doc))
    return path, true, doc


GRID = [case for case in itertools.product((0, 1, None), (0, 8), (0, 12), (None, 16),
                                           tuple(INDEX_TYPES), (1, 3, 8))
        if not (case[0] is None and (case[2] or case[3]))]


@pytest.mark.parametrize("base_buffer, view_offset, accessor_offset, stride, index_type, changed",
                         GRID)
def test_a_sparse_accessor_reads_as_its_dense_positions(
    tmp_path, base_buffer, view_offset, accessor_offset, stride,
                                                          index_type, changed):
    path, true, doc = (_document(base_buffer, view_offset, accessor_offset, stride, index_type,
                                 changed, tmp_path))
    dense = dense_accessor(doc, buffer_bytes(path, "gltf", doc), 0)
    np.testing.assert_array_equal(dense, true)
    if base_buffer is not None or changed == 8:
        # the box itself, through the whole loader (mm); its triangles
        # in the other buffer, read where that buffer starts
        loaded = load_mesh(path)
        np.testing.assert_allclose(loaded.mesh.bounds,
                                   np.array([[-20, -25, -30], [20, 25, 30]], float), atol=1e-4)


def test_a_sparse_accessor_past_its_buffer_is_one_line(tmp_path):
    from pinchmatch.errors import MeshError

    path, _, doc = _document(0, 0, 0, None, 5123, 3, tmp_path)
    # past the end of its buffer view
    doc["accessors"][0]["sparse"]["values"]["byteOffset"] = 10_000
    path.write_text(json.dumps(doc))
    with pytest.raises(MeshError) as refused:
        load_mesh(path)
    assert ("\n" not in str(refused.value) and "sparse" in str(refused.value)
            and str(path) in str(refused.value))


def test_a_sparse_accessor_naming_a_view_that_is_not_there_is_one_line(tmp_path):
    from pinchmatch.errors import MeshError

    path, _, doc = _document(0, 0, 0, None, 5123, 3, tmp_path)
    doc["accessors"][0]["sparse"]["indices"]["bufferView"] = len(doc["bufferViews"]) + 5
    path.write_text(json.dumps(doc))
    with pytest.raises(MeshError) as refused:
        load_mesh(path)
    assert "\n" not in str(refused.value) and str(path) in str(refused.value)


def test_morph_weights_on_a_mesh_whose_other_primitive_has_no_positions_apply_to_the_one_that_has(
        tmp_path):
    """A mesh with a default morph weight of 0.5 and two primitives: one with positions and a target
    moving them 20 mm along x, one with normals only (positions are optional in glTF). The first is
    moved half way, the second left as it is; nothing is refused."""
    from pinchmatch.mesh.gltf_apply import applied_glb

    box = trimesh.creation.box(extents=(0.04, 0.05, 0.06))
    positions = np.asarray(box.vertices, np.float32)
    shift = np.tile(np.float32([0.02, 0.0, 0.0]), (len(positions), 1))
    faces = np.asarray(box.faces, "<u4").ravel()
    blob = positions.tobytes() + shift.tobytes() + faces.tobytes() + positions.tobytes()
    n, size = len(positions), positions.nbytes
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": size},
             {"buffer": 0, "byteOffset": size, "byteLength": size},
             {"buffer": 0, "byteOffset": 2 * size, "byteLength": faces.nbytes},
             {"buffer": 0, "byteOffset": 2 * size + faces.nbytes, "byteLength": size}]
    vec3 = {"componentType": 5126, "count": n, "type": "VEC3"}
    accessors = [dict(vec3, bufferView=0, min=positions.min(0).tolist(),
                      max=positions.max(0).tolist()),
                 dict(vec3, bufferView=1, min=shift.min(0).tolist(), max=shift.max(0).tolist()),
                 {"bufferView": 2, "componentType": 5125, "count": len(faces), "type": "SCALAR"},
                 dict(vec3, bufferView=3)]
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"mesh": 0}], "meshes": [{"weights": [0.5], "primitives": [
               {"attributes": {"POSITION": 0}, "indices": 2, "targets": [{"POSITION": 1}]},
               {"attributes": {"NORMAL": 3}, "indices": 2}]}],
           "accessors": accessors, "bufferViews": views,
           "buffers": [{"uri": "b.bin", "byteLength": len(blob)}]}
    (tmp_path / "b.bin").write_bytes(blob)
    path = tmp_path / "morphed.gltf"
    path.write_text(json.dumps(doc))
    glb = applied_glb(path, "gltf", doc)
    (tmp_path / "applied.glb").write_bytes(glb)
    text_length = struct.unpack_from("<I", glb, 12)[0]
    applied = json.loads(glb[20:20 + text_length])
    first, second = applied["meshes"][0]["primitives"]
    assert "POSITION" not in second["attributes"] and "targets" not in second
    moved = dense_accessor(applied, buffer_bytes(tmp_path / "applied.glb", "glb", applied),
                           first["attributes"]["POSITION"])
    np.testing.assert_allclose(moved, positions + 0.5 * shift, atol=1e-7)
