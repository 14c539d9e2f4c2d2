"""How much memory a run may still take, and what limits it: the machine, the process's address
space, its control group.

Three limits bound a process on Linux, and any one can end a run: what the machine has free
(``MemAvailable``), the address space a shell's ``ulimit -v`` allows (``RLIMIT_AS``, counted in
virtual memory, of which numpy, numba and the ray engine reserve more than they touch), and the
memory of its control group (a container's or a systemd unit's ``memory.max``).
:func:`memory_headroom` gives the least of them and names it, so that a refusal or a run out of
memory says which limit to raise.

Imports nothing heavy: the command line uses it before it loads the pipeline.
"""

from __future__ import annotations

import resource
from pathlib import Path

#: the address space below which no run starts: the interpreter, numpy, numba's compiled kernels,
#: the ray engine and the worker threads take about 0.8 GiB of it before any mesh (measured on
#: x86_64 Linux)
MIN_ADDRESS_SPACE_BYTES = 1 << 30
#: a control group's files, version 2 then version 1 (what it may hold, what it holds)
CGROUP_FILES = (("memory.max", "memory.current"),
                ("memory.limit_in_bytes", "memory.usage_in_bytes"))
#: where Linux says all this (tests point them at files of their own)
PROC_MEMINFO, PROC_STATUS, PROC_CGROUP = "/proc/meminfo", "/proc/self/status", "/proc/self/cgroup"
CGROUP_ROOT = "/sys/fs/cgroup"


def _proc_value(path: str, key: str) -> int | None:
    """A ``key: N kB`` line of a /proc file, in bytes (None where the file or the line is
    missing)."""
    try:
        with open(path) as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def _meminfo(key: str) -> int | None:
    return _proc_value(PROC_MEMINFO, key)


def _own_status(key: str) -> int | None:
    return _proc_value(PROC_STATUS, key)


def address_space_limit() -> int | None:
    """``ulimit -v``'s limit on this process (bytes), or None where there is none."""
    try:
        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (OSError, ValueError):
        return None
    return None if soft == resource.RLIM_INFINITY else int(soft)


def _cgroup_folder() -> tuple[Path, Path] | None:
    """(this process's control group folder, the hierarchy's root folder), or None."""
    try:
        lines = Path(PROC_CGROUP).read_text().splitlines()
    except OSError:
        return None
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) == 3 and (parts[1] == "" or "memory" in parts[1].split(",")):
            base = Path(CGROUP_ROOT) if parts[1] == "" else Path(CGROUP_ROOT) / "memory"
            folder = base / parts[2].lstrip("/")
            if folder.is_dir():
                return folder, base
    return None


def _group_limit(folder: Path) -> tuple[int, int] | None:
    """(limit, free) bytes of one control group folder, or None where it sets no limit."""
    for limit_name, usage_name in CGROUP_FILES:
        try:
            limit_text = (folder / limit_name).read_text().strip()
            usage = int((folder / usage_name).read_text().strip())
        except (OSError, ValueError):
            continue
        if limit_text == "max" or not limit_text.isdigit() or int(limit_text) >= 1 << 60:
            return None
        return int(limit_text), max(int(limit_text) - usage, 0)
    return None


def cgroup_headroom() -> tuple[int, int] | None:
    """(limit, free) bytes of the tightest control group this process is in: its own or any group
    above it up to the hierarchy's root (a systemd slice limits every unit below it), the least
    free; None where none sets a limit."""
    found = _cgroup_folder()
    if found is None:
        return None
    folder, root = found
    limits = []
    while True:
        limit = _group_limit(folder)
        if limit is not None:
            limits.append(limit)
        if folder == root or root not in folder.parents:
            break
        folder = folder.parent
    return min(limits, key=lambda x: x[1]) if limits else None


def memory_headroom() -> tuple[int, str] | None:
    """(bytes, which limit) of the least memory this process may still take: the machine's free
    memory, the address space left under ``ulimit -v``, or its control group's; None where none is
    known."""
    limits = []
    free = _meminfo("MemAvailable")
    if free is not None:
        limits.append((free, f"{gib(free)} free on this machine"))
    space = address_space_limit()
    if space is not None:
        used = _own_status("VmSize") or 0
        limits.append((max(space - used, 0),
                       f"{gib(max(space - used, 0))} of address space left under "
                                             f"'ulimit -v' ({gib(space)})"))
    group = cgroup_headroom()
    if group is not None:
        limits.append((group[1],
                       f"{gib(group[1])} left of the control group's {gib(group[0])} (container "
                       "limit)"))
    return min(limits) if limits else None


def gib(n_bytes: float) -> str:
    return f"{n_bytes / 2**30:.1f} GiB"


def address_space_problem() -> str | None:
    """Why no run can start under this process's ``ulimit -v`` (None where it is large enough)."""
    space = address_space_limit()
    if space is not None and space < MIN_ADDRESS_SPACE_BYTES:
        return (f"'ulimit -v' allows {gib(space)} of address space, less than the "
                f"{gib(MIN_ADDRESS_SPACE_BYTES)} "
                "pinchmatch needs before it reads any mesh; raise it (ulimit -v unlimited)")
    return None


def out_of_memory_message() -> str:
    """The line for a run that ran out of memory: the limit it met and what to do."""
    limits = [f"ulimit -v {gib(s)}" for s in [address_space_limit()] if s is not None]
    group = cgroup_headroom()
    if group is not None:
        limits.append(f"control group {gib(group[0])}")
    total = _meminfo("MemTotal")
    if total is not None:
        limits.append(f"machine {gib(total)}")
    return (f"ran out of memory (limits: {', '.join(limits) or 'unknown'}); give the run more "
            "memory, run fewer "
            "jobs at once (--jobs 1), or decimate the largest meshes (to about a million faces)")
