"""The command line: ``pinchmatch`` and its subcommands (:mod:`.commands`), shown through a console
presenter (:mod:`.console`)."""

from .commands import console, main

__all__ = ["console", "main"]
