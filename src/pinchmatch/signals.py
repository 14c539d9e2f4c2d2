"""The signals that end a run, SIGINT and SIGTERM: raised where they arrive, and remembered.

A signal's exception unwinds the run the documented way (exit 130 or 143, the output folder as it
was). While the pipeline is imported, the handlers only remember the signal: an exception raised in
the middle of a compiled extension's import can crash the interpreter, and :func:`arm`, called once
the pipeline is loaded, raises what came meanwhile.

Armed, a signal waits where its exception would leave native work half done, and is delivered again
every :data:`RETRY_S` until that is over:
- during an import (numba is imported when its first kernel runs): a compiled extension half
  initialised;
- while numba loads or compiles a kernel (about 10 s the first time, a fraction of a second from
  numba's cache): LLVM modules handed to the engine in two steps, one of them then freed twice;
- inside :func:`deferred` (a KD-tree query on several threads, which scipy joins in Python): threads
  left writing into arrays the unwinding frees.
Raised there, the exception can crash the process as it exits, after the run's one line (glibc's
"double free", or a segmentation fault).

Even armed, a signal can be lost: a library that wraps its optional imports in ``except
BaseException`` (trimesh does) swallows whatever arrives while it imports, and an exception raised
inside a callback that Python cannot unwind (a weak reference's) is printed as "Exception ignored"
and dropped. So the handlers :func:`handled` installs also remember the signal, such dropped
exceptions are not printed (they are remembered), and :func:`check`, called at the run's safe points
(the pipeline loaded, each result collected, before anything is published), raises the signal again.
"""

from __future__ import annotations

import signal
import sys
import threading
from contextlib import contextmanager

from .errors import Terminated

_received: list[int] = []
_armed: list[bool] = [False]
_deferred: list[int] = [0]


def interruption(signum: int) -> BaseException:
    """The exception a signal unwinds with: KeyboardInterrupt for SIGINT, Terminated for SIGTERM."""
    return KeyboardInterrupt() if signum == signal.SIGINT else Terminated()


#: how long a signal that arrived where it must wait is held before it is delivered again (s)
RETRY_S = 0.05
#: the modules in whose code a signal waits: importlib's (an import: a compiled extension half
#: initialised), and numba's and llvmlite's, which hand native objects between Python wrappers and LLVM
#: in two steps (``ExecutionEngine.add_module``: an exception between them frees a module twice, and the
#: process aborts as it exits)
WAIT_IN = ("importlib._bootstrap", "importlib._bootstrap_external", "numba", "llvmlite")


def _must_wait(frame) -> bool:
    """Whether the frame, or one that called it, runs the code of a module of :data:`WAIT_IN`."""
    while frame is not None:
        name = frame.f_globals.get("__name__") or ""
        if any(name == m or name.startswith(m + ".") for m in WAIT_IN):
            return True
        frame = frame.f_back
    return False


def _again(signum: int) -> None:
    """Deliver the signal to the main thread once more, if the run still handles signals."""
    if _received and _armed[0] and signal.getsignal(signum) is _remember:
        signal.pthread_kill(threading.main_thread().ident, signum)


def _remember(signum, frame):
    _received.append(signum)
    if _armed[0]:
        if _deferred[0] or _must_wait(frame):  # the signal comes again until that code is done
            timer = threading.Timer(RETRY_S, _again, (signum,))
            timer.daemon = True
            timer.start()
            return
        raise interruption(signum)


@contextmanager
def handled():
    """While the block runs (in the main thread), SIGINT and SIGTERM are remembered, and raised once
    :func:`arm` has been called."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _received.clear()
    _armed[0] = False
    previous = {s: signal.signal(s, _remember) for s in (signal.SIGINT, signal.SIGTERM)}
    hook = sys.unraisablehook

    def quiet(unraisable):
        if not (_received and isinstance(unraisable.exc_value, (KeyboardInterrupt, Terminated))):
            hook(unraisable)

    sys.unraisablehook = quiet
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        sys.unraisablehook = hook
        _received.clear()
        _armed[0] = False


@contextmanager
def deferred():
    """While the block runs in the main thread, an armed signal waits for it to end (delivered again
    every :data:`RETRY_S`): for calls that an exception must not leave half done, such as a call that
    joins threads in Python while they still write into the caller's arrays."""
    main = threading.current_thread() is threading.main_thread()
    if main:
        _deferred[0] += 1
    try:
        yield
    finally:
        if main:
            _deferred[0] -= 1


def arm() -> None:
    """From now on a signal raises where it arrives; one that came before is raised now."""
    _armed[0] = True
    check()


def received() -> int | None:
    """The first signal received since :func:`handled` began, or None."""
    return _received[0] if _received else None


def check() -> None:
    """Raise the first signal received since :func:`handled` began, in case its exception was swallowed."""
    if _received:
        raise interruption(_received[0])
