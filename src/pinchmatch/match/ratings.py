"""The tables calibration reads: a ratings table (CSV) and a weights file (JSON).

A ratings table holds one row per rated pair: its ``rating`` and each criterion's difference in JND
(``<criterion>_jnd``), optionally the ``pair``, or the ``object`` and ``pose_source`` that group the
rows shown together (:func:`placement_groups`). A weights file is what ``pinchmatch calibrate``
writes (``{"weights": {...}, "pooling": ..., "criteria": ...}``) and ``--weights-file`` reads.
:mod:`pinchmatch.match.calibrate` fits the weights.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..config import finite_number
from ..errors import ConfigError
from .cost import CRITERIA, CostModel
#: the bounds of a table's numbers: a rating scale's points, and differences in JND
MAX_RATING, MAX_JND = 1e6, 1e4


def exponent_of(pooling: str) -> float:
    """β of a pooling, as the cost uses it (:attr:`pinchmatch.match.cost.CostModel.exponent`)."""
    return CostModel(pooling=pooling).exponent


@dataclass(frozen=True)
class Ratings:
    """A ratings table: per row the rating, the difference per criterion (JND), the group of rows
    that rate one placement, and the virtual object rated (-1 where the table names none)."""

    criteria: tuple
    jnd: np.ndarray  # (n, len(criteria))
    rating: np.ndarray  # (n,)
    pair: np.ndarray  # (n,) int: rows of one placement share a number
    source: str
    obj: np.ndarray | None = None  # (n,) int, the ``object`` column numbered; None without it



def read_ratings(text: str, source: str, *, criteria: tuple | None = None) -> Ratings:
    """Parse a ratings CSV: a ``rating`` column and one ``<criterion>_jnd`` column per criterion
    (only ``criteria`` if given); optional ``pair`` or ``object`` + ``pose_source`` group the rows.

    Parameters
    ----------
    text : str
        The CSV's text.
    source : str
        What messages call it (its file).
    criteria : tuple of str, optional
        Read only these criteria's columns.

    Returns
    -------
    Ratings
        The ratings, each row's differences in JND and the rows' groups.

    Examples
    --------
    >>> table = "pair,width_jnd,kmax_jnd,rating\\n1,0.2,0.1,6\\n2,1.5,0.3,3\\n"
    >>> r = read_ratings(table, "ratings.csv")
    >>> r.criteria, r.rating.tolist(), r.jnd.tolist()
    (('width', 'kmax'), [6.0, 3.0], [[0.2, 0.1], [1.5, 0.3]])
    """
    # CR-only line endings: old spreadsheet exports
    text = text.replace("\r\n", "\n").replace("\r", "\n")
    delimiter, decimal_comma = _dialect(text)
    try:
        reader = csv.reader(io.StringIO(text), strict=True, delimiter=delimiter)
        table, lines = [], []
        for row in reader:
            if row:  # blank lines
                table.append(row)
                lines.append(reader.line_num)
    except csv.Error as exc:
        raise ConfigError(f"{source}: not a CSV table ({exc}); check its quotes") from None
    if len(table) < 2:
        raise ConfigError(f"{source}: no rated rows; give a CSV with a header and one row per "
                          "rated trial")
    names = [n.strip() for n in table[0]]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ConfigError(f"{source}: the column {', '.join(map(repr, twice))} appears twice; give "
                          "each column once")
    unknown = [n for n in names if n.endswith("_jnd") and n[:-4] not in CRITERIA]
    if unknown:
        raise ConfigError(f"{source}: unknown column {', '.join(map(repr, unknown))}; the criteria "
                          f"are {', '.join(CRITERIA)}")
    for line, row in zip(lines[1:], table[1:]):
        if len(row) != len(names):
            raise ConfigError(f"{source}: line {line} has {len(row)} cells and the header "
                              f"{len(names)}; fix that row")
    rows = [dict(zip(names, row)) for row in table[1:]]
    header = set(names)
    if "rating" not in header:
        raise ConfigError(f"{source}: no 'rating' column (the header reads "
                          f"{', '.join(map(repr, names[:6]))}); the "
                          "table needs rating and <criterion>_jnd columns, separated by commas, "
                          "semicolons or tabs (docs/study.md)")
    present = tuple(c for c in CRITERIA if f"{c}_jnd" in header)
    if criteria is not None:
        missing = [c for c in criteria if c not in present]
        if missing:
            raise ConfigError(f"{source}: no column {', '.join(f'{c}_jnd' for c in missing)}; "
                              "fit only the criteria the table has")
        present = tuple(c for c in CRITERIA if c in criteria)
    if not present:
        raise ConfigError(f"{source}: no <criterion>_jnd column (one of "
                          f"{', '.join(c + '_jnd' for c in CRITERIA)})")
    rated_lines = [line for line, r in zip(lines[1:], rows) if (r.get("rating") or "").strip()]
    # an unrated trial (skipped) is left out
    rated = [r for r in rows if (r.get("rating") or "").strip()]
    values = np.empty((len(rated), len(present) + 1))
    for i, r in enumerate(rated):
        for k, name in enumerate(("rating",) + tuple(f"{c}_jnd" for c in present)):
            cell = r[name].strip().replace(",", ".") if decimal_comma else r[name]
            try:
                values[i, k] = float(cell)
            except (TypeError, ValueError):
                raise ConfigError(f"{source}: line {rated_lines[i]}: {name} = {r[name]!r} is not a "
                                  "number") from None
    if not np.isfinite(values).all() or (values[:, 1:] < 0).any():
        raise ConfigError(f"{source}: a rating or a difference is not finite, or a difference is "
                          "negative; the <criterion>_jnd columns are sizes in JND (0 or more)")
    if (np.abs(values[:, 0]) > MAX_RATING).any() or (values[:, 1:] > MAX_JND).any():
        raise ConfigError(f"{source}: a rating beyond ±{MAX_RATING:g} or a difference over "
                          f"{MAX_JND:g} JND; "
                          "ratings are points of a scale and differences sizes in JND")
    if "pair" in header:
        keys = [r["pair"] for r in rated]
    elif {"object", "pose_source"} <= header:
        keys = [(r["object"], r["pose_source"]) for r in rated]
    else:
        keys = list(range(len(rated)))
    objects = None
    if "object" in header:
        names: dict = {}
        objects = np.array([names.setdefault(r["object"], len(names)) for r in rated],
                           dtype=np.int64)
    return Ratings(present, values[:, 1:], values[:, 0], placement_groups(keys, values[:, 1:]),
                   source, objects)


def _dialect(text: str) -> tuple[str, bool]:
    """The header's delimiter, as spreadsheets write CSV: commas, semicolons (where the decimal mark
    is a comma: the numbers are then read with either mark) or tabs; and whether decimal commas are
    read."""
    header = text.split("\n", 1)[0]
    counts = {d: header.count(d) for d in (",", ";", "\t")}
    delimiter = max(counts, key=lambda d: (counts[d], d == ","))
    if counts[delimiter] == 0:
        delimiter = ","
    return delimiter, delimiter != ","


def placement_groups(keys: list, jnd: np.ndarray) -> np.ndarray:
    """(n,) group of each row: rows of one key, and rows whose differences are identical (to 1e-6
    JND), are one group (connected components: two keys sharing a placement are one group)."""
    n = len(keys)
    if not n:
        return np.zeros(0, dtype=np.int64)
    index: dict = {}
    by_key = np.array([index.setdefault(k, len(index)) for k in keys], dtype=np.int64)
    _, by_values = np.unique(np.round(jnd, 6), axis=0, return_inverse=True)
    by_values = by_values.reshape(-1)
    # nodes: the rows, then the keys, then the distinct difference vectors; a row joins its key and
    # vector
    key_node, value_node = n + by_key, n + len(index) + by_values
    size = n + len(index) + int(by_values.max()) + 1
    rows = np.arange(n)
    graph = coo_matrix((np.ones(2 * n),
                        (np.concatenate([rows, rows]), np.concatenate([key_node, value_node]))),
                       shape=(size, size))
    _, label = connected_components(graph, directed=False)
    first: dict = {}
    return np.array([first.setdefault(g, len(first)) for g in label[:n].tolist()], dtype=np.int64)


def read_weights_file(text: str, source: str) -> tuple[dict, str | None, str | None]:
    """The weights of a ``weights.json`` that ``calibrate`` wrote (or any ``{"weights": {...}}``),
    the pooling they were fitted for and the criteria set they are for (``default`` or ``paper``;
    None where the file does not say).

    Parameters
    ----------
    text : str
        The JSON's text.
    source : str
        What messages call it (its file).

    Returns
    -------
    (dict, str or None, str or None)
        The weights, the pooling they were fitted for and their criteria set.

    Examples
    --------
    >>> text = '{"weights": {"width": 2, "kmax": 0.5}, "pooling": "quick"}'
    >>> read_weights_file(text, "weights.json")
    ({'width': 2.0, 'kmax': 0.5}, 'quick', None)
    """
    import json

    def unique(pairs):
        keys = [k for k, _ in pairs]
        twice = sorted({k for k in keys if keys.count(k) > 1})
        if twice:
            raise ConfigError(f"{source}: {', '.join(map(repr, twice))} given twice; give each key "
                              "once")
        return dict(pairs)

    try:
        doc = json.loads(text, object_pairs_hook=unique)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{source}: not JSON ({exc.msg}, line {exc.lineno}); give the "
                          "weights.json that 'pinchmatch calibrate' writes") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{source}: not UTF-8 text (byte {exc.start}); save it as UTF-8 JSON, as "
                          "'pinchmatch calibrate' writes it") from None
    except ValueError as exc:  # an integer of thousands of digits
        raise ConfigError(f"{source}: a value no weight can be ({str(exc)[:60]}); give the "
                          "weights.json that 'pinchmatch calibrate' writes") from None
    except RecursionError:
        raise ConfigError(f"{source}: nested too deep to be a weights file; give the weights.json "
                          "that 'pinchmatch calibrate' writes") from None
    weights = doc.get("weights") if isinstance(doc, dict) else None
    if not isinstance(weights, dict) or not all(finite_number(v) for v in weights.values()):
        raise ConfigError(f"{source}: needs a 'weights' object of criterion: number; give the "
                          "weights.json that 'pinchmatch calibrate' writes")
    pooling = doc.get("pooling")
    if pooling is not None and pooling not in ("quick", "sum"):
        raise ConfigError(f"{source}: pooling {pooling!r} is neither quick nor sum; give the "
                          "weights.json that 'pinchmatch calibrate' writes")
    criteria = doc.get("criteria")
    if criteria is not None and criteria not in ("default", "paper"):
        raise ConfigError(f"{source}: criteria {criteria!r} is neither default nor paper; give the "
                          "weights.json that 'pinchmatch calibrate' writes")
    return {str(k): float(v) for k, v in weights.items()}, pooling, criteria
