"""The command line's contract under odd input: one line naming the problem, exit 2, nothing
written."""

import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest
import trimesh

from pinchmatch.cli.commands import example_mesh_path
from pinchmatch.cli.main import main
from pinchmatch.errors import ConfigError
from pinchmatch.match.search import MatchSettings
from pinchmatch.mesh.shapes import ellipsoid

from conftest import assert_bad_input, run_cli


@pytest.mark.parametrize("command, argv, words", [
    ("poses", ["--unit", "mm"], ["unknown option --unit", "did you mean --units?"]),
    ("poses", ["--count=5", "--see", "1"], ["unknown option --see", "did you mean --seed?"]),
    ("match", ["--tangibles", "x.stl", "--virtual", "y.stl"],
     ["unknown option --tangibles", "did you mean --tangible?"]),
    ("poses", ["--seed", "-1"], ["--seed: got -1", "0 or more"]),
    ("poses", ["--count", "10000000"], ["--count: got 10000000", "100,000"]),
    ("poses", ["--fingertip-radius-mm", "1000"],
     ["--fingertip-radius-mm: got 1000.0", "between 2 and 25"]),
    ("poses", ["--fingertip-radius-mm", "0.5"], ["--fingertip-radius-mm"]),
    ("poses", ["--finger-length-mm", "1000"], ["--finger-length-mm: got 1000.0"]),
    ("poses", ["--max-width-mm", "5000"], ["--max-width-mm: got 5000.0"]),
    ("poses", ["--patch-radius-mm", "400"], ["--patch-radius-mm: got 400.0"]),
    ("match", ["--weights", "width=1,width=2"], ["'width' is named twice"]),
    ("match", ["--weights", "width=0,com=0,tilt=0,normal=0,axis=0,kmax=0,kmin=0,mass=0"],
     ["every weight is 0"]),
    ("match",
     ["--criteria", "paper", "--weights", "width=0,com=0,tilt=0,normal=0,axis=0,kmax=0,kmin=0"],
     ["every weight is 0"]),
])
def test_bad_options_are_refused_in_one_line(tmp_path, capsys, command, argv, words):
    out = tmp_path / "out"
    where = (["--example"] if command == "poses"
             else ["--tangible", example_mesh_path(), "--virtual", example_mesh_path()])
    if command == "match" and argv[0] == "--tangibles":
        where = []
    code, _, err = run_cli(capsys, command, *where, *argv, "-o", out)
    assert_bad_input(code, err, *words)
    assert not out.exists()


def test_the_library_and_the_command_line_share_one_rule_for_weights():
    assert MatchSettings(weights={"width": 2}).weights == {
        "width": 2.0, "com": 0.0, "tilt": 1.0, "normal": 1.0,
                                                           "axis": 1.0, "kmax": 1.0, "kmin": 1.0,
                                                           "mass": 1.0}
    paper = ("width", "com", "tilt", "normal", "axis", "kmax", "kmin")
    assert MatchSettings(weights={}, criteria=paper).weights["mass"] == 0.0
    for weights, words in [({"widht": 1}, "did you mean 'width'"), ({"width": -1}, "0 or more"),
                           ({"width": float("nan")}, "0 or more"), ({"tilt": "x"}, "0 or more"),
                           (dict.fromkeys(paper + ("mass",), 0), "every weight is 0"),
                           ({"com": 1}, "not part of --criteria default")]:
        with pytest.raises(ConfigError, match=words):
            MatchSettings(weights=weights)
    with pytest.raises(ConfigError, match="mass"):
        MatchSettings(weights={"mass": 1}, criteria=paper)
    with pytest.raises(ConfigError, match="criteria"):
        MatchSettings(criteria=("width",))


def _egg(axes, seed):
    return ellipsoid(axes, faces=1500, triangulation="random", seed=seed).mesh


