"""The method's static ratings joined with the study's placements: a table ``calibrate`` reads.

The method's user study rated 36 placements (3 tangible parts x 6 virtual objects x the paper's
algorithm and the reference) on a 7-point scale; the means of the static task (grasp only) ship as
``data/ratings_static.csv`` (the paper's Table 3: ``paper_vo``, the paper's numbering, with the
stacking order it stands for, the part pinched, ``pose_source`` and the mean and SD of the rating).

:func:`static_ratings_table` joins them with a run of the rebuilt study (``pinchmatch demo``): per
rated placement, the study's object name, the cost under the run's model and each criterion's
difference in JND, the columns :func:`pinchmatch.match.ratings.read_ratings` reads. The
differences are the run's, not the paper's: they follow this version's features and criteria.
"""

from __future__ import annotations

import csv
import io
from importlib import resources

from ..match.cost import CRITERIA

#: the table's columns: the placement, its rating, its cost and differences
COLUMNS = (["pair", "object", "paper_vo", "virtual_order", "tangible_part", "pose_source", "rating",
            "rating_sd", "cost", "cost_paper", "cost_expected"] + [f"{c}_jnd" for c in CRITERIA])


def static_ratings() -> list[dict]:
    """The shipped ratings, one dict per rated placement (values as text)."""
    text = resources.files("pinchmatch").joinpath("data",
                                                  "ratings_static.csv").read_text(encoding="utf-8")
    return list(csv.DictReader(io.StringIO(text)))


def static_ratings_rows(study_rows: list, virtual_names: list[str]) -> list[dict]:
    """The ratings joined with the study's rows (``runner.study``): one dict per rated placement.

    ``virtual_names``: the study's virtual objects' names, in the study's order (``virtual`` -
    1)."""
    by_key = {("/".join(r["virtual_order"]), r["tangible_part"]): r for r in study_rows}
    out = []
    for rated in static_ratings():
        row = by_key[(rated["virtual_order"], rated["tangible_part"])]
        entry = row[rated["pose_source"]]
        jnd = entry.get("criteria_jnd") or {}
        name = virtual_names[row["virtual"] - 1]
        out.append({"pair": f"{rated['tangible_part']}/{name}/{rated['pose_source']}",
                    "object": name,
                    **{k: rated[k]
                       for k in ("paper_vo", "virtual_order", "tangible_part", "pose_source",
                                 "rating",
                                             "rating_sd")},
                    "cost": entry["cost"], "cost_paper": entry["cost_paper"],
                    "cost_expected": entry.get("cost_expected"),
                    **{f"{c}_jnd": jnd.get(c) for c in CRITERIA}})
    return out


def static_ratings_table(study_rows: list, virtual_names: list[str]) -> str:
    """:func:`static_ratings_rows` as CSV text (RFC 4180, a header row)."""
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in static_ratings_rows(study_rows, virtual_names):
        writer.writerow({k: ("" if v is None else v) for k, v in row.items()})
    return out.getvalue()
