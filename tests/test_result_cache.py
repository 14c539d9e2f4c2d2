"""Whole results in the cache (pinchmatch.runner.results): a warm run with the same inputs reads a
virtual object's result back, bit for bit, and any input that could change it is in its key."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from pinchmatch.cli.commands import example_mesh_path
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.config import Config
from pinchmatch.match.search import MatchSettings
from pinchmatch.mesh.manifest import ObjectSpec
from pinchmatch.mesh.shapes import ellipsoid
from pinchmatch.runner import results, tasks
from pinchmatch.runner.cache import FeatureCache
from pinchmatch.runner.tasks import Job, ObjectTask

from conftest import run_cli


@pytest.fixture
def meshes(tmp_path):
    egg, ball = tmp_path / "egg.stl", tmp_path / "ball.stl"
    ellipsoid((30.0, 20.0, 12.0), faces=1500).mesh.export(egg)
    ellipsoid((22.0, 22.0, 22.0), faces=1200).mesh.export(ball)
    return egg, ball


def _outputs(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and ".pinchmatch" not in p.parts}


def _match(capsys, meshes, out, cache, *extra):
    argv = ["match", "--tangible", example_mesh_path(), "--virtual", *meshes, "--count", 150,
            "--jobs", 1, "--cache", cache, "-o", out, *extra]
    code, stdout, err = run_cli(capsys, *argv)
    assert code == 0, err
    return stdout


def test_a_warm_run_reads_each_result_back_bit_for_bit_without_searching(
    tmp_path, capsys, meshes, monkeypatch):
    cache = tmp_path / "cache"
    _match(capsys, meshes, tmp_path / "cold", cache)
    assert len(list(cache.glob("*.result.npz"))) == 2
    searched = []
    inner = tasks.match_virtual
    monkeypatch.setattr(tasks, "match_virtual", lambda *a,
                        **k: searched.append(1) or inner(*a, **k))
    _match(capsys, meshes, tmp_path / "warm", cache)
    assert searched == []  # every virtual object's result came from the cache
    # page, scenes, figures, matches.json
    assert _outputs(tmp_path / "warm") == _outputs(tmp_path / "cold")

    # other weights: other results, searched again, as a run without the cache finds them
    _match(capsys, meshes, tmp_path / "tuned", cache, "--weights", "width=3,mass=0")
    assert len(searched) == 2
    _match(capsys, meshes, tmp_path / "fresh", tmp_path / "other-cache", "--weights",
           "width=3,mass=0")
    assert _outputs(tmp_path / "tuned") == _outputs(tmp_path / "fresh")
    assert _outputs(tmp_path / "tuned") != _outputs(tmp_path / "cold")


def test_a_damaged_result_is_searched_again(tmp_path, capsys, meshes, caplog):
    cache = tmp_path / "cache"
    _match(capsys, meshes, tmp_path / "cold", cache, "--no-view")
    for entry in cache.glob("*.result.npz"):
        entry.write_bytes(entry.read_bytes()[:200])
    _match(capsys, meshes, tmp_path / "again", cache, "--no-view")
    assert "searching again" in caplog.text
    assert _outputs(tmp_path / "again") == _outputs(tmp_path / "cold")
    for entry in cache.glob("*.result.npz"):  # written whole again
        with np.load(entry) as z:
            assert z["row"].ndim == 1


def test_cache_info_counts_objects_and_clear_takes_results_too(tmp_path, capsys, meshes):
    cache = tmp_path / "cache"
    _match(capsys, meshes, tmp_path / "out", cache, "--no-view")
    assert FeatureCache(cache).info().entries == 3  # the prop and the two virtual objects
    code, out, _ = run_cli(capsys, "cache", "clear", "--cache", cache)
    assert code == 0 and not list(cache.glob("*.npz"))


def test_the_key_covers_every_input_of_a_result(tmp_path, meshes):
    egg, ball = meshes
    cache = FeatureCache(tmp_path / "c")
    task = ObjectTask("virtual", str(egg))
    job = Job(units=None, up=None, config=Config(PinchSettings(count=150), MatchSettings()))
    shared, model = ("a" * 64, None), {"weights": 1.0}
    key = results.result_key(cache, task, job, shared, model, None, None)
    assert key == results.result_key(cache, task, job, shared, model, None, None)  # deterministic
    changed = {
        "another file": (ObjectTask("virtual", str(ball)), job, shared, model, None, None),
        "another name or mass": (ObjectTask("virtual", str(egg),
                                            spec=ObjectSpec(str(egg), mass_g=50.0)),
                                 job, shared, model, None, None),
        "other tangibles": (task, job, ("b" * 64, None), model, None, None),
        "another cost model": (task, job, shared, {"weights": 2.0}, None, None),
        "other match settings": (task, dataclasses.replace(job, config=job.config.replace(top_k=5)),
                                 shared, model, None, None),
        "other pinch settings": (task,
                                 dataclasses.replace(job, config=job.config.replace(count=151)),
                                 shared, model, None, None),
        "units": (task, dataclasses.replace(job, units="cm"), shared, model, None, None),
        "a one-to-one plan": (task, job, shared, model, np.array([True, False]),
                              np.array([0.5, 1.5])),
        "no scenes written": (task, dataclasses.replace(job, scenes=False), shared, model, None,
                              None),
    }
    keys = {name: results.result_key(cache, *args) for name, args in changed.items()}
    assert key not in keys.values() and len(set(keys.values())) == len(keys), keys
    egg.write_bytes(egg.read_bytes()[:-50] + bytes(50))  # the file edited
    assert results.result_key(cache, task, job, shared, model, None, None) != key


