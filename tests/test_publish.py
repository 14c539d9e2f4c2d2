"""An output folder holds one whole result, whatever stops a run: errors, signals, a second run."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from pinchmatch.export import folder as publish
from pinchmatch.export import sink
from pinchmatch.runner import executors
from pinchmatch.cli.commands import example_mesh_path
from pinchmatch.cli.main import main
from pinchmatch.export.folder import OutputFolder, read_manifest, recover
from pinchmatch.export.seal import sealed
from pinchmatch.mesh.shapes import ellipsoid


@pytest.fixture(scope="module")
def virtuals(tmp_path_factory):
    root = tmp_path_factory.mktemp("v")
    for k, axes in enumerate([(30.0, 20.0, 15.0), (40.0, 22.0, 18.0), (26.0, 26.0, 26.0)]):
        ellipsoid(axes, faces=1500, triangulation="random", seed=k).mesh.export(root / f"e{k}.stl")
    return root


def match(out, virtuals, *extra, jobs=1):
    return main(["match", "--tangible", str(example_mesh_path()), "--virtual", *map(str, virtuals),
                 "--count", "120", "-q", "--jobs", str(jobs), "-o", str(out), *extra])


def snapshot(out):
    return {str(p.relative_to(out)): p.read_bytes() for p in sorted(out.rglob("*"))
            if p.is_file() and p.name != "lock"}


def assert_whole(out):
    """OUT is one whole result: the manifest lists exactly the result's files, every one exists,
    every scene the document names exists, and nothing is left staged or half-published."""
    files = read_manifest(out)
    assert files and all((out / f).is_file() for f in files)
    doc = json.loads((out / "matches.json").read_text())
    assert all(m["scene_file"] in files for m in doc["matches"] if m.get("tangible"))
    assert not (out / ".pinchmatch" / "commit.json").exists()
    assert not (out / ".pinchmatch" / "staging").exists()
    assert not list(out.rglob("*.tmp"))


def test_a_run_that_fails_midway_leaves_the_previous_result(
    tmp_path, virtuals, monkeypatch, capsys):
    out = tmp_path / "out"
    assert match(out, sorted(virtuals.glob("*.stl"))) == 0
    before = snapshot(out)
    calls = []
    real_add = sink.MatchesSink.add

    def add_then_stop(self, k, r):
        calls.append(k)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real_add(self, k, r)

    monkeypatch.setattr(sink.MatchesSink, "add", add_then_stop)
    assert match(out, sorted(virtuals.glob("*.stl")), "--top-k", "1") == 130
    assert "holds what it held before" in capsys.readouterr().err
    assert snapshot(out) == before
    assert_whole(out)


def test_files_of_an_earlier_result_go_and_a_users_files_stay(tmp_path, virtuals):
    out = tmp_path / "out"
    assert match(out, sorted(virtuals.glob("*.stl")), "--figures") == 0
    assert len(list((out / "scenes").glob("*.glb"))) == 3
    (out / "notes.txt").write_text("mine")
    (out / "scenes" / "mine.glb").write_bytes(b"mine")
    assert match(out, [virtuals / "e1.stl"], "--no-figures") == 0
    assert sorted(p.name for p in (out / "scenes").iterdir()) == ["e1.glb", "mine.glb"]
    assert not (out / "figures").exists()  # every figure was the earlier result's
    assert (out / "notes.txt").read_text() == "mine" and (
        out / "scenes" / "mine.glb").read_bytes() == b"mine"
    assert_whole(out)


def test_a_second_run_into_the_same_folder_is_refused_while_one_runs(tmp_path, virtuals, capsys):
    out = tmp_path / "out"
    with OutputFolder(out) as stage:
        code = match(out, [virtuals / "e0.stl"])
        # the second wrote nothing
        assert list(stage.iterdir()) == [] and not (out / "matches.json").exists()
    err = capsys.readouterr().err
    assert (code == 2 and "another pinchmatch run is writing this folder" in err
            and len(err.strip().splitlines()) == 1)


def test_view_leaves_the_page_alone_while_a_run_holds_the_folder(tmp_path, virtuals, capsys):
    out = tmp_path / "out"
    assert match(out, [virtuals / "e0.stl"]) == 0
    def page():
        return (out / "index.html").read_bytes() if (out / "index.html").exists() else None

    before = page()
    capsys.readouterr()
    with OutputFolder(out):
        code = main(["view", str(out), "-q"])
        after = page()  # (the run, when it ends, publishes its own folder)
    err = capsys.readouterr().err
    assert (code == 2 and "a pinchmatch run is writing this folder" in err
            and len(err.strip().splitlines()) == 1)
    assert after == before is not None


def test_a_publication_cut_short_is_finished_by_the_next_reader(tmp_path, virtuals, monkeypatch):
    out = tmp_path / "out"
    assert match(out, [virtuals / "e0.stl"]) == 0
    # the second run dies after its journal is written and one file is moved
    real_replace = os.replace
    moved = []

    def replace_once_then_die(src, dst):
        if ".pinchmatch/staging" in str(src) and ".pinchmatch" not in str(dst):  # publishing
            if moved:
                raise SystemExit("killed")
            moved.append(dst)
        return real_replace(src, dst)

    monkeypatch.setattr(publish.os, "replace", replace_once_then_die)
    with pytest.raises(SystemExit):
        match(out, [virtuals / "e1.stl", virtuals / "e2.stl"])
    monkeypatch.setattr(publish.os, "replace", real_replace)
    assert (out / ".pinchmatch" / "commit.json").exists()  # half published
    assert main(["view", str(out), "-q"]) == 0  # a reader finishes the journal first
    assert_whole(out)
    doc = json.loads((out / "matches.json").read_text())
    assert [m["virtual"] for m in doc["matches"]] == ["e1.stl", "e2.stl"]
    assert not (out / "scenes" / "e0.glb").exists()


def _pgid_members(pgid):
    """The live processes of the process group ``pgid`` or of the session it leads: the run's child
    runs the command in a group of its own, in the same session."""
    members = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as fh:
                    fields = fh.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if pgid in (int(fields[2]), int(fields[3])) and fields[0] != "Z":
                members.append(int(entry))
    return members


@pytest.mark.parametrize("sig, delay_s",
                         [(signal.SIGINT, 2.0), (signal.SIGTERM, 3.0), (signal.SIGKILL, 1.5),
                                         (signal.SIGKILL, 3.5)])
def test_signals_leave_a_whole_result_and_no_worker(tmp_path, virtuals, sig, delay_s):
    out = tmp_path / "out"
    assert match(out, [virtuals / "e0.stl"], "--no-view") == 0
    before = snapshot(out)
    argv = [sys.executable, "-m", "pinchmatch", "match", "--tangible", str(example_mesh_path()),
            "--virtual", *map(str, sorted(virtuals.glob("*.stl"))), "--count", "400", "-q",
            "--jobs", "2", "-o", str(out)]
    proc = subprocess.Popen(argv, start_new_session=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    time.sleep(delay_s)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    if proc.returncode == 0:  # finished before the signal: the new result, whole
        assert_whole(out)
    else:
        # 130/143: pinchmatch's handler ran; -sig: the signal came before Python started it (a slow
        # start)
        assert proc.returncode in (-signal.SIGKILL, -sig, 130, 143), (proc.returncode, err)
        if sig != signal.SIGKILL and proc.returncode > 0:
            assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
        recover(out)  # what any next run or view does first
        assert snapshot(out) == before or read_manifest(out) != []
        assert_whole(out)
    deadline = time.time() + 15
    while _pgid_members(proc.pid) and time.time() < deadline:
        time.sleep(0.2)
    assert _pgid_members(proc.pid) == []  # no worker, no resource tracker outlives the run
    assert match(out, sorted(virtuals.glob("*.stl")), "--no-view") == 0  # and a rerun completes
    assert_whole(out)


CHILDREN = '''
import os, sys
from pinchmatch.cli.main import main
if __name__ == "__main__":
    code = main(sys.argv[1:])
    states = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                fields = open(f"/proc/{entry}/stat").read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == os.getpid():
                states.append(fields[0])
    print(code, " ".join(states))
'''


def test_a_normal_parallel_run_leaves_no_defunct_child(tmp_path, virtuals):
    script = tmp_path / "children.py"
    script.write_text(CHILDREN)
    proc = subprocess.run([sys.executable, str(script), "match", "--tangible",
                           str(example_mesh_path()), "--virtual", str(virtuals / "e0.stl"),
                           str(virtuals / "e1.stl"), "--count", "120", "-q", "--jobs", "2",
                           "--no-cache", "-o", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=300)
    code, *states = proc.stdout.split()
    assert code == "0", proc.stderr
    assert "Z" not in states  # workers joined; the resource tracker ends with the process


def test_two_runs_at_once_one_is_refused(tmp_path, virtuals):
    out = tmp_path / "out"
    argv = [sys.executable, "-m", "pinchmatch", "match", "--tangible", str(example_mesh_path()),
            "--virtual", *map(str, sorted(virtuals.glob("*.stl"))), "--count", "300", "-q",
            "--jobs", "1", "--no-cache",
            # computed, with figures: the first run is still writing when the second starts
            "--figures", "-o", str(out)]
    first = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while not (out / ".pinchmatch" / "staging").exists() and time.time() < deadline:
        time.sleep(0.05)
    second = subprocess.run(argv, capture_output=True, text=True, timeout=120)
    _, first_err = first.communicate(timeout=300)
    assert first.returncode == 0, first_err
    assert (second.returncode == 2
            and "another pinchmatch run is writing this folder" in second.stderr)
    assert len(second.stderr.strip().splitlines()) == 1
    assert_whole(out)


def test_the_next_parallel_run_removes_a_killed_runs_temporary_folder(tmp_path, virtuals):
    import tempfile

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()  # a pid that no longer runs
    orphan = tempfile.mkdtemp(prefix=f"{executors.RUN_FOLDER_PREFIX}{dead.pid}-")
    mine = tempfile.mkdtemp(prefix=f"{executors.RUN_FOLDER_PREFIX}{os.getpid()}-")  # a live run's
    try:
        assert match(tmp_path / "out", [virtuals / "e0.stl"], "--no-figures", "--no-view",
                     jobs=2) == 0
        assert not os.path.exists(orphan) and os.path.isdir(mine)
    finally:
        os.rmdir(mine)


def test_a_worker_that_dies_is_an_internal_error_not_bad_input(
    tmp_path, virtuals, monkeypatch, capsys):
    from concurrent.futures.process import BrokenProcessPool

    from pinchmatch.cli import runs as cli

    def broken(*args, **kwargs):
        raise BrokenProcessPool("a child process terminated abruptly")

    monkeypatch.setattr(cli, "run_match", broken)
    assert match(tmp_path / "out", [virtuals / "e0.stl"]) == 1
    err = capsys.readouterr().err
    assert (err.startswith("pinchmatch: internal error: a worker process died")
            and len(err.strip().splitlines()) == 1)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("link", ["scenes", "figures"])
def test_a_folder_of_out_linked_elsewhere_is_never_written_or_pruned_through(
    tmp_path, virtuals, capsys, link):
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    assert match(out, [virtuals / "e0.stl"], "--figures") == 0
    elsewhere.mkdir()
    (elsewhere / "e0.glb").write_bytes(b"someone else's scene")
    (elsewhere / "e0.png").write_bytes(b"someone else's figure")
    victims = snapshot(elsewhere)
    import shutil

    shutil.rmtree(out / link)
    (out / link).symlink_to(elsewhere, target_is_directory=True)
    before = snapshot(out)
    capsys.readouterr()
    # would prune e0's files and write e1's there
    assert match(out, [virtuals / "e1.stl"], "--figures") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert (len(err) == 1 and "symbolic link out of the output folder" in err[0]
            and link in err[0]), err
    assert snapshot(elsewhere) == victims and snapshot(out) == before


@pytest.mark.parametrize("name",
                         ["../victim.txt", "{abs}", "scenes/../../victim.txt", "linked/victim.txt"])
def test_a_journal_naming_a_path_outside_out_leaves_it_in_place(tmp_path, virtuals, name):
    out = tmp_path / "out"
    assert match(out, [virtuals / "e0.stl"], "--no-view") == 0
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    (out / "linked").symlink_to(tmp_path, target_is_directory=True)
    name = name.format(abs=str(victim))
    control = out / ".pinchmatch"
    (control / "commit.json").write_text(sealed("journal",
                                                {"new": [name], "staged": [], "remove": [name]}))
    (control / "manifest.json").write_text(sealed("manifest", {"files": [name]}))
    publish.finish_commit(out)
    assert victim.read_text() == "keep me"


def test_a_journal_or_manifest_naming_files_outside_out_touches_none_of_them(tmp_path, virtuals):
    """A journal left half done, or a manifest of the last result, that names ``../victim``, an
    absolute path, a path climbing out through a subfolder or a file behind a folder linked out of
    OUT: finishing the journal and the next run's pruning leave every one of them in place."""
    out = tmp_path / "out"
    assert match(out, [virtuals / "e0.stl"]) == 0
    outside = tmp_path / "outside"
    outside.mkdir()
    victims = {name: outside / name for name in ("a.txt", "b.txt", "c.txt", "d.txt")}
    for path in victims.values():
        path.write_text("keep me")
    (out / "linked").symlink_to(outside, target_is_directory=True)
    names = ["../outside/a.txt", str(victims["b.txt"]), "scenes/../../outside/c.txt",
             "linked/d.txt"]
    control = out / ".pinchmatch"
    (control / "commit.json").write_text(sealed("journal",
                                                {"new": [], "staged": names, "remove": names}))
    publish.finish_commit(out)
    assert all(p.read_text() == "keep me" for p in victims.values())
    assert not (control / "commit.json").exists()
    # the manifest of the last result names them too: the next run prunes only what is inside OUT
    (control / "manifest.json").write_text(sealed("manifest",
                                                  {"files": read_manifest(out) + names}))
    (out / "linked").unlink()  # (a folder linked out of OUT is refused outright; its own test)
    (out / "linked").mkdir()
    assert match(out, [virtuals / "e1.stl"]) == 0
    assert all(p.read_text() == "keep me" for p in victims.values())
    assert_whole(out)


