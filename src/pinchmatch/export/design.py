"""The design document (``OUT/design.json``) of ``pinchmatch design``.

Costs are those of the final matching run of the scene against the written STL files (the same
numbers as that run's ``matches.json``); the search's own figures (at its smaller pose count) are in
``search.history``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from ..mesh.stacks import OVERHANG_DEG, PART_KINDS, base_area_mm2, overhang_area_mm2
from ..version import __version__
from .documents import json_number

SCHEMA_DESIGN = "pinchmatch.design/1"


def prop_record(stack, path: Path, out: Path) -> dict:
    """One designed prop: its file, its parts, and what printing it needs (from the written STL)."""
    mesh = trimesh.load(path, force="mesh")
    overhang = overhang_area_mm2(mesh)
    return {"file": path.relative_to(out).as_posix(), **stack.as_dict(),
            "volume_mm3": json_number(mesh.volume, 1), "faces": len(mesh.faces),
            "watertight": bool(mesh.is_watertight),
            "winding_consistent": bool(mesh.is_winding_consistent),
            "base_area_mm2": json_number(base_area_mm2(mesh), 1),
            "overhang_area_mm2": json_number(overhang, 1),
            "printable_without_supports": bool(overhang < 1.0)}


def design_document(settings: dict, found, props: list[Path], out: Path, matches: dict | None,
                    shelf: dict | None, *, seconds: float) -> dict:
    """The design document; ``matches``: the final run's matches document; ``shelf``: the best shelf
    subset's figures (see :func:`pinchmatch.cli.universal`), or None."""
    objects = []
    for m in (matches or {}).get("matches", []):
        loud = [c for c, v in (m.get("criteria") or {}).items() if v["noticeable"]]
        objects.append({"virtual": m["virtual"], "prop": m["tangible"], "cost": m["cost"],
                        "p_noticed": m.get("p_noticed"), "noticeable": loud})
    costs = np.array([o["cost"] for o in objects if o["cost"] is not None], dtype=float)
    doc = {
        "schema": SCHEMA_DESIGN, "version": __version__, "settings": settings,
        "family": {"kinds": list(PART_KINDS), "coaxial": True, "flat_base": True,
                   "overhang_deg": OVERHANG_DEG},
        "props": [prop_record(st, p, out) for st, p in zip(found.best.stacks, props)],
        "objects": objects,
        "mean_cost": json_number(costs.mean(), 6) if len(costs) else None,
        "noticeable_count": sum(bool(m.get("noticeable"))
                                for m in (matches or {}).get("matches", [])),
        "search": {"evaluations": found.evaluations, "seconds": round(found.seconds, 2),
                   "first_evaluation_s": round(found.first_evaluation_s, 3), "pruned": found.pruned,
                   "history": [{"evaluations": e, "seconds": round(t, 2),
                                "mean_cost": json_number(c, 6)}
                               for e, t, c in found.history]},
        "seconds": round(seconds, 2),
        "shelf_comparison": None,
    }
    if shelf is not None:
        doc["shelf_comparison"] = {"props": shelf["props"],
                                   "mean_cost": json_number(shelf["mean_cost"], 6),
                                   "noticeable_count": shelf["noticeable_count"],
                                   "exact": shelf["exact"], "designed_minus_shelf_mean_cost":
                                       json_number(doc["mean_cost"] - shelf["mean_cost"], 6)
                                       if doc["mean_cost"] is not None else None}
    return doc
