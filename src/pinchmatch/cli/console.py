"""What the command line shows a person: progress bars, summary tables, one-line notes (rich).

The library never prints; it logs. Only the CLI builds a Presenter. Progress goes to stderr and
only to a terminal; tables and notes go to stdout. ``quiet`` keeps only errors, and ``json``
keeps stdout for the result document alone.
"""

from __future__ import annotations

import os
import sys
import time
from contextlib import contextmanager

from rich import box
from rich.console import Console
from rich.progress import (BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn,
                           TimeElapsedColumn)
from rich.table import Table
from rich.text import Text

#: width for tables written to a file or a pipe, where no terminal says how wide it is (``COLUMNS``
#: does)
PIPE_WIDTH = 200


def _pipe_width() -> int:
    try:
        return max(40, int(os.environ["COLUMNS"]))
    except (KeyError, ValueError):
        return PIPE_WIDTH


#: where stderr is no terminal, a progress line at most this often (s)
PROGRESS_LINE_S = 10.0


class Presenter:
    def __init__(self, *, quiet: bool = False, json_mode: bool = False):
        self.quiet = quiet
        self.json_mode = json_mode
        self.err = Console(stderr=True, highlight=False)
        self.out = Console(file=sys.stdout, highlight=False,
                           width=None if sys.stdout.isatty() else _pipe_width())
        self.show_progress = not quiet and self.err.is_terminal
        # a pipe or a log: plain lines, now and then
        self.show_lines = not quiet and not self.err.is_terminal
        self.show_summary = not quiet and not json_mode

    @contextmanager
    def step(self, description: str, total: int | None = None):
        """A progress bar for one step (a spinner when ``total`` is None).

        Yields ``advance(note=None, *, done=True)``: counts one item done and shows ``note``; with
        ``done=False`` it only shows ``note``, the item now being worked on.
        """
        if not self.show_progress:
            yield self._lines(description, total) if self.show_lines else (lambda note=None, *,
                                                                           done=True: None)
            return
        columns = [SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
                   MofNCompleteColumn(), TimeElapsedColumn()] if total is not None else [
                   SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn()]
        with Progress(*columns, console=self.err, transient=True) as progress:
            task = progress.add_task(description, total=total)

            def advance(note: str | None = None, *, done: bool = True) -> None:
                progress.update(task, advance=1 if done else 0,
                                description=f"{description}: {note}" if note else description)

            yield advance

    def _lines(self, description: str, total: int | None):
        """Where stderr is no terminal: ``advance`` as for :meth:`step`, printing one plain line
        (the step, the count done, the item, the seconds) once ``PROGRESS_LINE_S`` have passed since
        the step began or since the last line; a short run prints none."""
        start = last = time.monotonic()
        done_count = 0

        def advance(note: str | None = None, *, done: bool = True) -> None:
            nonlocal last, done_count
            done_count += 1 if done else 0
            now = time.monotonic()
            if now - last < PROGRESS_LINE_S:
                return
            last = now
            count = f" {done_count}/{total}" if total is not None else ""
            item = f" ({'done: ' if done else 'now: '}{note})" if note else ""
            print(f"{description}:{count}{item}, {now - start:.0f} s", file=sys.stderr, flush=True)

        return advance

    def table(self, rows: list, *, title: str | None = None, legend: list | None = None,
              optional: tuple = ()) -> None:
        """``rows[0]`` is the header; printed to stdout unless quiet or ``--json``, folded to the
        terminal's width (long names wrap instead of being cut), with the ``title`` line above (as
        wide as the terminal, not the table) and the ``legend`` lines below. Where the table is
        wider than the terminal, the ``optional`` columns (header names, the first to go first) are
        left out until it fits, and a legend line names them."""
        if not self.show_summary:
            return
        rows, dropped = _narrowed(rows, optional, self.out.width)
        if dropped:
            legend = [*(legend or []),
                      f"left out to fit {self.out.width} columns: {', '.join(dropped)} (the "
                                       "result file has every column)"]
        if title:
            self.out.print(Text(title), soft_wrap=False)
        table = Table(box=box.SIMPLE_HEAD, pad_edge=False, collapse_padding=True)
        for name in rows[0]:
            table.add_column(name, overflow="fold")
        for row in rows[1:]:
            table.add_row(*(Text(str(v)) for v in row))  # Text: names are not read as markup
        self.out.print(table)
        for line in legend or []:
            self.out.print(Text(line, style="dim"), soft_wrap=False)

    def note(self, message: str) -> None:
        if self.show_summary:
            self.out.print(message, soft_wrap=False, markup=False)  # wrapped at spaces to the width

    def warn(self, message: str) -> None:
        """A warning line on stderr; shown even with ``--quiet``."""
        self.err.print(f"pinchmatch: warning: {message}", soft_wrap=True, markup=False,
                       highlight=False)

    def error(self, message: str) -> None:
        """An error line on stderr; shown even with ``--quiet``."""
        self.err.print(f"pinchmatch: error: {message}", soft_wrap=True, markup=False,
                       highlight=False)

    def document(self, text: str) -> None:
        """The result document on stdout, with ``--json``."""
        if self.json_mode:
            sys.stdout.write(text)
            sys.stdout.flush()


def _narrowed(rows: list, optional: tuple, width: int) -> tuple[list, list]:
    """``rows`` without the ``optional`` columns (in that order) it takes to fit ``width``
    characters, each column as wide as its widest cell with a space between; and the columns left
    out."""
    header = list(rows[0])
    keep = list(range(len(header)))
    dropped = []

    def natural() -> int:
        return sum(max(len(str(r[i])) for r in rows if i < len(r)) for i in keep) + (len(keep) - 1)

    for name in optional:
        if natural() <= width:
            break
        if name in header and header.index(name) in keep:
            keep.remove(header.index(name))
            dropped.append(name)
    if not dropped:
        return rows, []
    return [tuple(r[i] for i in keep if i < len(r)) for r in rows], dropped
