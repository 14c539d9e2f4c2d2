import json

import pytest
import trimesh


from conftest import run_cli


def test_poses_on_the_example_writes_a_complete_document(tmp_path, capsys):
    out = tmp_path / "poses.json"
    code, stdout, err = run_cli(capsys, "poses", "--example", "--count", "150", "-o", str(out))
    assert code == 0, err
    doc = json.loads(out.read_text())
    assert doc["schema"] == "pinchmatch.poses/1" and doc["version"]
    assert doc["settings"]["count"] == 150 and doc["settings"]["units"] == "mm"
    obj = doc["object"]
    for key in ("com_mm", "principal_axis", "axis_source", "up", "units_in", "bounds_mm",
                "watertight", "repairs"):
        assert key in obj
    assert obj["watertight"] and obj["axis_source"] == "pca" and obj["up"] == "z"
    assert doc["pose_count"] == len(doc["poses"]) == 150
    pose = doc["poses"][0]
    for key in ("p1_mm", "p2_mm", "n1", "n2", "width_mm", "com_distance_mm", "tilt_deg"):
        assert key in pose
    assert set(pose["patches"][0]) >= {"normal_angle_deg", "curvature_axis_angle_deg",
                                       "kappa_max_per_m", "kappa_min_per_m"}
    assert "150 feasible" in stdout


def test_poses_csv_and_stdout(capsys):
    code, stdout, _ = run_cli(capsys, "poses", "--example", "--count", "20", "--format", "csv")
    assert code == 0
    lines = stdout.strip().splitlines()
    assert lines[0].startswith("index,feasible,p1_x_mm") and len(lines) == 21


def test_given_poses_are_checked_and_infeasible_ones_named(tmp_path, capsys):
    poses = tmp_path / "poses.json"
    poses.write_text(json.dumps([
        {"p1_mm": [-20, 0, 20], "p2_mm": [20, 0, 20]},   # across the cylinder: feasible
        {"p1_mm": [-20, 0, 20], "p2_mm": [0, 20, 20]},   # a quarter turn apart: not antipodal
    ]))
    out = tmp_path / "checked.json"
    code, stdout, _ = run_cli(capsys, "poses", "--example", "--poses", str(poses), "-o", str(out))
    assert code == 0
    doc = json.loads(out.read_text())
    assert [p["feasible"] for p in doc["poses"]] == [True, False]
    assert "antipodal" in doc["poses"][1]["broken_rules"]
    assert "pose 1: infeasible, breaks antipodal" in stdout


@pytest.mark.parametrize("style", ["equals", "separate"])
def test_features_accepts_negative_coordinates(capsys, style):
    args = (["--p1=-20,0,20", "--p2=20,0,20"] if style == "equals"
            else ["--p1", "-20,0,20", "--p2", "20,0,20"])
    code, stdout, err = run_cli(capsys, "features", "--example", *args, "-q")
    assert code == 0, err
    doc = json.loads(stdout)
    assert doc["schema"] == "pinchmatch.features/1"
    pose = doc["pose"]
    assert pose["feasible"] and pose["width_mm"] == pytest.approx(40.0, abs=1e-3)
    assert pose["patches"][0]["kappa_max_per_m"] == pytest.approx(50.0, rel=0.02)
    # the hand: a unit approach within 30 deg of the plane across the pinch line (x)
    assert sum(c * c for c in pose["approach"]) == pytest.approx(1.0, abs=1e-5)
    assert abs(pose["approach"][0]) <= 0.5 + 1e-6 and pose["approach_clearance_mm"] >= -0.3


def test_features_names_the_approach_and_the_csv_carries_it(capsys):
    code, stdout, _ = (run_cli(capsys, "features", "--example", "--p1", "-20,0,20", "--p2",
                               "20,0,20"))
    assert code == 0 and "approach [" in stdout and "fingers clear by" in stdout
    code, stdout, _ = run_cli(capsys, "poses", "--example", "--count", "5", "--format", "csv")
    head, first = stdout.splitlines()[:2]
    columns = dict(zip(head.split(","), first.split(",")))
    h = [float(columns[f"approach_{c}"]) for c in "xyz"]
    assert (sum(c * c for c in h) == pytest.approx(1.0, abs=1e-4)
            and "approach_clearance_mm" in columns)


