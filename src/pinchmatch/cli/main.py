"""The command line's entry point: parse, dispatch, and turn every ending into an exit code.

Exit codes, in one place: 0 success, 2 bad input or usage (one line on stderr naming the file,
the problem and the fix), 3 ``match`` finished but left out files it could not use (each named
on stderr, in the summary and in ``matches.json``), 130 and 143 interrupted or terminated (the
output folder as it was), 1 unexpected error (a traceback only with ``--verbose``).

Only the parser is imported up front: ``--help``, ``--version`` and a bad option answer without
loading the pipeline (:mod:`pinchmatch.cli.commands` and everything below it).

:func:`main` runs a command in this process (as the tests and other Python code call it); the
console script, :func:`console`, runs it in a child process that it ends at once on Ctrl-C or
SIGTERM (:mod:`pinchmatch.cli.supervise`), so that no signal is ever raised inside the numeric work.
"""

from __future__ import annotations

import logging
import signal
import sys

from ..errors import PinchmatchError, RunError, route_warnings
from ..cores import default_jobs
from ..memory import address_space_problem, out_of_memory_message
from ..runner.forkserver import start_worker_server
from .parser import build_parser, check_option_names, join_vector_values
from .supervise import SIGNAL_EXIT, left_as_it_was, supervise


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    return _main(argv)


def _main(argv: list[str]) -> int:
    verbose = "-v" in argv or "--verbose" in argv
    logging.basicConfig(level=logging.INFO if verbose else logging.WARNING,
                        format="%(name)s: %(message)s")
    route_warnings(verbose=verbose)
    command = None
    try:
        parser = build_parser()
        check_option_names(parser, argv)
        args = parser.parse_args(join_vector_values(argv, parser))
        command = args.command
        if args.command is None:
            build_parser().print_help()
            return 2
        if problem := address_space_problem():
            print(f"pinchmatch: error: {problem}", file=sys.stderr)
            return 2
        if _wants_local_workers(args):
            # it loads the pipeline for the workers while this process does the same
            start_worker_server()
        from .commands import COMMANDS  # the pipeline: loaded for a command, not for --help

        return COMMANDS[args.command](args)
    except PinchmatchError as exc:
        print(f"pinchmatch: error: {exc.cli_message()}", file=sys.stderr)
        return 2
    except RunError as exc:  # not the input's fault: an internal error, in one line
        print(f"pinchmatch: internal error: {exc}", file=sys.stderr)
        return 1
    except MemoryError:  # no input is wrong, and no traceback says more than the limit met
        print(f"pinchmatch: error: {out_of_memory_message()}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        # Ctrl-C where main runs in the terminal's process (not under the console script)
        return _interrupted(signal.SIGINT, command)
    except Exception as exc:  # an internal error: say so, traceback on request
        if verbose:
            raise
        print(f"pinchmatch: internal error: {type(exc).__name__}: {exc}; rerun with --verbose and "
              "report it",
              file=sys.stderr)
        return 1


def _interrupted(signum: int, command: str | None) -> int:
    """The run ended by a signal: one line, exit 130 (SIGINT) or 143 (SIGTERM)."""
    word = "interrupted" if signum == signal.SIGINT else "terminated"
    print(f"pinchmatch: {word}; {left_as_it_was(command)}", file=sys.stderr)
    return SIGNAL_EXIT[signum]


def _wants_local_workers(args) -> bool:
    """The command will run local worker processes (``match`` or ``select`` with more than one job,
    no cluster)."""
    if args.command not in ("match", "select") or getattr(args, "scheduler", None):
        return False
    jobs = default_jobs() if args.jobs is None else args.jobs
    return jobs > 1


def console() -> None:
    """The console script: the command in a child process, ended at once on a signal."""
    argv = sys.argv[1:]
    if not argv or any(a in ("-h", "--help", "--version") for a in argv):
        sys.exit(main(argv))  # answered by the parser alone: nothing to end
    if "--serve" in argv:
        # a server that Ctrl-C stops, as it should: in this process, no numeric work
        sys.exit(main(argv))
    try:  # a bad command line is answered here, before any process is started
        parser = build_parser()
        check_option_names(parser, argv)
        parser.parse_args(join_vector_values(argv, parser))
    except PinchmatchError as exc:
        print(f"pinchmatch: error: {exc.cli_message()}", file=sys.stderr)
        sys.exit(2)
    sys.exit(supervise(argv, main))
