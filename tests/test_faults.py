"""Files that cannot be read or written: one line naming the file, the right exit code, nothing
half-written.

Permission tests drop root's power to bypass file permissions with ``setpriv`` (util-linux) when
they run as root, as CI does; the full-disk test mounts a small tmpfs and is skipped where the
machine does not allow it.
"""

import contextlib
import errno
import json
import os
import shutil
import subprocess
import sys

import pytest

from pinchmatch.cli.commands import example_mesh_path
from pinchmatch.cli.main import main
from pinchmatch.mesh.shapes import ellipsoid

from conftest import assert_one_line

SETPRIV = shutil.which("setpriv")


def cli(*argv, cwd=None):
    """pinchmatch in a subprocess, without root's bypass of file permissions."""
    command = [sys.executable, "-m", "pinchmatch", *map(str, argv)]
    if os.geteuid() == 0:
        if SETPRIV is None:
            pytest.skip("running as root without setpriv: permissions cannot be tested")
        command = [SETPRIV, "--bounding-set=-dac_override,-dac_read_search", *command]
    proc = subprocess.run(command, capture_output=True, text=True, cwd=cwd, timeout=600)
    return proc.returncode, proc.stdout, proc.stderr


@pytest.fixture
def objects(tmp_path):
    root = tmp_path / "v"
    (root / "locked").mkdir(parents=True)
    for k, name in enumerate(["good.stl", "locked.stl", "locked/inner.stl"]):
        ellipsoid((30.0 + 3 * k, 20.0, 15.0), faces=1200, seed=k).mesh.export(root / name)
    os.chmod(root / "locked.stl", 0)
    os.chmod(root / "locked", 0)
    yield root
    os.chmod(root / "locked", 0o755)


def test_an_unreadable_mesh_is_one_line_and_exit_2(objects, tmp_path):
    code, _, err = cli("poses", objects / "locked.stl", "-o", tmp_path / "o.json")
    assert code == 2
    assert_one_line(err, "locked.stl: cannot be read (Permission denied)")
    assert not (tmp_path / "o.json").exists()


def test_a_folder_run_lists_unreadable_files_and_folders_under_failed_and_goes_on(
    objects, tmp_path):
    out = tmp_path / "out"
    code, _, err = cli("match", "--tangible", example_mesh_path(), "--virtual", objects, "--count",
                       100, "-q", "--no-view", "--no-figures", "-o", out)
    assert code == 3, err
    doc = json.loads((out / "matches.json").read_text())
    failed = {os.path.basename(f["path"]): f["error"] for f in doc["failed"]}
    assert set(failed) == {"locked.stl", "locked"}, failed
    assert "Permission denied" in failed["locked.stl"] and "cannot be read" in failed["locked"]
    assert [m["virtual"] for m in doc["matches"]] == ["good.stl"]


def test_an_unreadable_poses_file_is_one_line(tmp_path):
    poses = tmp_path / "poses.json"
    poses.write_text(json.dumps([{"p1_mm": [-20, 0, 20], "p2_mm": [20, 0, 20]}]))
    os.chmod(poses, 0)
    code, _, err = cli("poses", "--example", "--poses", poses)
    assert code == 2
    assert_one_line(err, "poses.json: cannot be read (Permission denied)")


@pytest.mark.parametrize("target", ["read-only folder", "a file as OUT", "a folder as FILE"])
def test_an_output_that_cannot_be_written_is_refused_before_any_work(tmp_path, target):
    locked = tmp_path / "locked"
    locked.mkdir()
    if target == "read-only folder":
        os.chmod(locked, 0o555)
        argv = ["match", "--tangible", example_mesh_path(), "--virtual", example_mesh_path(), "-o",
                locked / "out"]
        words = [f"{locked / 'out'}: cannot write in {locked}"]
    elif target == "a file as OUT":
        (tmp_path / "file").write_text("mine")
        argv = ["match", "--tangible", example_mesh_path(), "--virtual", example_mesh_path(), "-o",
                tmp_path / "file"]
        words = ["-o names a file"]
    else:
        argv = ["poses", "--example", "-o", locked]
        words = ["-o names a folder"]
    code, _, err = cli(*argv)
    os.chmod(locked, 0o755)
    assert code == 2
    assert_one_line(err, *words)
    assert list(locked.iterdir()) == []
    if target == "a file as OUT":
        assert (tmp_path / "file").read_text() == "mine"


