"""``python -m pinchmatch``: the command line."""

from .cli import console

console()