def test_output_names_are_unique_and_each_scene_holds_its_own_object(tmp_path, capsys):
    """a.obj, a.stl and a_2.stl: three scenes, none overwritten, each with its own geometry."""
    objects = tmp_path / "v"
    objects.mkdir()
    sizes = {"a.obj": (30.0, 20.0, 15.0), "a.stl": (40.0, 25.0, 18.0),
             "a_2.stl": (26.0, 26.0, 26.0)}
    for k, (name, axes) in enumerate(sizes.items()):
        _egg(axes, k).export(objects / name)
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", example_mesh_path(), "--virtual",
                           objects / "a.obj",
                       objects / "a.stl", objects / "a_2.stl", "--count", 120, "-q", "--figures",
                       "-o", out)
    assert code == 0, err
    doc = json.loads((out / "matches.json").read_text())
    files = [m["scene_file"] for m in doc["matches"]]
    assert len(set(files)) == 3 and all((out / f).is_file() for f in files)
    assert len({m["figure_file"] for m in doc["matches"]}) == 3
    for m in doc["matches"]:
        scene = trimesh.load(out / m["scene_file"], force="scene")
        virtual = next(g for name, g in scene.geometry.items() if "virtual" in name)
        extent = np.sort(virtual.extents)[::-1]
        want = 2.0 * np.sort(sizes[m["virtual"]])[::-1] / 1000.0  # glTF is in metres
        assert np.allclose(extent, want, rtol=0.05), (m["virtual"], extent, want)


def test_a_failed_object_beside_one_of_the_same_stem_leaves_a_viewable_folder(tmp_path, capsys):
    objects = tmp_path / "v"
    objects.mkdir()
    (objects / "a.obj").write_text("v 0 0 0\nthis is not a mesh\n")
    _egg((30.0, 20.0, 15.0), 0).export(objects / "a.stl")
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", example_mesh_path(), "--virtual",
                           objects / "a.obj",
                       objects / "a.stl", "--count", 120, "-q", "--no-figures", "-o", out)
    assert code == 3, err
    (out / "index.html").unlink()
    code, _, err = run_cli(capsys, "view", out, "-q")
    assert code == 0, err
    assert (out / "index.html").is_file()


def _icosphere():
    return trimesh.creation.icosphere(subdivisions=2, radius=20.0)


def _ply_with_fewer_faces_claimed(tmp_path, encoding):
    mesh = _icosphere()
    data = trimesh.exchange.ply.export_ply(mesh, encoding=encoding)
    end = data.index(b"end_header")
    header = data[:end].replace(f"element face {len(mesh.faces)}".encode(),
                                f"element face {len(mesh.faces) - 10}".encode())
    path = tmp_path / f"short_{encoding}.ply"
    path.write_bytes(header + data[end:])
    return path


@pytest.mark.parametrize("case, words", [
    ("ascii ply",
     ["its header counts 162 vertices and 310 faces, but the file holds 482 data lines"]),
    ("binary ply", ["its header counts 310 faces, but 130 more bytes follow them"]),
    ("gltf without its buffer", ["its buffer file 'gltf_buffer_0.bin' is missing"]),
    ("far from the origin", ["32-bit floats cannot hold that detail so far out"]),
])
def test_malformed_files_are_named_for_what_they_are(tmp_path, capsys, case, words):
    if case == "ascii ply":
        path = _ply_with_fewer_faces_claimed(tmp_path, "ascii")
    elif case == "binary ply":
        path = _ply_with_fewer_faces_claimed(tmp_path, "binary")
    elif case == "gltf without its buffer":
        _icosphere().export(tmp_path / "s.gltf")
        (tmp_path / "gltf_buffer_0.bin").unlink()
        path = tmp_path / "s.gltf"
    else:
        far = _icosphere()
        far.vertices += 1e7
        path = tmp_path / "far.stl"
        far.export(path)
    code, _, err = run_cli(capsys, "poses", path, "-o", tmp_path / "o.json")
    assert_bad_input(code, err, path.name, *words)
    assert not (tmp_path / "o.json").exists()


