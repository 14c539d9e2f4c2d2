"""How many cores a run may use.

Imports nothing heavy, so that the command line can say the default in its help without
loading the pipeline.
"""

from __future__ import annotations

import os


def default_jobs() -> int:
    """All the cores this process may use (its CPU affinity where the system has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1