def test_a_full_disk_met_while_writing_names_the_file(tmp_path, monkeypatch, capsys):
    """ENOSPC injected where the result is written: one line naming it, exit 2, no temporary
    left."""
    from pinchmatch import files

    real = files.os.replace

    def full(source, target):
        if os.path.basename(target) == "o.json":
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(source, target)

    monkeypatch.setattr(files.os, "replace", full)
    code = main(["poses", "--example", "--count", "30", "-o", str(tmp_path / "o.json")])
    _, err = capsys.readouterr()
    assert code == 2
    assert_one_line(err, "o.json: cannot write it (No space left on device)")
    assert list(tmp_path.iterdir()) == []


@contextlib.contextmanager
def small_tmpfs(mount, size: str):
    """A real, small file system at ``mount`` (root only; skipped where it cannot be mounted)."""
    mount.mkdir()
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs",
                                            str(mount)],
                                           capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    try:
        yield mount
    finally:
        subprocess.run(["umount", str(mount)])


def test_a_full_tmpfs(tmp_path):
    """A real full disk: a 300 KB tmpfs cannot hold a match run's outputs."""
    with small_tmpfs(tmp_path / "small", "300k") as mount:
        proc = subprocess.run([sys.executable, "-m", "pinchmatch", "match", "--tangible",
                               example_mesh_path(), "--virtual", example_mesh_path(), "--count",
                               "120", "-q", "-o", mount / "out"],
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == 2, proc.stderr
        assert_one_line(proc.stderr, "cannot write it (No space left on device)",
                        str(mount / "out"))


def test_a_full_cache_disk_costs_only_the_caching(tmp_path):
    """The cache is an optimisation: on a full disk the run goes on without it, says so once, leaves
    no temporary file there and writes the same result as a run without a cache."""
    with small_tmpfs(tmp_path / "cache", "100k") as mount:
        (mount / "filler").write_bytes(b"\0" * 90_000)
        argv = [sys.executable, "-m", "pinchmatch", "match", "--tangible", example_mesh_path(),
                "--virtual", example_mesh_path(), "--count", "120", "-q", "--jobs", "1",
                "--no-view"]
        proc = subprocess.run(argv + ["-o", tmp_path / "out", "--cache", mount],
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and "cache" in lines[0] and "going on without it" in lines[0], lines
        # what fitted is whole, no more
        assert not [p.name for p in mount.iterdir() if p.name.endswith(".tmp")]
        plain = subprocess.run(argv + ["-o", tmp_path / "plain", "--no-cache"], capture_output=True,
                               timeout=600)
        assert plain.returncode == 0
        assert (tmp_path / "out" / "matches.json").read_bytes() == (
            tmp_path / "plain" / "matches.json").read_bytes()


def test_clearing_a_read_only_cache_is_one_line(tmp_path, capsys):
    cache = tmp_path / "cache"
    assert main(["match", "--tangible", str(example_mesh_path()), "--virtual",
                 str(example_mesh_path()), "--count", "60", "-q", "--jobs", "1", "--no-view", "-o",
                 str(tmp_path / "out"), "--cache", str(cache)]) == 0
    capsys.readouterr()
    cache.chmod(0o555)
    try:
        if os.access(cache, os.W_OK) and os.geteuid() == 0:
            mount_ro = subprocess.run(["mount", "--bind", "-o", "ro", str(cache), str(cache)],
                                      capture_output=True)
            if mount_ro.returncode != 0:
                pytest.skip("cannot make a read-only folder here")
            subprocess.run(["mount", "-o", "remount,ro,bind", str(cache)], capture_output=True)
        try:
            assert main(["cache", "clear", "--cache", str(cache)]) == 2
            assert_one_line(capsys.readouterr().err, "cannot delete", str(cache))
        finally:
            if os.geteuid() == 0:
                subprocess.run(["umount", str(cache)], capture_output=True)
    finally:
        cache.chmod(0o755)
