"""An output folder that always holds one whole result: the previous run's or the new one's.

A run that writes a folder OUT (``match``, ``demo``) writes into ``OUT/.pinchmatch/staging`` and
publishes at the end, in a step that a signal cannot interrupt:

1. a journal ``OUT/.pinchmatch/commit.json`` lists the new files and the old ones no longer needed;
2. each new file is moved into place (``os.replace``, atomic per file), the old files that the
   previous result had and this one has not are deleted, and the manifest
   ``OUT/.pinchmatch/manifest.json`` is rewritten to list exactly the new result's files;
3. the journal is removed.

If the process dies during step 2 (SIGKILL, a power cut), the next run, or ``pinchmatch view``,
finishes the journal first, so OUT is again one whole result. A run that stops before step 1
(Ctrl-C, SIGTERM, an error, a full disk) leaves OUT as it was: what it staged is removed, and the
files it wrote straight into OUT are taken back. A run's process killed outright (the command line
kills it on Ctrl-C and SIGTERM: :mod:`pinchmatch.cli.supervise`) cannot clean up itself, so what it
must take back is kept in ``OUT/.pinchmatch/run.json`` as it goes, and :func:`undo_killed_run` (the
command line's parent, or the next run) does it.

Only files the manifest lists are ever deleted: a file a user put in OUT is never deleted (it is
replaced only when it sits at the very path of an output). A lock
(``flock`` on ``OUT/.pinchmatch/lock``) refuses a second run into the same OUT while one is going.

A result folder may come from someone else (a shared drive, an archive), so nothing under
``OUT/.pinchmatch`` is trusted:

- a link there (the control folder itself, its staging folder, its lock, journal, manifest or run
  record) is refused before anything is read or written through it (:func:`check_control`);
- the manifest, the journal and the run record are sealed (:mod:`pinchmatch.export.seal`): a
  manifest whose seal does not verify lists nothing to delete (its files are kept as the user's
  own), and a journal or run record whose seal does not verify is refused in one line, never carried
  out;
- even a sealed journal deletes only files its manifest lists, and moves only regular files that lie
  in the real staging folder; a sealed run record is carried out only on names whose folder lies
  inside OUT, links followed;
- the folder a failed run made goes only when nothing but what that run wrote is in it.
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import stat
from contextlib import contextmanager
from pathlib import Path

from ..errors import OutputError
from ..files import RESULT_CONTROL, remove_temporaries, write_atomic
from .seal import sealed, unsealed

CONTROL = RESULT_CONTROL
#: what the control folder holds; none of it may be a link
CONTROL_ENTRIES = ("staging", "replaced", "lock", "commit.json", "manifest.json", "run.json")


class FolderBusy(OutputError):
    """Another run holds the folder's lock."""


def check_control(out: str | os.PathLike) -> bool:
    """Refuse, in one line, a control folder ``OUT/.pinchmatch`` that is a link or holds one among
    its entries (``CONTROL_ENTRIES``), or that is not a folder: pinchmatch never reads, writes or
    moves through one. Returns whether the control folder exists."""
    control = Path(out) / CONTROL
    if not os.path.lexists(control):
        return False
    bad = [control] if control.is_symlink() or not control.is_dir() else \
        [control / e for e in CONTROL_ENTRIES if (control / e).is_symlink()]
    if (control / "staging").exists() and not (control / "staging").is_dir():
        bad.append(control / "staging")
    if bad:
        raise OutputError(f"{bad[0]}: a symbolic link or not a folder where pinchmatch keeps its "
                          "own control files; "
                          "pinchmatch never follows one there (a result folder received from "
                          f"elsewhere?); remove {control} and run again")
    return True


def _open_lock(control: Path) -> int:
    """The lock file's descriptor, never through a link."""
    return os.open(control / "lock", os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)


