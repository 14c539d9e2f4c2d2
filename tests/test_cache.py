import dataclasses
import shutil
import json
import logging
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from pinchmatch.runner.cache import FeatureCache, cached_candidates, default_cache_dir
from pinchmatch.cli.commands import example_mesh_path
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.mesh.manifest import ObjectSpec
from pinchmatch.mesh.regions import ContactRegions, Region
from pinchmatch.mesh.shapes import ellipsoid

from conftest import run_cli

SETTINGS = PinchSettings(count=200, seed=3)


@pytest.fixture
def mesh_file(tmp_path):
    path = tmp_path / "e.stl"
    ellipsoid((30.0, 20.0, 12.0), faces=1500).mesh.export(path)
    return path


def same_candidates(a, b):
    for name in ("points", "normals", "face_index", "kappa_max_per_m", "kappa_min_per_m", "dir_max",
                 "broken"):
        assert np.array_equal(getattr(a.pinches, name), getattr(b.pinches, name)), name
    assert np.array_equal(a.table, b.table, equal_nan=True) and np.array_equal(a.index, b.index)
    assert np.array_equal(a.obj.loaded.mesh.vertices, b.obj.loaded.mesh.vertices)
    assert np.array_equal(a.obj.loaded.mesh.faces, b.obj.loaded.mesh.faces)
    assert np.array_equal(a.obj.props.com_mm, b.obj.props.com_mm)
    assert np.array_equal(a.obj.props.principal_axis, b.obj.props.principal_axis)
    assert a.obj.loaded.repairs == b.obj.loaded.repairs and a.pinches.rejected == b.pinches.rejected


def test_a_hit_rebuilds_exactly_what_a_cold_run_computes(tmp_path, mesh_file):
    cache = FeatureCache(tmp_path / "c")
    cold = cached_candidates(mesh_file, cache=cache, settings=SETTINGS)
    warm = cached_candidates(mesh_file, cache=cache, settings=SETTINGS)
    assert (cache.hits, cache.misses) == (1, 1) and cache.info().entries == 1
    same_candidates(cold, warm)
    same_candidates(cold, cached_candidates(mesh_file, cache=None, settings=SETTINGS))


def test_the_key_follows_content_and_settings_only(tmp_path, mesh_file):
    cache = FeatureCache(tmp_path / "c")
    spec = ObjectSpec(str(mesh_file))
    key = cache.key(spec, settings=SETTINGS)
    same = lambda spec=spec, **kw: cache.key(spec, **({"settings": SETTINGS} | kw))  # noqa: E731
    assert same() == key
    assert same(settings=PinchSettings(count=200, seed=4)) != key
    assert same(settings=PinchSettings(count=200, seed=3, friction_cone_deg=20)) != key
    assert same(settings=dataclasses.replace(SETTINGS, patch_radius_mm=6.0)) != key
    assert same(given=(np.zeros((1, 3)), np.ones((1, 3)))) != key
    # what shapes the candidates is in the key; the name and the mass are not
    for change in ({"units": "cm"}, {"up": "y"}, {"com_mm": (0.0, 0.0, 5.0)},
                   {"axis": (1.0, 0.0, 0.0)}, {"node": "handle"},
                   {"regions": ContactRegions(exclude=(Region.sphere((0, 0, 0), 5.0),))}):
        assert same(dataclasses.replace(spec, **change)) != key, change
    assert same(dataclasses.replace(spec, name="can", mass_g=350.0)) == key
    copy = tmp_path / "copy.stl"  # the name does not matter, the bytes do
    copy.write_bytes(mesh_file.read_bytes())
    assert cache.key(ObjectSpec(str(copy)), settings=SETTINGS) == key
    mesh_file.write_bytes(mesh_file.read_bytes()[:-50] + bytes(50))
    assert same() != key