def test_well_formed_ply_and_gltf_still_load(tmp_path):
    from pinchmatch.mesh.load import load_mesh

    mesh = _icosphere()
    for name, kwargs in [("a.ply", {"encoding": "ascii"}), (
        "b.ply", {"encoding": "binary"}), ("c.gltf", {})]:
        mesh.export(tmp_path / name, **kwargs)
        assert len(load_mesh(tmp_path / name, units="mm").mesh.faces) == len(mesh.faces)


def test_warnings_from_libraries_never_reach_stderr(tmp_path, capsys):
    """A self-intersecting mesh makes numpy and trimesh warn inside; a normal run prints none of
    it."""
    a = trimesh.creation.box(extents=(40.0, 30.0, 20.0))
    b = trimesh.creation.box(extents=(20.0, 50.0, 10.0))
    mesh = trimesh.util.concatenate([a, b])  # two overlapping closed shells
    mesh.export(tmp_path / "crossed.stl")
    code, _, err = (run_cli(capsys, "poses", tmp_path / "crossed.stl", "--count", 50, "-o",
                            tmp_path / "o.json"))
    assert "Warning" not in err and "warn" not in err.lower(), err


def test_trimesh_log_notes_are_shown_only_when_verbose():
    """trimesh logs its fallbacks (with the traceback of the exception it caught, a signal's too): a
    run's stderr holds one line per problem, so they show only with --verbose."""
    import logging

    from pinchmatch.errors import route_warnings

    try:
        route_warnings(verbose=False)
        assert not logging.getLogger("trimesh.util").isEnabledFor(logging.WARNING)
        route_warnings(verbose=True)
        assert logging.getLogger("trimesh.util").isEnabledFor(logging.WARNING)
    finally:
        route_warnings(verbose=False)


def test_the_patch_radius_is_one_setting():
    from pinchmatch.grasp.analysis import analyze_object, find_pinches
    from pinchmatch.grasp.pinches import PinchSettings

    obj = analyze_object(example_mesh_path(), patch_radius_mm=6.0)
    with pytest.raises(ConfigError,
                       match="analysed for 6 mm patches but the pinch settings ask for 8 mm"):
        find_pinches(obj, settings=PinchSettings(count=20))
    with pytest.raises(ConfigError,
                       match="analysed for 6 mm patches but the pinch settings ask for 6.5 mm"):
        # half a millimetre is another
        find_pinches(obj, settings=PinchSettings(count=20, patch_radius_mm=6.5))
    pinches, _ = find_pinches(obj, settings=PinchSettings(count=20, patch_radius_mm=6.0))
    assert len(pinches) == 20


def test_every_output_file_gets_ordinary_permissions(tmp_path, capsys):
    """One writer for every file: matches.json, matches.jsonl, scenes, figures and cache entries
    alike."""
    import os
    import stat

    old = os.umask(0o022)
    try:
        for fmt in ("json", "jsonl"):
            code, _, err = run_cli(capsys, "match", "--tangible", example_mesh_path(), "--virtual",
                                   example_mesh_path(),
                               "--count", 80, "-q", "--format", fmt, "--cache", tmp_path / "cache",
                               "-o", tmp_path / fmt)
            assert code == 0, err
        files = [p for p in tmp_path.rglob("*") if p.is_file() and p.name != "lock"]
        assert {p.name for p in files} >= {"matches.json", "matches.jsonl", "example_prop.glb",
                                           "manifest.json"}
        assert any(p.suffix == ".npz" for p in files)
        assert {stat.S_IMODE(p.stat().st_mode) for p in files} == {0o644}
    finally:
        os.umask(old)