@pytest.mark.parametrize("link", ["staging", "staging-folder", "staged-file", "control", "journal"])
def test_a_received_folder_with_links_in_its_control_folder_moves_nothing_from_outside(
    tmp_path, virtuals, capsys,
                                                                                        link):
    """A result folder received from someone else: its staging folder a link to another folder, a
    folder in staging a link, a staged file a link, the control folder itself a link, or the journal
    a link; its journal names a file there. ``view`` and the next ``match`` refuse in one line or
    move only what is really staged: the file outside stays where it is, and nothing is written
    outside OUT."""
    out = tmp_path / "out"
    assert match(out, [virtuals / "e0.stl"], "--no-view") == 0
    elsewhere = tmp_path / "elsewhere"
    (elsewhere / "sub").mkdir(parents=True)
    (elsewhere / "victim.txt").write_text("keep me")
    (elsewhere / "sub" / "victim.txt").write_text("keep me")
    control = out / ".pinchmatch"
    journal = {"new": ["victim.txt", "sub/victim.txt"], "staged": ["victim.txt", "sub/victim.txt"],
               "remove": []}
    if link == "control":
        real = tmp_path / "control-elsewhere"
        control.rename(real)
        control.symlink_to(real, target_is_directory=True)
        (real / "staging").symlink_to(elsewhere, target_is_directory=True)
        (real / "commit.json").write_text(sealed("journal", journal))
    else:
        (control / "staging").mkdir(exist_ok=True)
        if link == "staging":
            (control / "staging").rmdir()
            (control / "staging").symlink_to(elsewhere, target_is_directory=True)
        elif link == "staging-folder":
            (control / "staging" / "sub").symlink_to(elsewhere / "sub", target_is_directory=True)
        elif link == "staged-file":
            (control / "staging" / "victim.txt").symlink_to(elsewhere / "victim.txt")
        if link == "journal":
            (elsewhere / "commit.json").write_text(sealed("journal", journal))
            (control / "commit.json").symlink_to(elsewhere / "commit.json")
        else:
            (control / "commit.json").write_text(sealed("journal", journal))
    before = sorted(p.name for p in elsewhere.rglob("*"))
    capsys.readouterr()
    for argv in (["view", str(out)], None):
        code = main(argv) if argv else match(out, [virtuals / "e1.stl"], "--no-view")
        err = capsys.readouterr().err.strip()
        assert code in (0, 2) and "Traceback" not in err
        if code == 2:
            assert len(err.splitlines()) == 1 and "pinchmatch never follows" in err, err
        assert (elsewhere / "victim.txt").read_text() == "keep me"
        assert (elsewhere / "sub" / "victim.txt").read_text() == "keep me"
        # no lock, no file written outside
        assert sorted(p.name for p in elsewhere.rglob("*")) == before
        assert not (out / "victim.txt").exists() and not (out / "sub").exists()