def test_a_thinner_finger_reaches_into_a_narrow_tube(tmp_path, capsys):
    # the wall of a test tube (bore 12 mm) pinched 10 mm below its rim: an 8 mm fingertip does not
    # fit in the bore, a 5 mm one does, and its finger leaves upwards
    from pinchmatch.mesh import vessels

    path = tmp_path / "tube.stl"
    vessels.tube().export(path)
    argv = ["features", str(path), "--p1", "8,0,90", "--p2", "6,0,90", "-q"]
    code, stdout, _ = run_cli(capsys, *argv)
    assert code == 0 and "clearance" in json.loads(stdout)["pose"]["broken_rules"]
    code, stdout, _ = (run_cli(capsys, *argv, "--fingertip-radius-mm", "5", "--finger-radius-mm",
                               "5"))
    pose = json.loads(stdout)["pose"]
    assert code == 0 and pose["feasible"] and abs(pose["approach"][2]) > 0.85  # up, along the bore


# ---- bad input: exit 2, one line naming the file and the fix, no traceback, no output file
def _box(tmp_path, name="box.stl", extents=(60.0, 40.0, 20.0)):
    path = tmp_path / name
    trimesh.creation.box(extents=extents).export(path)
    return path


def _bad_files(tmp_path):
    garbage = tmp_path / "garbage.stl"
    garbage.write_bytes(bytes(range(256)) * 4)
    truncated = _box(tmp_path, "trunc.stl")
    truncated.write_bytes(truncated.read_bytes()[:300])
    (tmp_path / "empty.obj").write_text("")
    (tmp_path / "badidx.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    (tmp_path / "nan.obj").write_text("v 0 0 0\nv nan 0 0\nv 0 9 0\nv 0 0 9\nf 1 2 3\nf 1 3 4\nf 1 "
                                      "2 4\nf 2 3 4\n")
    (tmp_path / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    (tmp_path / "mesh.dat").write_text("1 2 3")
    (tmp_path / "folder.stl").mkdir()
    tiny = _box(tmp_path, "tiny.stl", (0.06, 0.04, 0.02))
    return {
        "missing.stl": "no such file",
        "empty.obj": "file is empty",
        "mesh.dat": "unknown mesh format",
        "folder.stl": "is a folder",
        "garbage.stl": "corrupt",
        "trunc.stl": "truncated binary STL",
        "badidx.obj": "refers to a vertex",
        "nan.obj": "NaN or infinite",
        "points.obj": "no faces",
        tiny.name: "read it with --units m (",
    }


def test_each_bad_file_fails_cleanly(tmp_path, capsys):
    for name, expected in _bad_files(tmp_path).items():
        out = tmp_path / f"{name}.out.json"
        code, stdout, err = run_cli(capsys, "poses", str(tmp_path / name), "-o", str(out))
        assert code == 2, name
        lines = err.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in err, err
        assert name in lines[0] and expected in lines[0], lines[0]
        assert not out.exists()
        assert not list(tmp_path.glob(f".{out.name}*"))  # no temporary left behind


@pytest.mark.parametrize("argv, expected", [
    (["--count", "0"], "--count: got 0"),
    (["--friction-cone-deg", "95"], "--friction-cone-deg: got 95"),
    (["--max-width-mm", "1"], "--max-width-mm"),
    (["--fingertip-radius-mm", "-1"], "--fingertip-radius-mm"),
    (["--finger-radius-mm", "9"],
     "--finger-radius-mm: got 9.0; it must be more than 0.3 and at most --fingertip-radius-mm"),
    (["--finger-radius-mm", "0.2"], "--finger-radius-mm: got 0.2"),
    (["--finger-length-mm", "0"], "--finger-length-mm: got 0.0"),
    (["--approach-tilt-deg", "90"], "--approach-tilt-deg: got 90.0"),
    (["--approach-tilt-deg", "-5"], "--approach-tilt-deg: got -5.0"),
    (["--patch-radius-mm", "0"], "--patch-radius-mm: got 0.0"),
    (["--snap-tolerance-mm", "-1"], "--snap-tolerance-mm: got -1.0"),
    (["--min-width-mm", "-0.5"], "--min-width-mm: got -0.5"),
    (["--units", "ft"], "invalid choice: 'ft'"),
    (["--com", "1,2"], "--com: expected three finite numbers"),
    (["--axis", "0,0,0"], "--axis: the axis must be a non-zero vector"),
    (["--bogus"], "unknown option --bogus"),
])
def test_bad_options_fail_cleanly(tmp_path, capsys, argv, expected):
    out = tmp_path / "o.json"
    code, _, err = run_cli(capsys, "poses", "--example", *argv, "-o", str(out))
    assert code == 2 and len(err.strip().splitlines()) == 1 and expected in err, err
    assert not out.exists()


def test_no_feasible_pinch_fails_cleanly(tmp_path, capsys):
    path = _box(tmp_path, "slab.stl", (300.0, 300.0, 150.0))
    code, _, err = run_cli(capsys, "poses", str(path), "-o", str(tmp_path / "o.json"))
    assert code == 2 and "slab.stl: no feasible pinch" in err and "width" in err
    assert not (tmp_path / "o.json").exists()


def test_contact_far_from_the_surface(tmp_path, capsys):
    code, _, err = run_cli(capsys, "features", "--example", "--p1", "-40,0,20", "--p2", "20,0,20")
    assert code == 2 and "p1 (-40, 0, 20) mm is 20.00 mm from the surface" in err


def test_bad_poses_file(tmp_path, capsys):
    bad = tmp_path / "p.json"
    bad.write_text("[{\"p1_mm\": [1, 2]")
    code, _, err = run_cli(capsys, "poses", "--example", "--poses", str(bad))
    assert code == 2 and "p.json: not valid JSON" in err
    bad.write_text(json.dumps([{"p1_mm": [1, 2], "p2_mm": [0, 0, 0]}]))
    code, _, err = run_cli(capsys, "poses", "--example", "--poses", str(bad))
    assert code == 2 and "pose 0 needs" in err


def test_mesh_and_example_together_or_neither(tmp_path, capsys):
    code, _, err = run_cli(capsys, "poses")
    assert code == 2 and "no mesh given" in err
    code, _, err = run_cli(capsys, "poses", str(_box(tmp_path)), "--example")
    assert code == 2 and "either a MESH or --example" in err


def test_output_has_ordinary_permissions(tmp_path, capsys):
    import os
    import stat

    out = tmp_path / "p.json"
    assert run_cli(capsys, "poses", "--example", "--count", "5", "-o", str(out))[0] == 0
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(out.stat().st_mode) == 0o666 & ~umask


def test_tables_fit_80_columns_and_explain_their_units(tmp_path, capsys, monkeypatch):
    import trimesh

    long_t = tmp_path / "tangible_prop_with_a_rather_long_descriptive_name_from_the_lab.stl"
    long_v = tmp_path / "virtual_asset_kitchen_shelf_left_jar_lid_variant_b_final.stl"
    trimesh.creation.box(extents=(60.0, 40.0, 20.0)).export(long_t)
    trimesh.creation.box(extents=(58.0, 41.0, 22.0)).export(long_v)
    monkeypatch.setenv("COLUMNS", "80")
    code, out, err = run_cli(capsys, "match", "--tangible", long_t, "--virtual", long_v, "--count",
                             "60", "--no-view", "--no-figures", "-o", tmp_path / "out")
    assert code == 0, err
    assert max(len(line) for line in out.splitlines()) <= 80
    assert "…" not in out  # long names wrap, whole, instead of being cut
    assert "virtual_asset" in out and "tangible_prop" in out
    said = " ".join(out.split())
    assert ("cost: the differences in JND pooled by probability summation (1: noticed half of the "
            "time)") in said
