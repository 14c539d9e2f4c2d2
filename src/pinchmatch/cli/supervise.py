"""The command line's process: it runs the command in a child process and ends it at once on a
signal.

``pinchmatch`` (the console script, ``python -m pinchmatch``) forks before it loads anything of the
pipeline. The child runs the command (:func:`pinchmatch.cli.main.main`) in a process group of its
own, with its local workers, fork server and resource tracker; it handles no signal itself. On
SIGINT or SIGTERM the parent kills that whole group (SIGKILL), puts the output back as a killed run
leaves it (:func:`pinchmatch.export.folder.undo_killed_run`: a publication under way is finished
from its journal, anything else staged or written into OUT is taken back), says one line and exits
with 130 or
143. A signal's exception is never raised inside the numeric work, so nothing the geometry does
     needs
to know about signals: the kernels, KD-tree queries and imports run to their end or die with their
process.

A parent killed outright (SIGKILL) takes the child with it (``PR_SET_PDEATHSIG``); the next run or
``pinchmatch view`` then puts OUT back as the parent would have.
"""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

#: exit codes of a run ended by SIGINT and SIGTERM
SIGNAL_EXIT = {signal.SIGINT: 130, signal.SIGTERM: 143}
#: the commands that write one file (-o FILE), not an output folder
FILE_COMMANDS = ("calibrate", "poses", "features")
#: the commands that publish a result folder (-o OUT)
FOLDER_COMMANDS = ("match", "demo", "select", "design")
#: Linux's prctl option that sends the child a signal when its parent dies
PR_SET_PDEATHSIG = 1


def supervise(argv: list[str], run) -> int:
    """``run(argv)`` (the command line's :func:`~pinchmatch.cli.main.main`) in a child process;
    return its exit code, or 130/143 after a signal."""
    received: list[int] = []
    child = [0]

    def stop(signum, frame):
        received.append(signum)
        if child[0]:
            _kill_group(child[0])

    previous = {s: signal.signal(s, stop) for s in SIGNAL_EXIT}
    published = _published(argv)  # what OUT held: a run that finished before the signal changed it
    try:
        pid = os.fork()
        if pid == 0:  # the child: the command, in a process group of its own, dying with its parent
            for s, handler in previous.items():
                signal.signal(s, handler)
            os.setpgid(0, 0)
            _die_with_parent()
            code = 1
            try:
                code = run(argv)
            except SystemExit as exc:  # --version, --help
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
            finally:
                for stream in (sys.stdout, sys.stderr):
                    try:
                        stream.flush()
                    except (OSError, ValueError):
                        pass
                os._exit(code)
        child[0] = pid
        try:
            # at once, so that a signal before the child's own call finds its group
            os.setpgid(pid, pid)
        except (PermissionError, ProcessLookupError):
            pass  # the child set it, or is gone already
        if received:  # a signal between the handlers and the fork
            _kill_group(pid)
        _, status = os.waitpid(pid, 0)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    code = os.waitstatus_to_exitcode(status)
    if received:
        return _ended_by(received[0], argv, published)
    if code < 0:  # the child was killed from outside (the system ran out of memory, a kill -9)
        if -code in SIGNAL_EXIT:
            return _ended_by(-code, argv, published)
        _undo(argv, published)
        print("pinchmatch: internal error: the run's process was killed "
              f"({signal.Signals(-code).name}; out of "
              "memory?); run again with fewer --jobs or a smaller --count", file=sys.stderr)
        return 1
    return code


def _kill_group(pid: int) -> None:
    try:
        os.killpg(pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def _die_with_parent() -> None:
    """Have the kernel kill this process when its parent dies (Linux; elsewhere nothing)."""
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass


def _ended_by(signum: int, argv: list[str], published: bytes | None) -> int:
    """The run was ended by a signal: OUT put back, one line, exit 130 (SIGINT) or 143 (SIGTERM)."""
    word = "interrupted" if signum == signal.SIGINT else "terminated"
    print(f"pinchmatch: {word}; {_undo(argv, published)}", file=sys.stderr)
    return SIGNAL_EXIT[signum]


def _published(argv: list[str]) -> bytes | None:
    """The manifest of the result in the command's output folder (None: none, or not a folder
    command)."""
    command, output = _command_and_output(argv)
    if command not in FOLDER_COMMANDS or output is None:
        return None
    try:
        return (output / ".pinchmatch" / "manifest.json").read_bytes()
    except OSError:
        return None


def _undo(argv: list[str], published: bytes | None = None) -> str:
    """Put the command's output back as a killed run leaves it; say what it holds now."""
    command, output = _command_and_output(argv)
    if command is None or command == "cache" or output is None:
        return left_as_it_was(command)
    from ..files import remove_temporaries

    try:
        if command in FOLDER_COMMANDS or command == "view":
            from ..export.folder import undo_killed_run

            finished = undo_killed_run(output)
            remove_temporaries(output / "index.html")
            if finished:
                return "the output folder holds the new result (it was being published)"
            if command in FOLDER_COMMANDS and _published([*argv]) != published:
                return "the output folder holds the new result (the run had finished)"
            return left_as_it_was(command)
        remove_temporaries(output)
    except Exception as exc:  # noqa: BLE001 - the run has ended; say what could not be put back
        return f"{output} could not be put back ({exc}); the next run into it will"
    return left_as_it_was(command)


def left_as_it_was(command: str | None) -> str:
    """What an interrupted run of ``command`` leaves, in its words."""
    if command in FILE_COMMANDS:
        return "nothing was written"
    if command is None:
        return "nothing was changed"
    if command == "cache":
        return "the entries not yet deleted stay in the cache"
    return "the output folder holds what it held before"


def _command_and_output(argv: list[str]) -> tuple[str | None, Path | None]:
    """The command and its output (a folder, or a file), from the command line as given."""
    from .parser import build_parser, join_vector_values

    try:
        args = build_parser().parse_args(join_vector_values(list(argv)))
    # a bad command line: the child said so, or the signal came first
    except BaseException:  # noqa: BLE001
        return None, None
    command = getattr(args, "command", None)
    if command == "view":
        folder = Path(args.folder)
        return command, (folder.parent if folder.suffix in (".json", ".jsonl") else folder)
    output = getattr(args, "output", None)
    return command, (Path(output) if output else None)