def test_files_written_straight_into_out_are_taken_back_when_the_run_does_not_finish(tmp_path):
    """design's props and the demo's objects are written where they stay, before the result is
    published: a run that stops (a signal, an error) puts back the files they replaced and removes
    those it added."""
    out = tmp_path / "out"
    (out / "props").mkdir(parents=True)
    (out / "props" / "prop_1.stl").write_bytes(b"the last result's prop")
    (out / "notes.txt").write_text("the user's own file")
    publisher = OutputFolder(out)
    with pytest.raises(KeyboardInterrupt):
        with publisher:
            publisher.write_direct(out / "props" / "prop_1.stl", b"new prop 1")
            publisher.write_direct(out / "props" / "prop_2.stl", b"new prop 2")
            (out / "objects").mkdir()
            (out / "objects" / "a.stl").write_bytes(b"added")
            publisher.direct(out / "objects" / "a.stl", new=True)
            raise KeyboardInterrupt
    assert (out / "props" / "prop_1.stl").read_bytes() == b"the last result's prop"
    assert not (out / "props" / "prop_2.stl").exists() and not (out / "objects").exists()
    assert (out / "notes.txt").read_text() == "the user's own file"
    assert not (out / ".pinchmatch" / "replaced").exists()
    # finished, the new files stay and nothing is kept aside
    publisher = OutputFolder(out)
    with publisher:
        publisher.write_direct(out / "props" / "prop_1.stl", b"new prop 1")
    assert (out / "props" / "prop_1.stl").read_bytes() == b"new prop 1"
    assert not (out / ".pinchmatch" / "replaced").exists()
    # part of the result: the next run prunes it if it goes
    assert read_manifest(out) == ["props/prop_1.stl"]