def test_a_mesh_too_large_for_the_free_memory_is_refused_before_reading(
    tmp_path, capsys, monkeypatch):
    from pinchmatch.mesh import file_checks

    path = tmp_path / "big.stl"
    _icosphere().export(path)
    monkeypatch.setattr(file_checks, "memory_headroom",
                        lambda: (20 * path.stat().st_size, "0.0 GiB left of the control "
                                                          # far too little
                                                          "group's 0.1 GiB (container limit)"))
    code, _, err = run_cli(capsys, "poses", path, "-o", tmp_path / "o.json")
    assert_bad_input(code, err, "big.stl",
                     "GiB to analyse, more than the 0.0 GiB left of the control group's",
                     "decimate it")
    monkeypatch.setattr(file_checks, "memory_headroom", lambda: None)  # unknown: not checked
    assert run_cli(capsys, "poses", path, "--count", 10, "-q", "-o", tmp_path / "o.json")[0] == 0


@pytest.mark.parametrize("limit_kib, words", [
    (600_000, "'ulimit -v' allows 0.6 GiB of address space, less than the 1.0 GiB"),
    (1_300_000, None),
])
def test_an_address_space_limit_is_said_in_one_line(tmp_path, limit_kib, words):
    """Under ``ulimit -v``: too little to start is refused at once, naming the limit; a limit a run
    can live with either finishes or, where a mesh needs more than is left, is refused before
    reading it; never an internal error, a missing shared object or a crash."""
    prop = tmp_path / "prop.stl"
    _icosphere().export(prop)
    script = (f"import resource, sys; resource.setrlimit(resource.RLIMIT_AS, ({limit_kib * 1024}, "
              f"{limit_kib * 1024})); from pinchmatch.cli.main import console; sys.argv = "
              "['pinchmatch', 'match', "
              f"'--tangible', {str(prop)!r}, '--virtual', {str(prop)!r}, '--count', '40', "
              "'--no-view', '-q', "
              f"'--no-cache', '-o', {str(tmp_path / 'out')!r}]; console()")
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=300)
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr, proc.stderr
    if words is None:
        assert proc.returncode in (0, 2), proc.stderr
        assert proc.returncode == 0 or "memory" in proc.stderr
    else:
        assert (proc.returncode == 2 and words in proc.stderr
                and len(proc.stderr.strip().splitlines()) == 1)


def test_running_out_of_memory_is_one_line(tmp_path, capsys, monkeypatch):
    """A MemoryError anywhere in a run: one line with the limits and what to do, exit 2."""
    from pinchmatch.match import scene

    def exhausted(*args, **kwargs):
        raise MemoryError()

    monkeypatch.setattr(scene, "match_one", exhausted)
    prop = tmp_path / "prop.stl"
    _icosphere().export(prop)
    code, _, err = run_cli(capsys, "match", "--tangible", prop, "--virtual", prop, "--count", 30,
                           "--jobs", 1, "--no-view", "-o", tmp_path / "out")
    assert code == 2 and "ran out of memory (limits:" in err and "--jobs 1" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "out").exists()


def test_loading_names_each_stage_as_it_starts(tmp_path):
    from pinchmatch.grasp.analysis import analyze_object

    path = tmp_path / "big.stl"
    trimesh.creation.icosphere(subdivisions=6, radius=30.0).export(path)  # 82k faces, 4 MiB
    stages = []
    analyze_object(path, progress=stages.append)
    assert stages == ["reading 4 MiB", "repairing: merging vertices",
                      "repairing: degenerate and duplicate faces", "repairing: edges and bodies",
                      "repairing: orientation", "mass properties", "surface sample and index"]


