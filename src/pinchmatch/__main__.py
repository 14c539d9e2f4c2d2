"""``python -m pinchmatch``: the command line."""

from .cli.commands import console

console()