@pytest.mark.parametrize("publishing", [False, True])
def test_a_run_whose_process_is_killed_is_taken_back_or_finished_by_the_next(tmp_path, publishing):
    """A run's process killed outright cleans nothing up itself: what it wrote straight into OUT (a
    replaced prop, an added object, one being written) is taken back from ``run.json`` by the
    command line's parent or the next run; a publication it had begun is finished from its
    journal."""
    import fcntl

    from pinchmatch.export.folder import undo_killed_run

    out = tmp_path / "out"
    (out / "props").mkdir(parents=True)
    (out / "props" / "prop_1.stl").write_bytes(b"the last result's prop")
    (out / "notes.txt").write_text("the user's own file")
    before = snapshot(out)
    publisher = OutputFolder(out)
    stage = publisher.__enter__()
    publisher.write_direct(out / "props" / "prop_1.stl", b"new prop 1")
    publisher.write_direct(out / "props" / "prop_2.stl", b"new prop 2")
    # recorded, then written: killed while it writes
    publisher.direct(out / "objects" / "a.stl", new=True)
    (out / "objects").mkdir()
    (out / "objects" / ".a.stl.k3J9x_2q.tmp").write_bytes(b"half")
    (stage / "matches.json").write_text("{}")
    if publishing:
        # (not called: the journal below is what a killed publication leaves)
        publisher._publish = lambda: None
        (out / ".pinchmatch" / "commit.json").write_text(sealed("journal",
            {"new": ["matches.json", "props/prop_1.stl", "props/prop_2.stl"],
             "staged": ["matches.json"], "remove": []}))
    fcntl.flock(publisher._lock, fcntl.LOCK_UN)  # the process is gone: its lock with it
    os.close(publisher._lock)
    assert undo_killed_run(out) is publishing
    if publishing:
        assert (out / "matches.json").read_text() == "{}" and (
            out / "props" / "prop_2.stl").exists()
        assert read_manifest(out) == ["matches.json", "props/prop_1.stl", "props/prop_2.stl"]
    else:
        assert snapshot(out) == before
    assert (not (out / ".pinchmatch" / "staging").exists()
            and not (out / ".pinchmatch" / "run.json").exists())
    assert not (out / ".pinchmatch" / "replaced").exists()


@pytest.mark.parametrize("run",
                         [{"undo": [1, "x", ["a.txt", 5], ["b.txt", ["c"]], [7, None]]},
                          {"undo": 3},
                                 {"created": "yes", "undo": [["../victim.txt", None]]}, [1, 2]])
def test_a_run_record_of_any_shape_is_taken_back_safely(tmp_path, run):
    """A run record (``run.json``) of any shape: received (not sealed), it is refused in one line;
    sealed by this user's runs, entries of other shapes are skipped. Either way nothing outside OUT
    and no file of the user's in it is touched, without an internal error."""
    out = tmp_path / "out"
    (out / ".pinchmatch").mkdir(parents=True)
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    (out / "a.txt").write_text("mine")
    (out / ".pinchmatch" / "run.json").write_text(json.dumps(run))
    with pytest.raises(publish.OutputError, match="no run of this user's wrote") as refused:
        recover(out)
    assert "\n" not in str(refused.value)
    if isinstance(run, dict):
        (out / ".pinchmatch" / "run.json").write_text(sealed("run", run))
        recover(out)
    assert victim.read_text() == "keep me" and (out / "a.txt").read_text() == "mine"
