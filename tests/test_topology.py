"""The loader's topology (pinchmatch.mesh.topology) gives trimesh's answers, order included."""

import numpy as np
import pytest
import trimesh

from pinchmatch.mesh import topology
from pinchmatch.mesh.load import MERGE_DIGITS, load_mesh
from pinchmatch.mesh.shapes import torus


def _soup(mesh: trimesh.Trimesh, rng) -> trimesh.Trimesh:
    """Every triangle with its own corners (as an STL holds them), a few nudged below the merge
    tolerance, the triangles shuffled."""
    tri = mesh.triangles[rng.permutation(len(mesh.faces))].reshape(-1, 3).copy()
    nudge = rng.random(len(tri)) < 0.05
    tri[nudge] += rng.uniform(-1, 1, (int(nudge.sum()), 3)) * 10.0 ** -(MERGE_DIGITS + 2)
    return trimesh.Trimesh(tri, np.arange(len(tri)).reshape(-1, 3), process=False)


def _cases():
    rng = np.random.default_rng(3)
    two = trimesh.util.concatenate([trimesh.creation.icosphere(3, radius=10.0),
                                    trimesh.creation.box((8.0, 6.0, 4.0)).apply_translation([30.0, 0, 0])])
    fin = trimesh.util.concatenate([trimesh.creation.box((10.0, 10.0, 10.0)),
                                    trimesh.Trimesh([[5, -5, 5], [5, 5, 5], [15, 0, 5]], [[0, 1, 2]])])  # open fin
    return [("torus", _soup(torus(triangulation="random", faces=3000, seed=1).mesh, rng)),
            ("two bodies", _soup(two, rng)), ("box with a fin", _soup(fin, rng)),
            ("open cylinder", _soup(_open_cylinder(), rng))]


def _open_cylinder() -> trimesh.Trimesh:
    """A cylinder without its top cap: an open surface."""
    cylinder = trimesh.creation.cylinder(5.0, 20.0, sections=48)
    keep = cylinder.face_normals[:, 2] < 0.5
    return trimesh.Trimesh(cylinder.vertices, cylinder.faces[keep], process=False)


@pytest.mark.parametrize("name, raw", _cases())
def test_every_answer_is_trimeshs(name, raw):
    ours, theirs = raw.copy(), raw.copy()
    theirs.merge_vertices()
    ours.update_vertices(*topology.merge_vertices(raw.vertices, raw.faces, MERGE_DIGITS))
    assert np.array_equal(ours.vertices, theirs.vertices) and np.array_equal(ours.faces, theirs.faces), name

    doubled = np.vstack([ours.faces, ours.faces[:7][:, [2, 1, 0]], ours.faces[3:5]])
    want = np.asarray(trimesh.Trimesh(ours.vertices, doubled, process=False).unique_faces())
    if want.dtype != bool:
        want = np.isin(np.arange(len(doubled)), want)
    assert np.array_equal(topology.unique_faces(doubled), want)

    e = topology.edges(ours.faces)
    adjacency = topology.face_adjacency(e)
    assert sorted(map(tuple, adjacency)) == sorted(map(tuple, np.sort(ours.face_adjacency, axis=1)))
    assert topology.watertight_and_wound(e) == (ours.is_watertight, ours.is_winding_consistent)
    labels = topology.component_labels(adjacency, len(ours.faces))
    assert np.array_equal(labels, trimesh.graph.connected_component_labels(ours.face_adjacency,
                                                                           node_count=len(ours.faces)))
    if ours.is_watertight:
        assert topology.signed_volumes(ours.vertices, ours.faces).sum() == pytest.approx(ours.volume, rel=1e-9)

    # one body turned inside out: the same faces turned back
    faces = ours.faces.copy()
    faces[labels == 0] = faces[labels == 0][:, ::-1]
    inside_out = trimesh.Trimesh(ours.vertices, faces, process=False)
    e = topology.edges(inside_out.faces)
    flip = topology.inverted_bodies(inside_out.vertices, inside_out.faces, e, labels)
    fixed = inside_out.copy()
    trimesh.repair.fix_inversion(fixed, multibody=True)
    mine = inside_out.faces.copy()
    mine[flip] = mine[flip][:, ::-1]
    assert np.array_equal(mine, fixed.faces), name


def test_rows_equal_under_one_hash_stay_apart():
    """Rows are compared whole: many rows, few buckets' worth of hash bits alike, each its own group."""
    rows = np.stack(np.meshgrid(np.arange(60), np.arange(60), np.arange(60), indexing="ij"), -1).reshape(-1, 3)
    rows = np.vstack([rows, rows[::-1]])
    first, inverse = topology.group_rows_first(rows)
    assert len(first) == 60**3 and np.array_equal(first, np.arange(60**3))
    assert np.array_equal(rows[first[inverse]], rows)


def test_a_loaded_inside_out_solid_is_turned_and_reported(tmp_path):
    mesh = trimesh.creation.icosphere(4, radius=20.0)
    mesh.invert()
    mesh.export(tmp_path / "inside_out.stl")
    loaded = load_mesh(tmp_path / "inside_out.stl")
    assert loaded.watertight and loaded.mesh.volume > 0
    assert loaded.repairs == ["turned the surface right side out (it was inside-out)"]
