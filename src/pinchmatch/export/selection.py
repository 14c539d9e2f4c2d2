"""The selection document (``OUT/selection.json``) of ``pinchmatch select``, and its printed tables.

Objects and props are named as in ``matches.json`` (a manifest's ``name``, a level node's, else the
file's); costs are dimensionless, in just-noticeable differences (1: just noticeable).
"""

from __future__ import annotations

import numpy as np

from ..version import __version__
from .documents import cost_matrix_section, json_number

SCHEMA_SELECTION = "pinchmatch.selection/1"


def _value(objective: str, value: float):
    return int(value) if objective == "noticeable" and np.isfinite(value) else json_number(value, 6)


def _summary(selection, names: list[str], objective: str) -> dict:
    served = selection.assigned >= 0
    return {"k": int(len(selection.props)), "props": [names[t] for t in selection.props],
            "value": _value(objective, selection.value),
            "mean_cost": json_number(selection.mean_cost, 6),
            "noticeable_count": int(selection.noticeable[served].sum()),
            "worst_cost": json_number(float(selection.cost[served].max()) if served.any()
                                      else float("inf"), 6), "exact": bool(selection.exact),
                                      "method": selection.method}


def selection_document(settings: dict, shelf: list[dict], scene: list[str], cost: np.ndarray,
                       noticeable: np.ndarray, selection, curve: list, addition,
                       helpful: np.ndarray, exact_limit: int) -> dict:
    """The selection document.

    shelf: per prop, ``{"name", "path"}``; scene: the virtual objects' names; cost, noticeable:
    the served matrix (objects x props); selection: the chosen
    :class:`~pinchmatch.match.select.Selection`; curve: the best selection for K = 1, 2, …;
    addition: :func:`~pinchmatch.match.select.best_addition`'s answer; helpful:
    :func:`~pinchmatch.match.select.helpful_props`'s.
    """
    names = [p["name"] for p in shelf]
    objective = settings["objective"]
    objects = []
    for j, name in enumerate(scene):
        t = int(selection.assigned[j])
        h = int(helpful[j])
        objects.append({
            "virtual": name, "tangible": names[t] if t >= 0 else None,
            "cost": json_number(float(selection.cost[j]), 6) if t >= 0 else None,
            "noticeable": bool(selection.noticeable[j]) if t >= 0 else None,
            "servable": bool(np.isfinite(cost[j]).any()),
            "best_addition": names[h] if h >= 0 else None,
            "cost_with_addition": json_number(float(cost[j, h]), 6) if h >= 0 else None,
        })
    badly = [o["virtual"] for o in objects if o["noticeable"] or o["tangible"] is None]
    return {
        "schema": SCHEMA_SELECTION, "version": __version__, "settings": settings,
        "shelf": shelf,
        "selection": _summary(selection, names, objective) | {"objective": objective,
                                                               "exact_limit_subsets": exact_limit},
        "objects": objects,
        "badly_served": badly,
        "suggestion": None if addition is None else {
            "add": names[addition[0]],
            **{k: v for k, v in _summary(addition[1], names, objective).items()
                                          if k in ("value", "mean_cost", "noticeable_count",
                                                   "worst_cost")}},
        "coverage": [_summary(s, names, objective) for s in curve],
        "unservable": [name for j, name in enumerate(scene) if not np.isfinite(cost[j]).any()],
        "served_matrix": cost_matrix_section(scene, names, cost) | {
            "noticeable": [[bool(x) for x in row] for row in noticeable]},
    }


def coverage_rows(document: dict) -> list[tuple]:
    """The printed coverage table: K, objective, mean cost, noticeable objects, props."""
    objective = document["settings"]["objective"]
    mean = objective == "mean"  # its value is the mean cost: one column, not two
    rows = [("K",) + (() if mean else (objective,)) + ("mean_cost", "noticeable", "exact", "props")]
    for c in document["coverage"]:
        rows.append((c["k"],) + (() if mean else (c["value"],))
                    + (c["mean_cost"], c["noticeable_count"],
                                                                   "yes" if c["exact"] else "no",
                     ", ".join(c["props"])))
    return rows


def selection_rows(document: dict) -> list[tuple]:
    """The printed per-object table: object, prop, cost, noticeable, the prop that would help
    most."""
    rows = [("virtual", "tangible", "cost", "noticeable", "best addition", "cost with it")]
    for o in document["objects"]:
        rows.append((o["virtual"], o["tangible"] or "-", "-" if o["cost"] is None else o["cost"],
                     "-" if o["noticeable"] is None else ("yes" if o["noticeable"] else "no"),
                     o["best_addition"] or "-", "-" if o["cost_with_addition"] is None
                     else o["cost_with_addition"]))
    return rows
