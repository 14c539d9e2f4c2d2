"""The signals that end a run, SIGINT and SIGTERM: raised where they arrive, and remembered.

A signal's exception unwinds the run the documented way (exit 130 or 143, the output folder as it
was). While the pipeline is imported, the handlers only remember the signal: an exception raised in
the middle of a compiled extension's import can crash the interpreter, and :func:`arm`, called once
the pipeline is loaded, raises what came meanwhile. Armed, a signal that arrives during a later import
(numba is imported when its first kernel runs) is delivered again every :data:`RETRY_S` until the
import is over, and raises then. Even armed, a signal can be lost: a library that wraps its optional imports in ``except BaseException`` (trimesh
does) swallows whatever arrives while it imports, and an exception raised inside a callback that
Python cannot unwind (a weak reference's, during an import) is printed as "Exception ignored" and
dropped. So the handlers :func:`handled` installs also remember the signal, such dropped exceptions
are not printed (they are remembered), and :func:`check`, called at the run's safe points (the
pipeline loaded, each result collected, before anything is published), raises the signal again.
"""

from __future__ import annotations

import signal
import sys
import threading
from contextlib import contextmanager

from .errors import Terminated

_received: list[int] = []
_armed: list[bool] = [False]


def interruption(signum: int) -> BaseException:
    """The exception a signal unwinds with: KeyboardInterrupt for SIGINT, Terminated for SIGTERM."""
    return KeyboardInterrupt() if signum == signal.SIGINT else Terminated()


#: how long a signal that arrived during an import waits before it is delivered again (s)
RETRY_S = 0.05


def _importing(frame) -> bool:
    """Whether the frame runs inside an import: importlib's bootstrap on its stack (a module's code,
    or a compiled extension's initialisation, being loaded)."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib._bootstrap"):
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
        if _importing(frame):
            # an exception raised inside an import leaves a compiled extension half initialised (numba's
            # LLVM: the interpreter can crash as it exits); the signal comes again when the import is over
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
