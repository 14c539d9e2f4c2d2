"""A level's nodes as a designer chooses them: globs that keep or leave out nodes, a clear line for
a node no hand could pinch, and a cache entry per node."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import trimesh

from conftest import assert_bad_input, run_cli
from levels import standing_can, tabletop_level
from pinchmatch.mesh.manifest import object_specs

PROP = ('[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, height_mm = '
        '66 }\n')


def _counter():
    """A counter slab (metres): 1.2 m x 0.6 m, 40 mm thick, its top at y = 0."""
    slab = trimesh.creation.box(extents=(1.2, 0.04, 0.6))
    slab.apply_translation([0.0, -0.02, 0.0])
    return slab


def _level(folder, *, moved_mm=0.0, extra=False):
    places = [("counter", _counter(), (0.0, 0.0, 0.0)),
              ("can_a", standing_can(), (0.1 + moved_mm / 1000, 0.0, 0.0)),
              ("can_b", standing_can(0.02, 0.09), (-0.12, 0.0, 0.05)),
              ("box_c", trimesh.creation.box(
                  extents=(0.04, 0.06, 0.05)), (0.0, 0.03, -0.15))]
    if extra:
        places.append(("can_d", standing_can(0.03, 0.05), (0.2, 0.0, 0.2)))
    tabletop_level(folder / "kitchen.glb", places)
    (folder / "props.toml").write_text(PROP)


def _match(capsys, folder, out, *extra):
    code, stdout, err = run_cli(capsys, "match", "--tangible", folder / "props.toml", "--virtual",
                                folder / "kitchen.glb", "--split", "nodes", "--count", 60, "-o",
                                out, "--no-view", "--jobs", 1, *extra)
    return code, stdout + err


def test_globs_keep_and_leave_out_nodes_by_name_and_in_a_manifest(tmp_path):
    _level(tmp_path)
    level = tmp_path / "kitchen.glb"
    notes = []
    every = [s.node for s in object_specs([level], option="--virtual", split="nodes", notes=notes)]
    assert sorted(every) == ["box_c", "can_a", "can_b"]  # the counter they stand on is furniture
    assert (len(notes) == 1 and "node counter left out" in notes[0]
            and "--nodes 'counter'" in notes[0])
    named = object_specs([level], option="--virtual", split="nodes", nodes=["count*", "can_a"])
    assert sorted(s.node for s in named) == ["can_a", "counter"]  # named, it comes back
    kept = object_specs([level], option="--virtual", split="nodes", skip_nodes=["counter"])
    assert sorted(s.node for s in kept) == ["box_c", "can_a", "can_b"]
    cans = object_specs([level], option="--virtual", split="nodes", nodes=["can_*"],
                        skip_nodes=["*_b"])
    assert [s.node for s in cans] == ["can_a"]
    (tmp_path / "level.toml").write_text('[[object]]\nfile = "kitchen.glb"\nsplit = "nodes"\n'
                                         'skip_nodes = ["count?r", "box_*"]\n')
    listed = object_specs([tmp_path / "level.toml"], option="--virtual")
    assert sorted(s.node for s in listed) == ["can_a", "can_b"]


@pytest.mark.parametrize("extra, words", [
    (["--nodes", "shelf*"], "'shelf*' (--nodes, or a manifest's nodes) matches no mesh node"),
    (["--skip-nodes", "*"], "leave no mesh node"),
])
def test_a_glob_that_leaves_nothing_is_one_line(tmp_path, capsys, extra, words):
    _level(tmp_path)
    out = tmp_path / "out"
    code, text = _match(capsys, tmp_path, out, *extra)
    assert_bad_input(code, text, "kitchen.glb", words)
    assert not out.exists()


def test_a_manifest_s_bad_glob_is_one_line(tmp_path, capsys):
    _level(tmp_path)
    (tmp_path / "level.toml").write_text('[[object]]\nfile = "kitchen.glb"\nsplit = '
                                         '"nodes"\nskip_nodes = [3]\n')
    code, stdout, err = run_cli(capsys, "match", "--tangible", tmp_path / "props.toml", "--virtual",
                                tmp_path / "level.toml", "-o", tmp_path / "out")
    assert_bad_input(code, stdout + err, "level.toml", "skip_nodes", "must be a glob")


def test_a_node_no_hand_can_pinch_is_named_with_its_size_and_the_way_out(tmp_path, capsys):
    """A 400 x 300 x 250 mm crate is wider than the largest pinch (100 mm) in every direction: the
    run says so for that node, names it and how to leave it out; the other nodes are matched, among
    them a pot as large in every direction whose 6 mm wall a hand pinches (not convex: sampling
    decides)."""
    crate = trimesh.creation.box(extents=(0.4, 0.25, 0.3))
    crate.apply_translation([0.0, 0.125, 0.0])
    pot = trimesh.creation.annulus(r_min=0.104, r_max=0.11, height=0.22)
    pot.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    pot.apply_translation([0.0, 0.11, 0.0])
    tabletop_level(tmp_path / "kitchen.glb",
                   [("crate", crate, (0.5, 0.0, 0.0)), ("can_a", standing_can(), (0.1, 0, 0)),
                                             ("pot", pot, (-0.4, 0.0, 0.0))])
    (tmp_path / "props.toml").write_text(PROP)
    code, text = _match(capsys, tmp_path, tmp_path / "out")
    assert code == 3, text
    line = next(ln for ln in text.splitlines() if "crate" in ln
                and "wider than the largest pinch" in ln)
    assert "(node crate)" in line and "250 x 300 x 400 mm" in line
    assert "--skip-nodes 'crate'" in line
    matched = json.loads((tmp_path / "out" / "matches.json").read_text())["matches"]
    assert sorted(m["virtual"] for m in matched) == ["can_a", "pot"]
    pot_width = [m for m in matched if m["virtual"] == "pot"][0]["virtual_pose"]
    # across its wall
    assert np.linalg.norm(np.subtract(pot_width["p1_mm"], pot_width["p2_mm"])) < 10.0
    code, text = _match(capsys, tmp_path, tmp_path / "out2", "--skip-nodes", "crate")
    assert code == 0, text


def test_editing_one_node_recomputes_that_node_only(tmp_path, capsys):
    """A cache entry depends on the node's own triangles in the world: moving one can and adding
    another node recomputes those two; the prop and the untouched nodes come from the cache, with
    the same answers."""
    _level(tmp_path)
    cache = tmp_path / "cache"
    code, text = (_match(capsys, tmp_path, tmp_path / "first", "--skip-nodes", "counter", "--cache",
                         cache))
    assert code == 0, text
    assert re.search(r"0 from the cache, 4 computed", text), text
    _level(tmp_path, moved_mm=15.0, extra=True)
    code, text = (_match(capsys, tmp_path, tmp_path / "second", "--skip-nodes", "counter",
                         "--cache", cache))
    assert code == 0, text
    assert re.search(r"3 from the cache, 2 computed", text), text
    first = {m["virtual"]: m
             for m in json.loads((tmp_path / "first" / "matches.json").read_text())["matches"]}
    second = {m["virtual"]: m
              for m in json.loads((tmp_path / "second" / "matches.json").read_text())["matches"]}
    for name in ("can_b", "box_c"):
        assert second[name]["cost"] == first[name]["cost"]
        assert np.allclose(second[name]["tangible_pose"]["p1_mm"],
                           first[name]["tangible_pose"]["p1_mm"])
    assert set(second) == {"can_a", "can_b", "box_c", "can_d"}


def test_a_level_of_many_nodes_is_read_once_not_once_per_node(tmp_path, monkeypatch, capsys):
    """300 mesh nodes: loading 60 of them reads the file once (a level of thousands of nodes was
    quadratic); a changed file is read again; the run says how many objects the level makes before
    it starts."""
    import trimesh

    from pinchmatch.cli.main import main
    from pinchmatch.mesh import load
    from pinchmatch.mesh.load import load_mesh, read_level

    scene = trimesh.Scene()
    for i in range(300):
        scene.add_geometry(trimesh.creation.box(extents=(0.05, 0.04, 0.03)), node_name=f"box{i}",
                           geom_name=f"g{i}",
                           transform=trimesh.transformations.translation_matrix([
                               0.1 * i, 0.0, 0.0]))
    path = tmp_path / "level.glb"
    scene.export(path)
    reads = []
    real = load._load
    monkeypatch.setattr(load, "_load", lambda *a, **k: reads.append(a[0]) or real(*a, **k))
    nodes = read_level(path)
    for node in nodes[:60]:
        mesh = load_mesh(path, node=node.name).mesh
        assert abs(mesh.centroid[0] - 100.0 * int(node.name[3:])) < 1e-6  # its own triangles, in mm
    assert len(reads) == 2  # once to list the nodes, once for the objects
    scene.export(path)  # the same level written again: another file state
    load_mesh(path, node="box1")
    assert len(reads) == 3
    prop = tmp_path / "prop.stl"
    trimesh.creation.box(extents=(40.0, 30.0, 20.0)).export(prop)
    assert main(["match", "--tangible", str(prop), "--virtual", str(path), "--split", "nodes",
                 "--nodes", "box1?", "--count", "40", "--no-view", "-o",
                 str(tmp_path / "out")]) in (0, 3)
    assert f"{path}: 10 nodes, one object each" in capsys.readouterr().out