@pytest.mark.parametrize("damage", ["truncated", "garbage", "empty", "other key"])
def test_a_damaged_entry_is_computed_again(tmp_path, mesh_file, damage, caplog):
    cache = FeatureCache(tmp_path / "c")
    cold = cached_candidates(mesh_file, cache=cache, settings=SETTINGS)
    entry = next(cache.folder.glob("*.npz"))
    data = entry.read_bytes()
    if damage == "truncated":
        entry.write_bytes(data[: len(data) // 2])
    elif damage == "garbage":
        entry.write_bytes(b"\x00not a zip" * 100)
    elif damage == "empty":
        entry.write_bytes(b"")
    else:  # an entry of another object under this key, as a stale or mixed-up file would be
        other = tmp_path / "o.stl"
        ellipsoid((25.0, 25.0, 10.0), faces=900).mesh.export(other)
        cached_candidates(other, cache=cache, settings=SETTINGS)
        other_entry = next(p for p in cache.folder.glob("*.npz") if p != entry)
        entry.write_bytes(other_entry.read_bytes())
    with caplog.at_level(logging.WARNING, logger="pinchmatch.runner.cache"):
        again = cached_candidates(mesh_file, cache=cache, settings=SETTINGS)
    assert "unusable" in caplog.text
    same_candidates(cold, again)
    spec = ObjectSpec(str(mesh_file))
    assert cache.load(cache.key(spec, settings=SETTINGS), spec,
                      patch_radius_mm=8.0) is not None  # rewritten whole


def test_an_unwritable_cache_only_loses_the_caching(tmp_path, mesh_file, caplog):
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    with caplog.at_level(logging.WARNING, logger="pinchmatch.runner.cache"):
        got = cached_candidates(mesh_file, cache=FeatureCache(blocked), settings=SETTINGS)
    assert len(got) > 0 and "cannot write the cache" in caplog.text


def _fill(args):
    folder, path = args
    cache = FeatureCache(folder)
    return len(cached_candidates(path, cache=cache, settings=SETTINGS))


def test_two_processes_writing_one_entry_leave_a_whole_entry(tmp_path, mesh_file):
    with ProcessPoolExecutor(2) as pool:
        counts = list(pool.map(_fill, [(tmp_path / "c", mesh_file)] * 4))
    assert len(set(counts)) == 1
    cache = FeatureCache(tmp_path / "c")
    assert cache.info().entries == 1 and not list(cache.folder.glob(".*.tmp"))
    cached_candidates(mesh_file, cache=cache, settings=SETTINGS)
    assert cache.hits == 1


def test_default_cache_dir_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("PINCHMATCH_CACHE_DIR", str(tmp_path / "x"))
    assert default_cache_dir() == tmp_path / "x"
    monkeypatch.delenv("PINCHMATCH_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert default_cache_dir() == tmp_path / "xdg" / "pinchmatch"


def test_match_reuses_the_cache_when_weights_change_and_gives_the_same_result(
    tmp_path, capsys, mesh_file):
    base = ["match", "--tangible", example_mesh_path(), "--virtual", mesh_file, "--count", 150,
            "--no-view", "--no-figures"]
    code, cold_out, err = run_cli(capsys, *base, "-o", tmp_path / "cold")
    assert code == 0, err
    assert "0 from the cache, 2 computed" in cold_out
    code, warm_out, err = run_cli(capsys, *base, "-o", tmp_path / "warm")
    assert code == 0 and "2 from the cache, 0 computed" in warm_out
    cold = (tmp_path / "cold" / "matches.json").read_text()
    assert (tmp_path / "warm" / "matches.json").read_text() == cold  # bit for bit
    code, tuned_out, err = run_cli(capsys, *base, "--weights", "width=3,mass=0", "--normalize",
                                   "range",
                               "-o", tmp_path / "tuned")
    assert code == 0 and "2 from the cache, 0 computed" in tuned_out
    assert json.loads((tmp_path / "tuned"
                       / "matches.json").read_text())["settings"]["weights"]["width"] == 3.0
    code, fresh_out, err = run_cli(capsys, *base, "--no-cache", "-o", tmp_path / "fresh")
    assert code == 0 and "from the cache" not in fresh_out
    assert (tmp_path / "fresh" / "matches.json").read_text() == cold


def test_cache_info_and_clear(tmp_path, capsys, mesh_file):
    folder = tmp_path / "mine"
    cached_candidates(mesh_file, cache=FeatureCache(folder), settings=SETTINGS)
    code, out, _ = run_cli(capsys, "cache", "info", "--cache", folder)
    assert code == 0 and f"{folder}: 1 entries" in out
    code, out, _ = run_cli(capsys, "cache", "clear", "--cache", folder)
    assert code == 0 and "deleted 1 entries" in out and FeatureCache(folder).info().entries == 0
    code, _, err = run_cli(capsys, "cache", "purge")
    assert code == 2 and "invalid choice" in err


def test_folders_are_searched_recursively_and_a_bad_file_is_left_out(tmp_path, capsys):
    props, assets = tmp_path / "props", tmp_path / "level"
    (assets / "room" / "shelf").mkdir(parents=True)
    (assets / ".hidden").mkdir()
    props.mkdir()
    (props / "prop.stl").write_bytes(example_mesh_path().read_bytes())
    ellipsoid((30.0, 20.0, 12.0), faces=900).mesh.export(assets / "room" / "egg.STL")
    ellipsoid((22.0, 22.0, 22.0), faces=900).mesh.export(assets / "room" / "shelf" / "ball.obj")
    ellipsoid((22.0, 22.0, 22.0), faces=900).mesh.export(assets / ".hidden" / "ignored.stl")
    (assets / "notes.txt").write_text("not a mesh")
    (assets / "room"
     / "broken.stl").write_bytes(b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0")
    out = tmp_path / "out"
    code, stdout, err = run_cli(capsys, "match", "--tangible", props, "--virtual", assets,
                                "--count", 120, "-o", out,
                            "--no-view", "--no-figures")
    assert code == 3, err
    assert err.count("pinchmatch: error:") == 1 and "broken.stl" in err and "going on" in err
    doc = json.loads((out / "matches.json").read_text())
    # by path: room/egg < room/shelf/ball
    assert [m["virtual"] for m in doc["matches"]] == ["egg.STL", "ball.obj"]
    assert len(doc["failed"]) == 1 and doc["failed"][0]["path"].endswith("broken.stl")
    assert doc["failed"][0]["role"] == "virtual" and "broken.stl" in doc["failed"][0]["error"]
    assert "failed: 1 files" in stdout


def test_when_no_file_of_a_role_can_be_used_the_run_stops(tmp_path, capsys):
    bad = tmp_path / "bad"
    bad.mkdir()
    for name in ("a.stl", "b.stl"):
        (bad / name).write_bytes(b"")
    out = tmp_path / "out"
    code, _, err = (run_cli(capsys, "match", "--tangible", example_mesh_path(), "--virtual", bad,
                            "-o", out))
    assert (code == 2 and "none of the 2 virtual files could be used" in err
            and "Traceback" not in err)
    assert err.strip().splitlines()[-1].startswith("pinchmatch: error: none of the 2")
    assert not out.exists()
    empty = tmp_path / "empty"
    empty.mkdir()
    code, _, err = (run_cli(capsys, "match", "--tangible", example_mesh_path(), "--virtual", empty,
                            "-o", out))
    assert (code == 2 and "names a folder that has no mesh file" in err
            and len(err.strip().splitlines()) == 1)


def test_clear_deletes_only_what_the_cache_wrote(tmp_path, capsys, mesh_file):
    folder = tmp_path / "mine"
    cached_candidates(mesh_file, cache=FeatureCache(folder), settings=SETTINGS)
    ours = next(folder.glob("*.npz"))
    np.savez(folder / "results.npz", a=np.arange(3))  # a user's own files, in the same folder
    (folder / "notes.tmp").write_text("mine")
    (folder / ".hidden.tmp").write_text("mine too")
    impostor = folder / ("ab" * 32 + ".npz")  # named like an entry, holding something else
    np.savez(impostor, meta=np.array('{"format": 2, "key": "someone else"}'))
    (folder / ("cd" * 32 + ".npz")).mkdir()  # a folder named like an entry
    # the cache's own temporary
    (folder / f".{'ef' * 32}.npz.x1y2.tmp").write_bytes(b"half an entry")
    code, out, err = run_cli(capsys, "cache", "clear", "--cache", folder)
    assert code == 0 and "deleted 1 entries" in out, err
    left = sorted(p.name for p in folder.iterdir())
    assert left == sorted([".hidden.tmp", "notes.tmp", "results.npz", impostor.name,
                           "cd" * 32 + ".npz"])
    assert not ours.exists()


def test_info_and_clear_on_a_file_say_so(tmp_path, capsys):
    path = tmp_path / "results.npz"
    path.write_bytes(b"user data")
    for action in ("info", "clear"):
        code, _, err = run_cli(capsys, "cache", action, "--cache", path)
        assert (code == 2 and "a file, not a cache folder" in err and len(err.strip().splitlines())
                == 1)
    assert path.read_bytes() == b"user data"


def test_the_key_covers_the_code(tmp_path, mesh_file, monkeypatch):
    from pinchmatch import options
    from pinchmatch.runner import cache as cache_module

    cache = FeatureCache(tmp_path / "c")
    key = cache.key(ObjectSpec(str(mesh_file)), settings=SETTINGS)
    # as after an edit of any module
    monkeypatch.setattr(cache_module, "code_digest", lambda: "0" * 64)
    assert cache.key(ObjectSpec(str(mesh_file)), settings=SETTINGS) != key
    # the code's digest reads every module of the package: none can be left out of a key
    copy = tmp_path / "pinchmatch"
    shutil.copytree(Path(cache_module.__file__).parents[1], copy,
                    ignore=shutil.ignore_patterns("__pycache__"))
    assert options.package_digest(copy) == options.code_digest()
    (copy / "data" / "notes.txt").write_text("a data file is no code")
    assert options.package_digest(copy) == options.code_digest()
    for edit in (lambda: (copy / "grasp"
                          / "hand.py").write_text((copy / "grasp" / "hand.py").read_text() + "#"),
                 lambda: (copy / "match" / "new_stage.py").write_text("x = 1\n"),
                 lambda: (copy / "viewer" / "viewer.js").write_text("//")):
        before = options.package_digest(copy)
        edit()
        assert options.package_digest(copy) != before


def test_a_code_error_while_reading_an_entry_is_raised_not_a_miss(tmp_path, mesh_file, monkeypatch):
    from pinchmatch.runner import cache as cache_module

    cache = FeatureCache(tmp_path / "c")
    cached_candidates(mesh_file, cache=cache, settings=SETTINGS)

    def broken(*args, **kwargs):
        raise TypeError("a bug")

    monkeypatch.setattr(cache_module, "_rebuild", broken)
    with pytest.raises(TypeError, match="a bug"):
        cached_candidates(mesh_file, cache=cache, settings=SETTINGS)
    assert len(list(cache.folder.glob("*.npz"))) == 1  # the entry is not thrown away for a bug


@pytest.mark.parametrize("error", [ValueError, KeyError])
def test_a_value_error_of_the_code_while_an_entry_is_checked_is_raised_not_a_miss(
    tmp_path, mesh_file, monkeypatch,
                                                                                   error):
    """Damage has its own exception: a bug that raises ValueError or KeyError while an entry is read
    or its arrays checked is raised, and the entry stays."""
    from pinchmatch.runner import cache as cache_module

    cache = FeatureCache(tmp_path / "c")
    cached_candidates(mesh_file, cache=cache, settings=SETTINGS)

    def broken(arrays):
        raise error("a bug")

    monkeypatch.setattr(cache_module, "_check_arrays", broken)
    with pytest.raises(error, match="a bug"):
        cached_candidates(mesh_file, cache=cache, settings=SETTINGS)
    assert len(list(cache.folder.glob("*.npz"))) == 1


def test_the_reference_pose_comes_from_the_cache_in_a_warm_run(tmp_path, mesh_file):
    """A warm run reads the reference pose's pinch back: the same pinch and cost, no surface sample
    or rays built."""
    from pinchmatch.match.scene import match_virtual
    from pinchmatch.match.search import MatchSettings, cost_model

    cache = FeatureCache(tmp_path / "c")
    # itself: the pinch line meets it
    tangible = cached_candidates(mesh_file, cache=None, settings=SETTINGS)
    cold = cached_candidates(mesh_file, cache=cache, settings=SETTINGS)
    # neither refined nor landed: both need the surface (a warm run of the same settings reads its
    # whole result from the cache instead)
    settings = MatchSettings(refine=False, landing_mm=0.0)
    model = cost_model(settings, [tangible, cold])
    def match(c, probes):
        return match_virtual([tangible], c, model=model, settings=settings, pinch_settings=SETTINGS,
                             probes=probes).matches[0].reference

    key = cache.last_key
    cold_probes = cache.load_probes(key)
    ref_cold = match(cold, cold_probes)
    assert len(cold_probes) == 1 and ref_cold.cost is not None
    cache.store_probes(key, cold_probes)
    assert len(list(cache.folder.glob("*.probes.npz"))) == 1 and cache.info().entries == 1

    warm = cached_candidates(mesh_file, cache=cache, settings=SETTINGS)
    warm_probes = cache.load_probes(cache.last_key)
    assert cache.last_key == key and warm_probes.keys() == cold_probes.keys()
    ref_warm = match(warm, warm_probes)
    # nothing of the surface was built
    assert not {"sample", "tree", "rays"} & set(vars(warm.obj.context))
    assert ref_warm.cost == ref_cold.cost and ref_warm.flipped == ref_cold.flipped
    for name in ("points", "normals", "kappa_max_per_m", "kappa_min_per_m", "broken", "approach"):
        assert np.array_equal(getattr(ref_warm.pinches, name),
                              getattr(cold_probes[next(iter(cold_probes))], name), equal_nan=True)
    assert dataclasses.asdict(warm.obj.props).keys() == dataclasses.asdict(cold.obj.props).keys()
    for name, value in dataclasses.asdict(cold.obj.props).items():
        # mass properties stored, not recomputed
        assert np.array_equal(getattr(warm.obj.props, name), value), name

    # a damaged probes file is a miss: computed again, the same
    probes = next(cache.folder.glob("*.probes.npz"))
    probes.write_bytes(probes.read_bytes()[:100])
    again = cached_candidates(mesh_file, cache=cache, settings=SETTINGS)
    assert cache.load_probes(cache.last_key) == {} and not probes.exists()
    assert match(again, {}).cost == ref_cold.cost


def test_given_poses_key_the_cache_by_their_values_in_any_number_type(tmp_path, mesh_file):
    """The same given contacts as float64, float32 and integers (values each type holds exactly)
    make one key; other contacts another."""
    cache = FeatureCache(tmp_path / "cache")
    spec = ObjectSpec(str(mesh_file))
    p1 = np.array([[10.0, -4.0, 2.0], [0.0, 6.0, -8.0]])
    p2 = np.array([[-10.0, -4.0, 2.0], [0.0, -6.0, -8.0]])
    keys = {cache.key(spec, settings=SETTINGS, given=(p1.astype(t), p2.astype(t)))
            for t in (np.float64, np.float32, np.int32)}
    assert len(keys) == 1
    assert cache.key(spec, settings=SETTINGS, given=(p1, p2 + 1.0)) not in keys


def test_an_unwritable_cache_is_said_once_with_the_systems_reason(tmp_path, mesh_file, caplog):
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    with caplog.at_level(logging.WARNING, logger="pinchmatch.runner.cache"):
        cached_candidates(mesh_file, cache=FeatureCache(blocked), settings=SETTINGS)
        cached_candidates(mesh_file, cache=FeatureCache(blocked), settings=SETTINGS)
    [record] = [r for r in caplog.records if "cannot write the cache" in r.getMessage()]
    import re

    assert re.fullmatch(r"cannot write the cache in .+ \([^()]+\); going on without it",
                        record.getMessage())
