"""Exceptions raised by pinchmatch.

Every message names the file (when there is one), the problem and the fix,
so the command line can show it as one line.
"""

from __future__ import annotations

import logging
import re
import warnings


#: an option named in a message: rendered as a keyword argument for Python, as a flag for the
#: command line
_OPTION = re.compile(r"\{option:([a-z_]+)=([^}]*)\}")


def option(name: str, value) -> str:
    """``name=value`` as a message names it: ``units="m"`` in Python (``str(error)``), ``--units m``
    on the command line (:meth:`PinchmatchError.cli_message`)."""
    return "{option:%s=%s}" % (name, value)


def in_manifest(error: "PinchmatchError", manifest: str) -> "PinchmatchError":
    """``error`` with the options it names as the keys of an object's manifest entry (``units = "m"
    in its entry of props.toml``): the object's options come from there, not from the command
    line."""
    text = _OPTION.sub(lambda m: f'{m[1]} = "{m[2]}" in its entry of {manifest}',
                       str(error.args[0]))
    return type(error)(text)


class PinchmatchError(Exception):
    """Base class of every error pinchmatch raises on bad input.

    ``str(error)`` speaks the library's terms (``units="m"``); :meth:`cli_message` the command
    line's (``--units m``), for the options a message names through :func:`option`."""

    def __str__(self) -> str:
        return _OPTION.sub(lambda m: f'{m[1]}="{m[2]}"', super().__str__())

    def cli_message(self) -> str:
        return _OPTION.sub(lambda m: f"--{m[1].replace('_', '-')} {m[2]}", super().__str__())


class MeshError(PinchmatchError):
    """A mesh file that cannot be read or used."""


class ConfigError(PinchmatchError):
    """An option value or an input file of options that is not valid."""


class NoFeasiblePinchError(PinchmatchError):
    """No candidate pinch passed the feasibility rules."""


class ContactError(PinchmatchError):
    """A user-given contact point that cannot be placed on the surface."""


class OutputError(PinchmatchError):
    """An output that cannot be written: a read-only or full file system, no permission."""


class InternalError(RuntimeError):
    """An invariant of pinchmatch's own broke (a bug, not the input's fault): report it."""


class RunError(Exception):
    """The run itself broke (a worker died), not the input: one line, exit 1, and what to change."""


def route_warnings(*, verbose: bool) -> None:
    """Send Python warnings (numpy's and trimesh's RuntimeWarnings) to the log, shown with
    ``--verbose`` only: a run prints one line per problem, never a warning from inside a library."""
    logging.captureWarnings(True)
    logging.getLogger("py.warnings").setLevel(logging.WARNING if verbose else logging.CRITICAL)
    # trimesh logs its own fallbacks ("unable to use sparse matrix, falling back!"), with a
    # traceback when an exception it caught was a signal's: notes for its developers, not for a
    # run's one line
    logging.getLogger("trimesh").setLevel(logging.WARNING if verbose else logging.CRITICAL)
    warnings.simplefilter("default")