class OutputFolder:
    """``with OutputFolder(out) as stage:`` write the result under ``stage``; it is published into
    ``out`` when the block ends without an exception, and discarded otherwise.

    ``direct(path)`` records a file written straight into ``out`` (inputs a run generates, the
    same bytes every time) as part of the result.
    """

    def __init__(self, out: str | os.PathLike):
        self.out = Path(out)
        self.control = self.out / CONTROL
        self.stage = self.control / "staging"
        self._lock = None
        self._direct: list[str] = []
        # direct writes: (name, the file it replaced)
        self._undo: list[tuple[str, Path | None]] = []
        self._created = False

    def __enter__(self) -> Path:
        if self.out.is_symlink() and not self.out.exists():
            raise OutputError(f"{self.out}: a symbolic link to {os.readlink(self.out)}, which does "
                              "not exist; make that folder first, or choose another -o")
        self._created = not self.out.exists()
        check_control(self.out)
        try:
            self.control.mkdir(parents=True, exist_ok=True)
            fd = _open_lock(self.control)
        except OSError as exc:
            raise OutputError(f"{self.out}: cannot write there ({exc.strerror or exc}); choose "
                              "another -o") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise OutputError(f"{self.out}: another pinchmatch run is writing this folder; wait "
                              "for it to end, or choose another -o") from None
        self._lock = fd
        try:
            _refuse_links_out(self.out, read_manifest(self.out))
        except BaseException:
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)
            self._lock = None
            raise
        # what a killed run left: its journal finished, or its writes taken back
        _undo_locked(self.out, last=False)
        self.stage.mkdir()
        self._save_run()
        return self.stage

    def _save_run(self) -> None:
        """Keep what a killed run must take back (``run.json``): the direct writes, and whether OUT
        is new."""
        write_atomic(self.control / RUN, sealed("run", self._run()))

    def _run(self) -> dict:
        return {"created": self._created, "undo": [
            [name, None if kept is None else kept.relative_to(self.control).as_posix()]
            for name, kept in self._undo]}

    def direct(self, path: str | os.PathLike, *, new: bool = False) -> None:
        """Record a file written straight into ``out``; ``new``: it was not there before the run, so
        it goes when the run does not finish."""
        name = Path(path).relative_to(self.out).as_posix()
        self._direct.append(name)
        if new:
            self._undo.append((name, None))
            self._save_run()

    def write_direct(self, path: str | os.PathLike, data: bytes) -> None:
        """Write a file straight into ``out`` (an input the run's later steps read where it stays).
        A run that does not finish leaves ``out`` as it was: a new file goes, a file it replaced
        comes back."""
        name = Path(path).relative_to(self.out).as_posix()
        if not _really_inside(self.out, name):
            raise OutputError(f"{path}: outside the output folder {self.out}; choose another -o")
        target = self.out / name
        kept = None
        if target.exists():
            kept = self.control / "replaced" / name
            kept.parent.mkdir(parents=True, exist_ok=True)
            self._undo.append((name, kept))
            self._save_run()  # before the move: a killed run puts the file back
            os.replace(target, kept)
        else:
            self._undo.append((name, None))
            self._save_run()
        target.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(target, data)
        self._direct.append(name)

    def __exit__(self, exc_type, exc, tb):
        failed = exc_type is not None
        try:
            if not failed:
                self._publish()
        finally:
            if (self.control / "commit.json").exists():
                # a publication cut short: its journal still needs what is staged (the next reader
                # finishes it)
                pass
            elif failed:
                _take_back(self.out, self._run(), last=True)
            else:
                _clean(self.out)
            fcntl.flock(self._lock, fcntl.LOCK_UN)
            os.close(self._lock)
            self._lock = None

    def _publish(self) -> None:
        new = sorted({p.relative_to(self.stage).as_posix() for p in self.stage.rglob("*")
                      if p.is_file()}
                     | set(self._direct))
        old = read_manifest(self.out)
        _refuse_links_out(self.out, new + old)  # a link made while the run worked
        journal = {"new": new, "staged": [n for n in new if (self.stage / n).is_file()],
                   "remove": sorted(set(old) - set(new))}
        write_atomic(self.control / "commit.json", sealed("journal", journal))
        finish_commit(self.out)


#: what a run must take back if it is killed: ``OUT/.pinchmatch/run.json``
RUN = "run.json"


