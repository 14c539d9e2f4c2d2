"""Writing files whole: every file pinchmatch writes goes through :class:`AtomicFile`.

A temporary file beside the target, renamed over it when complete: a reader sees the old file or
the new one, never half of one, and an error leaves the old one. Every file gets ordinary
permissions (0666 less the umask). A file that cannot be written (no permission, a read-only or
full file system) is an :class:`errors.OutputError` naming it: one line for the command line.

Small input files that are not meshes (poses, ratings, weights) are read whole by
:func:`read_input`, which turns every way of failing into one :class:`errors.ConfigError` line
naming the file.
"""

from __future__ import annotations

import os
import re
import stat
import tempfile
from pathlib import Path

from .errors import ConfigError, OutputError

#: the control folder of a folder pinchmatch published a result into (``OUT/.pinchmatch``)
RESULT_CONTROL = ".pinchmatch"


def holds_result(folder: str | os.PathLike) -> bool:
    """Whether ``folder`` holds a result pinchmatch published (its files are outputs, never
    inputs)."""
    return (Path(folder) / RESULT_CONTROL / "manifest.json").is_file()


class AtomicFile:
    """The one way pinchmatch writes a file: into a temporary file beside it, then renamed over it
    (``commit``), so a reader sees the old file or the new one, never half of one; ``abort`` (or an
    error) leaves the old one. Every file gets ordinary permissions (0666 less the umask).

    ``file`` is the open handle (text, UTF-8, or ``binary``); it may be written over time, as a
    stream is. Raises OutputError, naming the file, when it cannot be written (no permission, a
    read-only or full file system).
    """

    def __init__(self, path: str | os.PathLike, *, binary: bool = False):
        self.path = Path(path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            fd, self._tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".tmp",
                                             dir=self.path.parent)
        except OSError as exc:
            raise self._error(exc) from None
        self.file = os.fdopen(fd, "wb") if binary else os.fdopen(fd, "w", encoding="utf-8",
                                                                 newline="")

    def _error(self, exc: OSError) -> OutputError:
        return OutputError(f"{self.path}: cannot write it ({exc.strerror or exc}); free some "
                           "space, or choose a writable place for the output")

    def write(self, data) -> None:
        try:
            self.file.write(data)
        except OSError as exc:
            self.abort()
            raise self._error(exc) from None

    def commit(self) -> None:
        try:
            self.file.close()
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(self._tmp, 0o666 & ~umask)  # mkstemp makes 0600
            os.replace(self._tmp, self.path)
        except OSError as exc:
            self.abort()
            raise self._error(exc) from None

    def abort(self) -> None:
        """Drop the temporary file; on a full disk, closing it fails again, and it goes all the
        same."""
        try:
            self.file.close()
        except OSError:
            pass
        try:
            os.unlink(self._tmp)
        except FileNotFoundError:
            pass


def read_input(path: str | os.PathLike, what: str, *, limit_bytes: int, too_big: str = "") -> bytes:
    """The bytes of a small input file (``what``: "poses file", "ratings table"...), or a
    ConfigError naming the file: missing, a folder, not a regular file, unreadable, or larger than
    ``limit_bytes`` (``too_big`` adds what to do then)."""
    path = os.fspath(path)
    try:
        # a named pipe opens at once instead of waiting
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        with open(fd, "rb") as fh:
            if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
                raise ConfigError(f"{path}: not a regular file (a device or a pipe); give a {what}")
            raw = fh.read(limit_bytes + 1)
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such {what}; check the path") from None
    except IsADirectoryError:
        raise ConfigError(f"{path}: is a folder; give a {what}") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot be read ({exc.strerror or exc}); check its "
                          "permissions") from None
    if len(raw) > limit_bytes:
        raise ConfigError(f"{path}: larger than {limit_bytes // 2**20} MiB, too big for a {what}"
                          + (f"; {too_big}" if too_big else ""))
    return raw


def write_atomic(path: str | os.PathLike, text: str | bytes) -> None:
    """Write ``text`` (or bytes) to ``path`` whole (:class:`AtomicFile`)."""
    out = AtomicFile(path, binary=isinstance(text, bytes))
    try:
        out.write(text)
    except BaseException:
        out.abort()
        raise
    out.commit()


def check_writable(path: str | os.PathLike, *, folder: bool) -> None:
    """Before any work: raise OutputError unless ``path`` (a folder when ``folder``, else a file)
    can be created or written, naming the target."""
    path = Path(path)
    if path.exists():
        if folder and not path.is_dir():
            raise OutputError(f"{path}: -o names a file; give a folder for the results")
        if not folder and path.is_dir():
            raise OutputError(f"{path}: -o names a folder; give a file name for the result")
        target = path if folder else path.parent
    else:
        target = path.parent
        while not target.exists() and target != target.parent:
            target = target.parent
        if not target.is_dir():
            raise OutputError(f"{path}: {target} is a file, so the output cannot go there; choose "
                              "another -o")
    if not os.access(target, os.W_OK | os.X_OK):
        raise OutputError(f"{path}: cannot write in {target} (no permission, or a read-only file "
                          "system); choose another -o")


def remove_temporaries(path: str | os.PathLike) -> None:
    """Remove the temporary files that a killed write of ``path`` left beside it
    (:class:`AtomicFile`'s ``.NAME.XXXXXXXX.tmp``); nothing else is touched."""
    path = Path(path)
    pattern = re.compile(rf"^\.{re.escape(path.name)}\.[A-Za-z0-9_]{{8}}\.tmp$")
    try:
        entries = list(path.parent.iterdir())
    except OSError:
        return
    for entry in entries:
        if pattern.match(entry.name) and entry.is_file() and not entry.is_symlink():
            entry.unlink(missing_ok=True)
