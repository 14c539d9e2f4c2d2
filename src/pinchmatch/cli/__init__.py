"""The command line: ``pinchmatch`` (:mod:`.main`: parse and dispatch), its options
(:mod:`.parser`), its subcommands (:mod:`.commands`) and what they show (:mod:`.console`)."""

from .main import console, main

__all__ = ["console", "main"]
