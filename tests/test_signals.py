"""A signal at any moment of a run's first seconds ends it the documented way: exit 130 or 143, one
line, the output folder as it was, no process left. Signals arriving while the pipeline is imported
are the hard case: a library's ``except BaseException`` around its optional imports swallows
them."""

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest

from pinchmatch.cli.commands import example_mesh_path
from pinchmatch.mesh.shapes import ellipsoid

from test_publish import _pgid_members, snapshot


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    root = tmp_path_factory.mktemp("scene")
    for k, axes in enumerate([(30.0, 20.0, 15.0), (40.0, 22.0, 18.0)]):
        ellipsoid(axes, faces=1500, triangulation="random", seed=k).mesh.export(root / f"e{k}.stl")
    return root


def command(name, scene, out, jobs):
    prop, objects = str(example_mesh_path()), [str(p) for p in sorted(scene.glob("*.stl"))]
    common = ["--count", "300", "-q", "--no-cache", "-o", str(out)]
    if name == "match":
        # more poses: the run lasts well past the latest signal (about 1.4 s at 300 poses here)
        return (["match", "--tangible", prop, "--virtual", *objects, "--jobs", str(jobs), *common,
                 "--count", "3000"])
    if name == "select":
        return (["select", "--tangible", prop, prop, "--virtual", *objects, "-k", "1", "--jobs",
                 str(jobs), *common])
    if name == "design":
        return ["design", "--virtual", *objects, "--evaluations", "3", "--jobs", str(jobs), *common]
    return ["demo", "-o", str(out), "-q"]


CASES = ([("match", jobs, delay, signal.SIGTERM) for jobs in (1, 2)
          for delay in (0.2, 0.4, 0.7, 1.0, 1.5)]
         + [("match", 1, 0.5, signal.SIGINT), ("match", 2, 0.9, signal.SIGINT)]
         + [(name, jobs, delay, signal.SIGTERM) for name in ("select", "design") for jobs in (1, 2)
            for delay in (0.4, 1.2)]
         + [("demo", 1, delay, sig) for delay in (0.3, 0.8)
            for sig in (signal.SIGTERM, signal.SIGINT)])


@pytest.mark.parametrize("name, jobs, delay_s, sig", CASES)
def test_an_early_signal_ends_the_run_and_leaves_the_folder_as_it_was(
    tmp_path, scene, name, jobs, delay_s, sig):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("the user's own file")
    before = snapshot(out)
    argv = [sys.executable, "-m", "pinchmatch", *command(name, scene, out, jobs)]
    proc = subprocess.Popen(argv, start_new_session=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PINCHMATCH_CACHE_DIR": str(tmp_path / "cache")})
    time.sleep(delay_s)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=180)
    expected = 130 if sig == signal.SIGINT else 143
    # -sig: the signal came before Python ran pinchmatch's first line (a slow start), which the
    # default handler ends just as well; never 0, never a traceback
    assert proc.returncode in (expected, -sig), (proc.returncode, err)
    if proc.returncode > 0:
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert snapshot(out) == before  # nothing published, nothing of the user's touched
    assert not (out / ".pinchmatch" / "staging").exists()
    deadline = time.time() + 15
    while _pgid_members(proc.pid) and time.time() < deadline:
        time.sleep(0.2)
    assert _pgid_members(proc.pid) == []  # no worker, no resource tracker outlives the run


def test_the_end_of_the_stage_reports_never_waits_on_a_lock_a_killed_worker_holds():
    """A worker killed while it reports a stage holds the queue's write lock for ever: the run's end
    must not wait for it."""
    import threading

    from pinchmatch.runner.executors import LocalExecutor

    executor = LocalExecutor(1)
    try:
        assert executor._stages._wlock.acquire(timeout=5)  # as the killed worker left it
        shown = []
        ended = threading.Event()

        def run():
            with executor.stages(lambda *item: shown.append(item)):
                pass
            ended.set()

        threading.Thread(target=run, daemon=True).start()
        assert ended.wait(10)
    finally:
        executor._stages._wlock.release()
        executor.close()


def test_an_interrupted_calibrate_says_nothing_was_written(tmp_path, monkeypatch, capsys):
    from pinchmatch.cli.main import main
    from pinchmatch.match import calibrate as calibrate_module

    table = tmp_path / "r.csv"
    table.write_text("rating,width_jnd\n6,0.1\n5,0.5\n3,1.2\n2,1.5\n4,0.8\n")

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(calibrate_module, "calibrate", interrupted)
    assert main(["calibrate", str(table), "-o", str(tmp_path / "w.json")]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert (err == ["pinchmatch: interrupted; nothing was written"]
            and not (tmp_path / "w.json").exists())


FINISHED_THEN_WAITS = '''
import sys, time
from pinchmatch.cli.supervise import supervise
from pinchmatch.export.folder import OutputFolder

def run(argv):
    out = argv[argv.index("-o") + 1]
    with OutputFolder(out) as stage:
        (stage / "matches.json").write_text("{}")
    print("published", flush=True)
    time.sleep(30)  # the signal comes after the result is out
    return 0

sys.exit(supervise(sys.argv[1:], run))
'''


def test_a_signal_after_the_result_is_published_says_so(tmp_path):
    """The run's process has published when the signal comes: OUT keeps the new result, and the line
    says so."""
    script = tmp_path / "finished.py"
    script.write_text(FINISHED_THEN_WAITS)
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, str(script), "match", "--tangible", "a.stl",
                             "--virtual", "b.stl", "-o", str(out)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    assert proc.stdout.readline().strip() == "published"
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 143 and err.strip() == ("pinchmatch: terminated; the output folder "
                                                      "holds the new "
                                                      "result (the run had finished)"), err
    assert (out / "matches.json").read_text() == "{}"


@pytest.mark.parametrize("delay_s", [0.1, 0.3])
def test_a_ctrl_c_while_the_fork_server_loads_the_pipeline_prints_no_traceback(delay_s):
    """The fork server imports the whole pipeline before Python's multiprocessing installs its own
    handlers; SIGINT sent to it in that time (a terminal's Ctrl-C reaches the whole group) is
    ignored, so no traceback reaches the user's terminal, and the server stays up for the
    workers."""
    script = textwrap.dedent(f"""
        import os, signal, sys, time
        from multiprocessing import forkserver
        from pinchmatch.runner.forkserver import start_worker_server
        if not start_worker_server():
            print("no fork server"); sys.exit(0)
        pid = forkserver._forkserver._forkserver_pid
        time.sleep({delay_s})
        os.kill(pid, signal.SIGINT)
        time.sleep(3.0)
        with open(f"/proc/{{pid}}/status") as fh:
            state = [line for line in fh if line.startswith("State:")][0]
        print("alive" if "Z" not in state.split()[1] else "dead")
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr
    if proc.stdout.strip() == "no fork server":
        pytest.skip("no fork server on this system")
    assert proc.stdout.strip() == "alive"
    assert "Traceback" not in proc.stderr and "KeyboardInterrupt" not in proc.stderr, proc.stderr
