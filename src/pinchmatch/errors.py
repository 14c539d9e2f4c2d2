"""Exceptions raised by pinchmatch.

Every message names the file (when there is one), the problem and the fix,
so the command line can show it as one line.
"""

from __future__ import annotations

import logging
import warnings


class PinchmatchError(Exception):
    """Base class of every error pinchmatch raises on bad input."""


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


def route_warnings(*, verbose: bool) -> None:
    """Send Python warnings (numpy's and trimesh's RuntimeWarnings) to the log, shown with
    ``--verbose`` only: a run prints one line per problem, never a warning from inside a library."""
    logging.captureWarnings(True)
    logging.getLogger("py.warnings").setLevel(logging.WARNING if verbose else logging.CRITICAL)
    warnings.simplefilter("default")
