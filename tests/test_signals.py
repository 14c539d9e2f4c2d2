"""A signal at any moment of a run's first seconds ends it the documented way: exit 130 or 143, one
line, the output folder as it was, no process left. Signals arriving while the pipeline is imported
are the hard case: a library's ``except BaseException`` around its optional imports swallows them."""

import os
import signal
import subprocess
import sys
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
    if name == "match":  # more poses: the run lasts well past the latest signal (about 1.4 s at 300 poses here)
        return ["match", "--tangible", prop, "--virtual", *objects, "--jobs", str(jobs), *common, "--count", "3000"]
    if name == "select":
        return ["select", "--tangible", prop, prop, "--virtual", *objects, "-k", "1", "--jobs", str(jobs), *common]
    if name == "design":
        return ["design", "--virtual", *objects, "--evaluations", "3", "--jobs", str(jobs), *common]
    return ["demo", "-o", str(out), "-q"]


CASES = ([("match", jobs, delay, signal.SIGTERM) for jobs in (1, 2) for delay in (0.2, 0.4, 0.7, 1.0, 1.5)]
         + [("match", 1, 0.5, signal.SIGINT), ("match", 2, 0.9, signal.SIGINT)]
         + [(name, jobs, delay, signal.SIGTERM) for name in ("select", "design") for jobs in (1, 2)
            for delay in (0.4, 1.2)]
         + [("demo", 1, delay, sig) for delay in (0.3, 0.8) for sig in (signal.SIGTERM, signal.SIGINT)])


@pytest.mark.parametrize("name, jobs, delay_s, sig", CASES)
def test_an_early_signal_ends_the_run_and_leaves_the_folder_as_it_was(tmp_path, scene, name, jobs, delay_s, sig):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("the user's own file")
    before = snapshot(out)
    argv = [sys.executable, "-m", "pinchmatch", *command(name, scene, out, jobs)]
    proc = subprocess.Popen(argv, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PINCHMATCH_CACHE_DIR": str(tmp_path / "cache")})
    time.sleep(delay_s)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=180)
    expected = 130 if sig == signal.SIGINT else 143
    # -sig: the signal came before Python ran pinchmatch's first line (a slow start), which the default
    # handler ends just as well; never 0, never a traceback
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
    assert err == ["pinchmatch: interrupted; nothing was written"] and not (tmp_path / "w.json").exists()


def test_a_signal_a_library_turns_into_another_error_still_ends_the_run_as_the_signal(tmp_path, capsys, monkeypatch):
    """SIGTERM inside an extension's import comes back as an ImportError (numba's does): exit 143, one line."""
    from pinchmatch.cli import commands
    from pinchmatch.cli.main import main
    from pinchmatch.errors import Terminated

    def command(args):
        try:
            os.kill(os.getpid(), signal.SIGTERM)  # armed: raised as Terminated at the next bytecode
            time.sleep(1.0)
        except Terminated:
            raise ImportError("numba._devicearray failed to import") from None

    monkeypatch.setitem(commands.COMMANDS, "demo", command)
    code = main(["demo", "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 143 and err.startswith("pinchmatch: terminated;") and "ImportError" not in err, err


def test_a_signal_during_an_import_is_raised_when_the_import_is_over(tmp_path, monkeypatch):
    """An exception raised inside an import can leave a compiled extension half initialised (numba's, whose
    interpreter then crashes as it exits): armed, the signal waits for the import to finish."""
    from pinchmatch import signals
    from pinchmatch.errors import Terminated

    (tmp_path / "slow_to_import.py").write_text("import time\ntime.sleep(0.6)\nLOADED = True\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    main_thread = threading.main_thread().ident
    timer = threading.Timer(0.15, signal.pthread_kill, (main_thread, signal.SIGTERM))
    t0 = time.perf_counter()
    with pytest.raises(Terminated), signals.handled():
        signals.arm()
        timer.start()
        try:
            import slow_to_import  # noqa: F401  (the signal arrives while this runs)
            imported = time.perf_counter() - t0
            time.sleep(5.0)  # raised here, within a retry of the import's end
        finally:
            ended = time.perf_counter() - t0
    assert sys.modules["slow_to_import"].LOADED  # the import ran to its end
    assert 0.6 <= imported < ended < imported + 0.5
    sys.modules.pop("slow_to_import")


def test_a_signal_outside_an_import_is_raised_at_once():
    from pinchmatch import signals
    from pinchmatch.errors import Terminated

    timer = threading.Timer(0.1, signal.pthread_kill, (threading.main_thread().ident, signal.SIGTERM))
    t0 = time.perf_counter()
    with pytest.raises(Terminated), signals.handled():
        signals.arm()
        timer.start()
        try:
            time.sleep(5.0)
        finally:
            ended = time.perf_counter() - t0
    assert ended < 1.0


def test_a_signal_while_numba_compiles_a_kernel_is_raised_when_the_kernel_is_ready():
    """numba hands LLVM modules to its engine in two steps; an exception between them frees a module twice
    and the process aborts as it exits: the signal waits for the compilation."""
    from numba import njit

    from pinchmatch import signals
    from pinchmatch.errors import Terminated

    @njit
    def kernel(x):
        return x * 2.0 + 1.0

    timer = threading.Timer(0.02, signal.pthread_kill, (threading.main_thread().ident, signal.SIGTERM))
    with pytest.raises(Terminated), signals.handled():
        signals.arm()
        timer.start()
        assert kernel(1.0) == 3.0  # compiled on this first call, while the signal arrives
        compiled = list(kernel.signatures)
        time.sleep(5.0)
    assert len(compiled) == 1 and kernel(2.0) == 5.0


def test_a_signal_during_a_threaded_kd_tree_query_waits_for_its_threads():
    """scipy joins a query's threads in Python: a signal's exception raised there would leave them writing
    into arrays the unwinding frees (the process crashed as it exited, -11 or glibc's double free)."""
    from scipy.spatial import cKDTree

    from pinchmatch import signals
    from pinchmatch.cores import set_thread_budget, query_tree
    from pinchmatch.errors import Terminated

    rng = np.random.default_rng(0)
    tree = cKDTree(rng.random((200_000, 3)))
    points = rng.random((300_000, 3))
    before = set_thread_budget(2)
    timer = threading.Timer(0.05, signal.pthread_kill, (threading.main_thread().ident, signal.SIGTERM))
    answered = []
    try:
        with pytest.raises(Terminated), signals.handled():
            signals.arm()
            timer.start()
            t0 = time.perf_counter()
            answered.append(query_tree(tree, points, k=8, work=len(points)))
            took = time.perf_counter() - t0
            time.sleep(5.0)
    finally:
        set_thread_budget(before)
    assert took > 0.1 and answered and answered[0][1].shape == (300_000, 8)  # the signal came during the query
    assert not [t for t in threading.enumerate() if "_thread_func" in t.name]  # no query thread left running
