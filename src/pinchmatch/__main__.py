"""``python -m pinchmatch``: the command line."""

from .cli.main import console

console()
