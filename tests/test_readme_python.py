"""The README's Python lines give the command line's answer on the same files and options."""

import json

import numpy as np
import trimesh

from conftest import run_cli
from pinchmatch import (Config, MatchSettings, PinchSettings, analyze_object, analyze_prop,
                        candidate_poses, match_scene, read_manifest)


def test_the_python_path_gives_the_command_lines_answer(tmp_path, capsys):
    # a block (mm), a pebble-like prop in a manifest (metres), a mug-like virtual object (glTF,
    # metres, y up)
    trimesh.creation.box(extents=(60.0, 40.0, 25.0)).export(tmp_path / "block.stl")
    pebble = trimesh.creation.icosphere(subdivisions=3, radius=0.03)
    pebble.apply_scale([1.0, 0.7, 0.45])
    pebble.export(tmp_path / "pebble.obj")
    (tmp_path / "props.toml").write_text('[[object]]\nfile = "pebble.obj"\nunits = "m"\n')
    mug = trimesh.creation.cylinder(radius=0.04, height=0.09, sections=48)
    mug.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    mug.export(tmp_path / "mug.glb")

    settings = PinchSettings(count=200, seed=1)
    config = Config(settings, MatchSettings(top_k=2))
    props = [candidate_poses(analyze_prop(tmp_path / "block.stl"), settings=settings)]
    props += [candidate_poses(analyze_prop(spec), settings=settings)
              for spec in read_manifest(tmp_path / "props.toml")]
    obj = analyze_object(tmp_path / "mug.glb")
    scene = match_scene(props, [candidate_poses(obj, settings=settings)], config=config)
    best = scene.matches[0].best

    code, _, err = run_cli(capsys, "match", "--tangible", tmp_path / "block.stl",
                           tmp_path / "props.toml", "--virtual", tmp_path / "mug.glb", "--count",
                           200, "--seed", 1, "--top-k", 2, "--jobs", 1, "--no-view", "-q",
                           "--no-cache", "-o", tmp_path / "out")
    assert code == 0, err
    cli = json.loads((tmp_path / "out" / "matches.json").read_text())["matches"][0]
    assert best.tangible_name == cli["tangible"]
    assert round(best.cost, 6) == cli["cost"]
    np.testing.assert_allclose(best.tangible_pose.p1_mm, cli["tangible_pose"]["p1_mm"], atol=1e-3)
    np.testing.assert_allclose(best.virtual_pose.p1_mm, cli["virtual_pose"]["p1_mm"], atol=1e-3)
    # the props stand, as the command line's do
    assert all(p.obj.context.support is not None for p in props)
