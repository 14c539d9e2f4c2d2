"""Settings records whose fields describe themselves: how the command line offers each one, and a
digest.

A settings record (:class:`pinchmatch.config.PinchSettings`,
:class:`pinchmatch.config.MatchSettings`, and :class:`pinchmatch.config.Config` holding both)
is a frozen dataclass. Each field made with :func:`option` carries an :class:`Option`: its help, the
group of commands that offer it, how its value is written on the command line. The command line's
options, their defaults and their help are generated from those fields
(:func:`pinchmatch.cli.parser.add_record_options`), so the library and the command line cannot
drift.

:func:`digest` hashes a record's fields, and :func:`code_digest` the package's source: every cache
key is made of these two and of the inputs' bytes, with no hand-kept list of what a key depends on.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path



#: how a field's value is written on the command line
KINDS = ("float", "int", "flag", "choice", "onoff", "vector", "weights")


@dataclass(frozen=True)
class Option:
    """How the command line offers one field of a settings record.

    - ``help``: what it does, its bounds and units (the default is added from the field);
    - ``group``: the commands that offer it (:data:`pinchmatch.cli.parser.GROUPS`);
    - ``kind``: ``float``, ``int``, ``flag`` (present or not), ``choice`` (one of ``choices``: a
      sequence of words, or a mapping from each word to the field's value), ``onoff`` (a bool
      written ``on``/``off``), ``vector`` (``X,Y,Z``, default None), ``weights`` (``NAME=W,...``);
    - ``flag``: the option's name, default ``--`` and the field's name with ``-`` for ``_``;
    - ``metavar``: how its value is shown in the help.
    """

    help: str
    group: str
    kind: str
    choices: tuple | Mapping | None = None
    flag: str | None = None
    metavar: str | None = None

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"unknown option kind {self.kind!r}")

    def words(self) -> tuple:
        """The words the command line accepts for a ``choice`` or ``onoff`` field."""
        if self.kind == "onoff":
            return ("on", "off")
        return tuple(self.choices)

    def value(self, word):
        """The field's value for what the command line gave."""
        if self.kind == "onoff":
            return word == "on"
        if self.kind == "choice" and isinstance(self.choices, Mapping):
            return self.choices[word]
        return word

    def word(self, value) -> str:
        """How the command line writes the field's ``value`` (its default, in the help)."""
        if self.kind == "onoff":
            return "on" if value else "off"
        if self.kind == "choice" and isinstance(self.choices, Mapping):
            return next(w for w, v in self.choices.items() if v == value)
        if self.kind == "float":
            return f"{value:g}"
        return str(value)


def option(default=dataclasses.MISSING, *, help: str, group: str, kind: str, choices=None,
           flag: str | None = None, metavar: str | None = None,
           default_factory=dataclasses.MISSING):
    """A dataclass field the command line offers (see :class:`Option`)."""
    meta = {"option": Option(help, group, kind, choices, flag, metavar)}
    if default_factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def offered(record_type) -> list[tuple[dataclasses.Field, Option]]:
    """The fields of a settings record type that the command line offers, in order."""
    return [(f, f.metadata["option"]) for f in dataclasses.fields(record_type)
            if "option" in f.metadata]


def flag_of(field: dataclasses.Field, opt: Option) -> str:
    return opt.flag or "--" + field.name.replace("_", "-")


def field_default(field: dataclasses.Field):
    return field.default_factory() if field.default is dataclasses.MISSING else field.default


def plain(value):
    """A settings value as JSON holds it (dataclasses as dicts, arrays by their digest)."""
    if dataclasses.is_dataclass(value):
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if type(value).__module__ == "numpy":  # an array by its bytes, a numpy scalar as a number
        if value.ndim == 0:
            return value.item()
        data = value.tobytes(order="C")
        return {"dtype": str(value.dtype), "shape": list(value.shape),
                "sha256": hashlib.sha256(data).hexdigest()}
    return value


def digest(value) -> str:
    """SHA-256 of a record (or any value :func:`plain` takes), field by field; numbers by their
    value (5 and 5.0 alike, as the records compare them), a bool as a bool."""
    return hashlib.sha256(json.dumps(_canonical(plain(value)), sort_keys=True,
                                     default=repr).encode()).hexdigest()


def _canonical(value):
    """JSON values with every number as a float: equal records (5 == 5.0) give equal text."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, dict):
        return {k: _canonical(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_canonical(v) for v in value]
    return value


@lru_cache(maxsize=1)
def code_digest() -> str:
    """SHA-256 of every Python module and page file of the package, by name and bytes: any edit or
    upgrade changes it, so no cache entry outlives the code that wrote it."""
    return package_digest(Path(__file__).resolve().parent)


def package_digest(root) -> str:
    """SHA-256 of the ``.py``, ``.js``, ``.html`` and ``.css`` files under ``root``, by relative
    path and bytes."""
    h = hashlib.sha256()
    stack, files = [root], []
    while stack:
        folder = stack.pop()
        for item in folder.iterdir():
            if item.is_dir():
                if item.name != "__pycache__":
                    stack.append(item)
            elif item.name.endswith((".py", ".js", ".html", ".css")):
                files.append((item.relative_to(root).as_posix(), item))
    for name, item in sorted(files, key=lambda pair: pair[0]):
        h.update(name.encode())
        h.update(item.read_bytes())
    return h.hexdigest()
