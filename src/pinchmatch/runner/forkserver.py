"""Local workers forked from a server that holds the pipeline loaded already.

A local worker started fresh (``spawn``) imports the pipeline and loads the compiled kernels before
its first task: over a second, in every worker of every run, while the cores could be working. On
systems with multiprocessing's fork server (Linux, macOS) a run starts that server as soon as it
knows it will want local workers (:func:`start_worker_server`, called by the command line right
after parsing), and the server loads all that once (:mod:`pinchmatch.runner.preload`) while the
run's own process loads and reads its input. Each worker is then a fork of the server: it starts in
milliseconds with nothing left to import or compile.

What forks is sane: the server is started with BLAS held to one thread (no thread pool to lose in
the fork), does nothing but load, and each worker sets its own share of the cores
(:func:`pinchmatch.runner.worker.init_worker`). Where there is no fork server, workers are spawned.

The server starts with SIGINT ignored, a disposition that survives its ``exec``: it imports the
whole pipeline before it installs its own handlers, and a Ctrl-C in that second would print Python's
traceback. The command line's parent ends a run by killing its process group
(:mod:`pinchmatch.cli.supervise`), the server and its workers with it.

Imports nothing heavy: the command line calls it before loading the pipeline itself.
"""

from __future__ import annotations

import multiprocessing
import os
import signal

#: the module the server imports before it forks any worker
PRELOAD = "pinchmatch.runner.preload"
#: environment of the server while it starts: BLAS libraries start no threads of their own
SERVER_ENVIRONMENT = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def worker_context():
    """The multiprocessing context local workers start from: the fork server where there is one
    (loaded with :data:`PRELOAD`), else ``spawn``."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload([PRELOAD])
    return context


def start_worker_server() -> bool:
    """Start the fork server now, if there is one, so that it loads while this process works; return
    whether it runs. Workers started later fork from it
    (:class:`pinchmatch.runner.executors.LocalExecutor`)."""
    if worker_context().get_start_method() != "forkserver":
        return False
    from multiprocessing import forkserver

    before = {name: os.environ.get(name) for name in SERVER_ENVIRONMENT}
    os.environ.update(SERVER_ENVIRONMENT)
    interrupt = signal.signal(signal.SIGINT, signal.SIG_IGN)  # inherited through the server's exec
    try:
        forkserver.ensure_running()
    finally:
        signal.signal(signal.SIGINT, interrupt)
        for name, value in before.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
    return True