@pytest.mark.parametrize("argv, words", [
    (["view", "OUT", "--port", "70000"],
     ["--port 70000: not a port; give 0 (any free port) to 65535"]),
    (["view", "OUT", "--port", "-1"], ["--port -1: not a port"]),
    (["match", "--tangible", "T", "--virtual", "T", "--cache", "C", "--no-cache"],
     ["--cache and --no-cache: give one of them"]),
    (["match", "--tangible", "T", "--virtual", "T", "--json", "--format", "jsonl"],
     ["--json and --format jsonl: give one of them"]),
    (["match", "--tangible", "T", "--virtual", "T", "--top-k", "-1"],
     ["--top-k: -1 must be a whole number of 0 or more"]),
    (["match", "--tangible", "T", "--virtual", "T", "--distinct-mm", "nan"],
     ["--distinct-mm: nan must be a distance"]),
    (["match", "--tangible", "T", "--virtual", "T", "--jobs", "0"],
     ["--jobs: 0 must be 1 or more"]),
])
def test_each_validator_says_what_to_change(tmp_path, capsys, argv, words):
    argv = [str(example_mesh_path()) if a == "T" else str(tmp_path / "c") if a == "C" else a
            for a in argv]
    if argv[0] == "view":
        argv[1] = str(tmp_path)
    code, _, err = run_cli(capsys, *argv, *(["-o", tmp_path / "out"] if argv[0] == "match" else []))
    assert_bad_input(code, err, *words)
    assert not (tmp_path / "out").exists() and not (tmp_path / "c").exists()


