"""Seals on the records an output folder's control folder keeps: pinchmatch acts only on its own.

A run keeps three records in ``OUT/.pinchmatch`` (:mod:`pinchmatch.export.folder`): the manifest of
the result's files, the journal of a publication under way and the record of what a run must take
back if it is killed. Each of them makes the next run move or delete files, so a record that came
with a folder from elsewhere (a shared drive, an archive, a colleague's killed run, a hand-made
file) must never be acted on: its names could be any file of the user's.

So every record is **sealed**: written with an HMAC-SHA256 of its canonical JSON under a key that
only this user's runs know, and read back only when the seal verifies. The key is 32 random bytes in
``$PINCHMATCH_STATE_DIR/seal.key``, else ``$XDG_STATE_HOME/pinchmatch/seal.key``, else
``~/.local/state/pinchmatch/seal.key`` (made on first use, readable by the user alone). Where no
such file can be made (no writable home), the key is drawn once per process; the command line draws
it before it forks, so the process that takes back a killed run knows it, but a later run does not:
it then treats that run's records as received ones.

A record's seal binds its contents and its kind (``manifest``, ``journal``, ``run``), so a journal's
text is not read as a run record; it does not bind the folder, so a result folder moved or copied by
its own user stays its own.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import secrets
from pathlib import Path

#: the field of a record that holds its seal
SEAL = "seal"
#: the key's length, bytes
KEY_BYTES = 32

_KEY: list[bytes] = []


def key_path() -> Path:
    """Where this user's key is kept (module notes)."""
    if os.environ.get("PINCHMATCH_STATE_DIR"):
        return Path(os.environ["PINCHMATCH_STATE_DIR"]) / "seal.key"
    state = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local",
                                                             "state")
    return Path(state) / "pinchmatch" / "seal.key"


def key() -> bytes:
    """This user's key: read from :func:`key_path`, made there on first use, else drawn for this
    process."""
    if _KEY:
        return _KEY[0]
    path = key_path()
    value = _read_key(path)
    if value is None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
            try:
                os.write(fd, secrets.token_bytes(KEY_BYTES))
            finally:
                os.close(fd)
        except OSError:
            pass  # made by another run at the same moment, or no place to keep it
        value = _read_key(path)
    _KEY.append(value if value is not None else secrets.token_bytes(KEY_BYTES))
    return _KEY[0]


def _read_key(path: Path) -> bytes | None:
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError:
        return None
    try:
        value = os.read(fd, KEY_BYTES + 1)
    except OSError:
        return None
    finally:
        os.close(fd)
    return value if len(value) == KEY_BYTES else None


def _digest(kind: str, record: dict) -> str:
    text = json.dumps({"kind": kind, "record": record}, sort_keys=True, separators=(",", ":"),
                      allow_nan=False)
    return hmac.new(key(), text.encode("utf-8"), hashlib.sha256).hexdigest()


def sealed(kind: str, record: dict, *, indent: int | None = None) -> str:
    """``record`` (a dict of JSON values, without a ``seal`` field) as JSON text with its seal."""
    return json.dumps({**record, SEAL: _digest(kind, record)}, indent=indent)


def unsealed(kind: str, text: str | bytes) -> dict | None:
    """The record of ``text`` when it is a JSON object whose seal, of ``kind``, verifies; else
    None."""
    try:
        record = json.loads(text)
    except (ValueError, UnicodeDecodeError, RecursionError):
        return None
    if not isinstance(record, dict) or not isinstance(record.get(SEAL), str):
        return None
    seal = record.pop(SEAL)
    try:
        expected = _digest(kind, record)
    except (ValueError, TypeError):
        return None
    return record if hmac.compare_digest(seal, expected) else None
