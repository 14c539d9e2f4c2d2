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
                                    trimesh.creation.box((8.0, 6.0, 4.0)).apply_translation([
                                        30.0, 0, 0])])
    fin = trimesh.util.concatenate([trimesh.creation.box((10.0, 10.0, 10.0)),
                                    # open fin
                                    trimesh.Trimesh([[5, -5, 5], [5, 5, 5], [15, 0, 5]],
                                                    [[0, 1, 2]])])
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
    assert (np.array_equal(ours.vertices, theirs.vertices)
            and np.array_equal(ours.faces, theirs.faces)), name

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
    assert np.array_equal(labels, trimesh.graph.connected_component_labels(
        ours.face_adjacency, node_count=len(ours.faces)))
    if ours.is_watertight:
        assert topology.signed_volumes(ours.vertices,
                                       ours.faces).sum() == pytest.approx(ours.volume, rel=1e-9)

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
    """Rows are compared whole: many rows, few buckets' worth of hash bits alike, each its own
    group."""
    rows = np.stack(np.meshgrid(np.arange(60), np.arange(60), np.arange(60), indexing="ij"),
                    -1).reshape(-1, 3)
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


@pytest.mark.parametrize("k, keys", [(2, 50), (3, 400), (2, 3)])
def test_rows_bucketed_by_their_vertex_group_as_hashed(k, keys):
    """The bucketed grouping (a vertex's few edges) and the hash give the same groups, numbered
    alike; with buckets too large for it (three keys) the hash is taken."""
    rng = np.random.default_rng(k * keys)
    rows = np.column_stack([rng.integers(0, keys, 20_000), rng.integers(0, 40, (20_000, k - 1))])
    from pinchmatch.mesh import topology_kernel

    bucketed = topology.group_rows(rows, keys=keys)
    hashed = topology_kernel.group_rows(np.ascontiguousarray(rows, dtype=np.int64))
    for a, b in zip(bucketed, hashed):
        assert np.array_equal(a, b)
    first, last, inverse = hashed
    assert np.array_equal(rows[first[inverse]], rows) and np.array_equal(rows[last[inverse]], rows)
    assert (np.diff(first) > 0).all() and (last >= first).all()


def test_degenerate_faces_as_trimesh_finds_them():
    rng = np.random.default_rng(5)
    vertices = rng.normal(size=(300, 3)) * 10.0
    vertices[200:] = vertices[:100] + rng.normal(size=(100, 3)) * 1e-10  # corners a hair apart
    faces = rng.integers(0, 300, (4000, 3))
    faces[:50, 2] = faces[:50, 1]  # two corners the same
    # all but collinear
    line = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.000000001]])
    vertices = np.vstack([vertices, line])
    faces = np.vstack([faces, [[300, 301, 302]], faces[:100] % 100 + np.array([0, 200, 0])])
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    for height in (1e-9, 1e-6, 0.5):
        want = mesh.nondegenerate_faces(height=height)
        got = topology.nondegenerate_faces(vertices, faces, height)
        assert np.array_equal(got, want) and 0 < got.sum() < len(faces), height


def test_edges_around_a_vertex_of_huge_valence_are_hashed_alike():
    """A fan of 3,000 triangles around one corner (a CAD cone's apex): its edges group as a
    mesh of small valences does, through the hash."""
    from pinchmatch.mesh.topology_kernel import face_edges

    cone = trimesh.creation.cone(radius=10.0, height=20.0, sections=3000)
    faces = np.ascontiguousarray(cone.faces, dtype=np.int64)
    # too skewed to bucket
    assert not face_edges(faces, len(cone.vertices), float(topology.BUCKET_WORK_PER_ROW))[0]
    e = topology.edges(cone.faces)
    assert np.array_equal(np.sort(topology.face_adjacency(e), axis=0),
                          np.sort(np.sort(cone.face_adjacency, axis=1), axis=0))
    assert topology.watertight_and_wound(e) == (cone.is_watertight,
                                                cone.is_winding_consistent) == (True, True)
    doubled = trimesh.Trimesh(cone.vertices, np.vstack([cone.faces, cone.faces[:5, ::-1]]),
                              process=False)
    assert topology.watertight_and_wound(topology.edges(doubled.faces)) == \
        (doubled.is_watertight, doubled.is_winding_consistent) == (False, True)