def _take_back(out: Path, run: dict, *, last: bool) -> None:
    """Undo a run that did not publish (``run``: its sealed record, or the run's own): its direct
    writes put back (a file it replaced comes back, one it added goes) and what it staged removed;
    with ``last`` (no run follows into OUT), OUT itself when the run made it and nothing else is in
    it."""
    control = out / CONTROL
    if (control / "commit.json").exists():  # it was publishing: finished, never taken back
        finish_commit(out)
        _clean(out)
        return
    undo = run.get("undo")
    for entry in reversed(undo if isinstance(undo, list) else []):
        if not (isinstance(entry, list) and len(entry) == 2):
            continue  # not a record this code wrote (a folder received from elsewhere)
        name, kept = entry
        if not (isinstance(name, str) and _really_inside(out, name)):
            continue
        target = out / name
        if kept is None:  # a file the run added, or was writing
            target.unlink(missing_ok=True)
            remove_temporaries(target)
            _prune_empty(out, target.parent)
        elif isinstance(kept, str) and _inside(kept) and _regular_in(control, kept):
            # a file it replaced comes back (not moved yet: still there)
            os.replace(control / kept, target)
    _clean(out)
    if last and run.get("created") is True:
        _remove_if_only_control(out)


def _remove_if_only_control(out: Path) -> None:
    """Remove the folder ``out`` a run made, when all it holds is the control folder's own files: a
    file the user put there while the run went keeps it."""
    control = out / CONTROL
    if any(p.name != CONTROL
           for p in out.iterdir()) or not control.is_dir() or control.is_symlink():
        return
    if any(p.name not in CONTROL_ENTRIES or not (p.is_file() and not p.is_symlink())
           for p in control.iterdir()):
        return
    for p in control.iterdir():
        p.unlink()
    control.rmdir()
    out.rmdir()


def _clean(out: Path) -> None:
    control = out / CONTROL
    shutil.rmtree(control / "staging", ignore_errors=True)
    shutil.rmtree(control / "replaced", ignore_errors=True)
    (control / RUN).unlink(missing_ok=True)


def _undo_locked(out: Path, *, last: bool) -> bool:
    """With the folder's lock held: finish a killed run's publication, or take its writes back (its
    sealed run record; one not sealed by this user's runs is refused in one line). ``last``: no run
    follows into OUT. Returns whether a publication was finished."""
    control = Path(out) / CONTROL
    if (control / "commit.json").exists():
        finish_commit(out)
        _clean(Path(out))
        return True
    try:
        text = (control / RUN).read_bytes()
    except FileNotFoundError:
        run = {}
    except OSError as exc:
        raise OutputError(f"{control / RUN}: unreadable ({exc.strerror or exc}); delete it and run "
                          "again") from None
    else:
        run = unsealed("run", text)
        if run is None:
            raise OutputError(_not_ours(control / RUN, "run record"))
    _take_back(Path(out), run, last=last)
    return False


def _not_ours(path: Path, what: str) -> str:
    return (f"{path}: a {what} that no run of this user's wrote (a result folder received from "
            f"elsewhere?); pinchmatch never carries one out; delete {path} and run again")


def undo_killed_run(out: str | os.PathLike) -> bool:
    """After a run's process was killed: finish its publication if it had begun one (True), else
    take back what it wrote into OUT (False). Nothing when OUT holds no control folder; refused
    while another run holds the folder."""
    control = Path(out) / CONTROL
    if not control.is_dir() or control.is_symlink():
        return False
    check_control(out)
    fd = _open_lock(control)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # the killed run's lock went with its process
        return _undo_locked(Path(out), last=True)
    finally:
        os.close(fd)


def recover(out: str | os.PathLike) -> None:
    """For readers: finish a publication that a killed run left half done and remove what a killed
    run staged, under the folder's lock. While a run is writing the folder, a half-done publication
    is refused and anything else left alone."""
    try:
        with exclusive(out):
            pass
    except FolderBusy:
        if (Path(out) / CONTROL / "commit.json").exists():
            raise


@contextmanager
def exclusive(out: str | os.PathLike):
    """Hold the folder's lock while the block writes into it (``pinchmatch view`` rewriting the
    page), after finishing what a killed run left; a folder that a run is writing is refused in one
    line."""
    control = Path(out) / CONTROL
    if not check_control(out):
        yield
        return
    fd = _open_lock(control)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise FolderBusy(f"{out}: a pinchmatch run is writing this folder; wait for it to "
                             "end") from None
        _undo_locked(Path(out), last=False)
        yield
    finally:
        os.close(fd)