@pytest.mark.parametrize("argv, words", [
    (["match", "--tangible", "{prop}", "--virtual", "{prop}", "--weights", "width=1e308"],
     "more than 1e+06"),
    (["match", "--tangible", "{prop}", "--virtual", "{prop}", "--weights-file", "{deep}"],
     "nested too deep"),
    (["match", "--tangible", "{prop}", "--virtual", "{prop}", "--weights-file", "{twice}"],
     "given twice"),
    (["match", "--tangible", "{far}", "--virtual", "{prop}"], "within 1e+06 mm"),
    (["match", "--tangible", "{nested}", "--virtual", "{prop}"], "nested too deep"),
    (["design", "--virtual", "{prop}", "--budget-s", "inf"], "at most 86400"),
    (["design", "--virtual", "{prop}", "--budget-s", "1e12"], "at most 86400"),
    (["design", "--virtual", "{prop}", "-k", "100"], "at most 8 props"),
    (["design", "--virtual", "{prop}", "--max-height-mm", "1e9"], "at most 1000 mm"),
    (["calibrate", "{pipe}"], "not a regular file"),
    (["calibrate", "{ragged}"], "line 3 has 2 cells"),
    (["calibrate", "{quote}"], "check its quotes"),
    (["calibrate", "{dupcol}"], "appears twice"),
    (["calibrate", "{unknown}"], "unknown column 'grip_jnd'"),
    (["calibrate", "{huge}"], "beyond"),
    (["calibrate", "{ok}", "--seed", "-3"], "--seed"),
    (["select", "--tangible", "{prop}", "{prop}", "--virtual", "{prop}", "-k", "2", "--max-k", "1"],
     "--max-k 1"),
    (["match", "--tangible", "{prop}", "--virtual", "{prop}", "--tangible-poses", "{text_poses}"],
     "pose 0 needs"),
    (["match", "--tangible", "{prop}", "--virtual", "{prop}", "--tangible-poses", "{bool_poses}"],
     "pose 1 needs"),
    (["match", "--tangible", "{prop}", "--virtual", "{prop}", "--weights-file", "{digits_json}"],
     "no weight can be"),
    (["match", "--tangible", "{prop}", "--virtual", "{prop}", "--weights-file", "{long_weight}"],
     "needs a 'weights'"),
    (["match", "--tangible", "{prop}", "--virtual", "{prop}", "--weights-file", "{latin1}"],
     "not UTF-8"),
    (["match", "--tangible", "{prop}", "--virtual", "{prop}", "--tangible-poses", "{digits_poses}"],
     "not valid JSON"),
    (["match", "--tangible", "{prop}", "--virtual", "{prop}", "--tangible-poses", "{long_poses}"],
     "pose 0 needs"),
    (["match", "--tangible", "{digits_toml}", "--virtual", "{prop}"],
     "a value the manifest cannot hold"),
    (["match", "--tangible", "{mass_toml}", "--virtual", "{prop}"], "mass_g"),
    (["match", "--tangible", "{shape_toml}", "--virtual", "{prop}"], "diameter_mm"),
])
def test_every_input_is_bounded_and_refused_in_one_line(tmp_path, capsys, argv, words):
    prop = tmp_path / "prop.stl"
    trimesh.creation.box(extents=(40.0, 30.0, 20.0)).export(prop)
    files = {"prop": prop, "deep": tmp_path / "deep.json", "twice": tmp_path / "twice.json",
             "far": tmp_path / "far.toml", "nested": tmp_path / "nested.toml",
             "pipe": tmp_path / "pipe.csv", "ragged": tmp_path / "ragged.csv",
             "quote": tmp_path / "quote.csv", "dupcol": tmp_path / "dup.csv",
             "unknown": tmp_path / "unknown.csv", "huge": tmp_path / "huge.csv",
             "ok": tmp_path / "ok.csv", "text_poses": tmp_path / "text.json",
             "bool_poses": tmp_path / "bool.json",
             **{k: tmp_path / f"{k}.{k.split('_')[-1] if k.endswith(('json', 'toml')) else 'json'}"
                for k in ("digits_json", "long_weight", "latin1", "digits_poses", "long_poses",
                          "digits_toml", "mass_toml", "shape_toml")}}
    files["digits_json"].write_text('{"weights": {"width": ' + "9" * 5000 + "}}")
    files["long_weight"].write_text('{"weights": {"width": ' + "9" * 400 + "}}")
    files["latin1"].write_bytes(b'{"weights": {"width": 1}, "note": "caf\xe9"}')  # a Latin-1 byte
    files["digits_poses"].write_text('[{"p1_mm": [' + "9" * 5000 + ', 0, 0], "p2_mm": [20, 0, 0]}]')
    files["long_poses"].write_text('[{"p1_mm": [' + "9" * 400 + ', 0, 0], "p2_mm": [20, 0, 0]}]')
    files["digits_toml"].write_text(f'[[object]]\nfile = "{prop}"\nmass_g = {"9" * 5000}\n')
    files["mass_toml"].write_text(f'[[object]]\nfile = "{prop}"\nmass_g = {"9" * 400}\n')
    files["shape_toml"].write_text('[[object]]\nname = "can"\nshape = { kind = "cylinder", '
                                   'diameter_mm = '
                                   + "9" * 400 + ", height_mm = 66 }\n")
    files["text_poses"].write_text(json.dumps([{"p1_mm": ["-20", 0, 0], "p2_mm": [20, 0, 0]}]))
    files["bool_poses"].write_text(json.dumps([{"p1_mm": [-20, 0, 0], "p2_mm": [20, 0, 0]},
                                               {"p1_mm": [-20, 0, 0], "p2_mm": [20, True, 0]}]))
    files["deep"].write_text('{"weights": ' + "[" * 100_000 + "]" * 100_000 + "}")
    files["twice"].write_text('{"weights": {"width": 1, "width": 2}}')
    files["far"].write_text(f'[[object]]\nfile = "{prop}"\ncom_mm = [1e300, 0, 0]\n')
    files["nested"].write_text("a = " + "[" * 50_000 + "]" * 50_000 + "\n")
    os.mkfifo(files["pipe"])
    rows = "\n".join(f"{r},{w},{k}"
                     for r, w, k in [(6, 0.1, 0.2), (5, 0.5, 0.9), (3, 1.2, 0.3), (2, 1.5, 1.4),
                                                    (4, 0.8, 0.4), (6.5, 0.0, 0.1)])
    files["ok"].write_text("rating,width_jnd,kmax_jnd\n" + rows + "\n")
    files["ragged"].write_text("rating,width_jnd,kmax_jnd\n6,0.1,0.2\n5,0.5\n")
    files["quote"].write_text('rating,width_jnd,kmax_jnd\n6,0.1,"0.2\n')
    files["dupcol"].write_text("rating,width_jnd,width_jnd\n" + rows + "\n")
    files["unknown"].write_text("rating,width_jnd,grip_jnd\n" + rows + "\n")
    files["huge"].write_text("rating,width_jnd,kmax_jnd\n1e300,0.1,0.2\n" + rows + "\n")
    out = tmp_path / ("o.json" if argv[0] == "calibrate" else "o")
    argv = [a.format(**files) for a in argv] + ["-o", str(out), "-q"]
    t0 = time.perf_counter()
    assert main(argv) == 2
    assert time.perf_counter() - t0 < 20
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and "Traceback" not in err[0], err
    assert not out.exists()


