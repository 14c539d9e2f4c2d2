"""Exceptions raised by pinchmatch.

Every message names the file (when there is one), the problem and the fix,
so the command line can show it as one line.
"""

from __future__ import annotations


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