def read_manifest(out: Path) -> list[str]:
    """The files of the result in ``out``, as its sealed manifest lists them ([] when there is none,
    or its seal does not verify: a received folder's files are the user's own)."""
    try:
        manifest = unsealed("manifest", (Path(out) / CONTROL / "manifest.json").read_bytes())
    except OSError:
        return []
    files = manifest.get("files") if manifest is not None else None
    return [f for f in files if isinstance(f, str) and _inside(f)] if isinstance(files,
                                                                                 list) else []


def finish_commit(out: str | os.PathLike) -> None:
    """Carry out a journal left by a publication that did not finish (nothing when there is
    none)."""
    out = Path(out)
    control = out / CONTROL
    if not os.path.lexists(control / "commit.json"):
        return
    check_control(out)
    try:
        journal = unsealed("journal", (control / "commit.json").read_bytes())
    except FileNotFoundError:
        return
    except OSError as exc:
        raise OutputError(f"{control / 'commit.json'}: unreadable ({exc.strerror or exc}); delete "
                          f"{control} and run again") from None
    if journal is None:
        raise OutputError(_not_ours(control / "commit.json", "journal"))
    if not (isinstance(journal, dict)
            and all(isinstance(journal.get(k), list) for k in ("new", "staged", "remove"))
            and all(isinstance(n, str) for k in ("new", "staged", "remove") for n in journal[k])):
        raise OutputError(f"{control / 'commit.json'}: not a journal pinchmatch wrote; delete "
                          f"{control} and run again")
    listed = set(read_manifest(out))
    try:
        for name in journal["staged"]:
            source, target = control / "staging" / name, out / name
            if _really_inside(out, name) and _staged_file(control, name):
                target.parent.mkdir(parents=True, exist_ok=True)
                os.replace(source, target)
        for name in journal["remove"]:
            if name in listed and _really_inside(out, name):
                (out / name).unlink(missing_ok=True)
                _prune_empty(out, (out / name).parent)
        write_atomic(control / "manifest.json",
                     sealed("manifest", {"files": journal["new"]}, indent=1))
        (control / "commit.json").unlink()
    except OSError as exc:
        raise OutputError(f"{out}: cannot finish writing the result ({exc.strerror or exc}); free "
                          "some space and run again") from None


def _regular_in(folder: Path, name: str) -> bool:
    """Whether ``folder / name`` is a regular file (not a link), no link on the way from
    ``folder``."""
    try:
        mode = os.lstat(folder / name).st_mode
    except OSError:
        return False
    inside = os.path.join(os.path.realpath(folder), *Path(name).parts)
    return stat.S_ISREG(mode) and os.path.realpath(folder / name) == inside


def _staged_file(control: Path, name: str) -> bool:
    """Whether ``name`` is a regular file (not a link) in the real staging folder, no link on the
    way."""
    stage = control / "staging"
    return _inside(name) and not stage.is_symlink() and stage.is_dir() and _regular_in(stage, name)


def _inside(name: str) -> bool:
    parts = Path(name).parts
    return (bool(parts) and not Path(name).is_absolute() and ".." not in parts
            and parts[0] != CONTROL)


def _really_inside(out: Path, name: str) -> bool:
    """``name`` is a path inside ``out`` and the folder that holds it is too, links followed:
    writing or deleting it touches nothing outside ``out``."""
    if not _inside(name):
        return False
    base = os.path.realpath(out)
    parent = os.path.realpath(Path(out) / Path(name).parent)
    return parent == base or parent.startswith(base + os.sep)


def _refuse_links_out(out: Path, names: list[str]) -> None:
    """Refuse a folder of ``out`` that is a link out of it: one of its entries, or a folder on the
    way to a result file (``names``)."""
    out = Path(out)
    folders = {out / p.name for p in out.iterdir() if p.is_symlink()
               and p.is_dir()} if out.is_dir() else set()
    folders |= {(out / n).parent for n in names if _inside(n)}
    base = os.path.realpath(out)
    for folder in sorted(folders):
        real = os.path.realpath(folder)
        if not (real == base or real.startswith(base + os.sep)):
            raise OutputError(f"{folder}: a symbolic link out of the output folder (to {real}); "
                              "pinchmatch never "
                              "writes or deletes through one; remove the link, or choose another "
                              "-o")


def _prune_empty(out: Path, folder: Path) -> None:
    """Remove folders that the deletions left empty, up to (not including) ``out``."""
    while folder != out and folder.is_dir() and not any(folder.iterdir()):
        folder.rmdir()
        folder = folder.parent