def test_with_no_usable_prop_the_virtual_files_are_checked_in_the_same_run(tmp_path, capsys):
    """Both roles' files in metres, read as mm: one line names the prop's problem and the virtual
    object's, so that one run shows every file to fix."""
    for name, extents in (("prop.stl", (0.05, 0.04, 0.03)), ("thing.stl", (0.06, 0.03, 0.02))):
        trimesh.creation.box(extents=extents).export(tmp_path / name)
    code, _, err = run_cli(capsys, "match", "--tangible", tmp_path / "prop.stl", "--virtual",
                           tmp_path / "thing.stl", "-o", tmp_path / "out", "--count", 40,
                           "--no-cache", "--jobs", 1)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert "prop.stl" in lines[0] and "thing.stl" in lines[0] and "--units" in lines[0]
    assert not (tmp_path / "out").exists()


def test_a_name_longer_than_a_file_name_may_be_still_gets_its_scene(tmp_path, capsys):
    """An object named by 80 CJK characters (240 bytes of UTF-8; its scene's name would be 240 +
    11): the run writes its scene under a name cut on a character boundary, and matches.json records
    it."""
    prop = tmp_path / "prop.stl"
    trimesh.creation.box(extents=(40.0, 30.0, 20.0)).export(prop)
    long = tmp_path / ("\u6f22" * 80 + ".stl")
    trimesh.creation.box(extents=(30.0, 30.0, 20.0)).export(long)
    out = tmp_path / "out"
    assert main(["match", "--tangible", str(prop), "--virtual", str(long), "--count", "60", "-q",
                 "--no-view", "-o", str(out)]) == 0, capsys.readouterr().err
    (m,) = json.loads((out / "matches.json").read_text())["matches"]
    scene = out / m["scene_file"]
    assert scene.is_file() and len(scene.name.encode("utf-8")) < 255
    assert scene.stem == "\u6f22" * 50  # 150 bytes: whole characters only


@pytest.mark.parametrize("case, words", [
    ("tiny shape", "diameter_mm, height_mm must be from 1 to 1000 mm"),
    ("huge shape", "object big (its shape): no feasible pinch"),
    ("dangling out", "a symbolic link to"),
    ("folder file", "a folder, not a mesh file"),
])
def test_small_cases_name_the_real_problem(tmp_path, capsys, case, words):
    """A shape too small for a millimetre, a described prop too big to pinch (named by its manifest,
    not its solid's file), -o a link to nothing, and file = "." each end in one line that says what
    is wrong."""
    prop = tmp_path / "prop.stl"
    trimesh.creation.box(extents=(40.0, 30.0, 20.0)).export(prop)
    manifest = tmp_path / "props.toml"
    out = tmp_path / "out"
    tangible = manifest
    if case == "tiny shape":
        manifest.write_text('[[object]]\nname = "t"\nshape = { kind = "cylinder", diameter_mm = '
                            '0.001, '
                            'height_mm = 0.001 }\n')
    elif case == "huge shape":
        manifest.write_text('[[object]]\nname = "big"\nshape = { kind = "cylinder", diameter_mm = '
                            '1000, '
                            'height_mm = 1000 }\n')
    elif case == "dangling out":
        tangible = prop
        out.symlink_to(tmp_path / "nowhere")
    else:
        manifest.write_text('[[object]]\nfile = "."\n')
    assert main(["match", "--tangible", str(tangible), "--virtual", str(prop), "--count", "50",
                 "-q", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and "Traceback" not in err[0], err
    assert "pinchmatch-shapes" not in err[0]
    assert not (tmp_path / "nowhere").exists()
