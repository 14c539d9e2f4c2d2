"""How well costs rank the method's static ratings (its Table 3): Spearman's rho over the 36
placements.

    python benchmarks/bench_validity.py                    # runs the rebuilt study (about 20 s)
    python benchmarks/bench_validity.py --study study.json # a study.json that any version wrote

The 36 rated placements are the rebuilt study's ``paper`` and ``ref`` poses of each (tangible part,
virtual object) row, with the rating means of ``data/ratings_static.csv``. Printed, each with rho
(negative: costlier placements are rated lower; -1 is perfect):

- the study's own columns: ``cost`` (the version's default, on target), ``cost_paper`` (the paper's
  algorithm) and ``cost_expected`` (the default's expected cost over where guided fingers land, the
  cost ``--rank`` ranks by; a study.json without it skips the line);
- recomputed from each placement's per-criterion differences (JND): both poolings over the default
  criteria and over the paper's, and each criterion left out of the default;
- the pooling exponent chosen by leaving one virtual object out (the exponent that ranks the other
  five objects' placements best, applied to the held-out object's; rho over all 36 held-out costs);
- ``calibrate``'s held-out figure, one virtual object out at a time, over the criteria that vary.

The dynamic (lift) ratings are not here: they are held back to judge the cost.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

from pinchmatch.export.study_ratings import static_ratings_rows, static_ratings_table
from pinchmatch.match.calibrate import SMALLEST_FITTED_JND, calibrate, read_ratings
from pinchmatch.match.cost import CRITERIA, DEFAULT_CRITERIA, PAPER_CRITERIA, CostModel

#: the exponents the leave-one-object-out choice picks from
EXPONENTS = (2.0, 2.5, 3.0, 3.5, 4.0, 5.0)


def pooled(jnd: np.ndarray, criteria: tuple, exponent: float, *,
           left_out: str | None = None) -> np.ndarray:
    """(n,) Minkowski pooling of rows of per-criterion differences (JND, in CRITERIA order), weights
    1: in JND whatever the exponent (for 2, the root of the sum pooling, which ranks the same)."""
    w = np.array([1.0 if c in criteria and c != left_out else 0.0 for c in CRITERIA])
    return ((jnd ** exponent) @ w) ** (1.0 / exponent)


def rho(cost, rating) -> float:
    return float(spearmanr(cost, rating).statistic)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", metavar="study.json",
                        help="a study.json to read instead of running the study")
    args = parser.parse_args()
    if args.study:
        doc = json.loads(Path(args.study).read_text())
        rows_in = doc["rows"]
        names = [f"VO{j}" for j in range(1, 7)]
    else:
        from pinchmatch.runner.study import run_study

        study = run_study(Path(tempfile.mkdtemp(prefix="pinchmatch-validity-")))
        rows_in, names = study.rows, [v.name for v in study.virtuals]
    rows = static_ratings_rows(rows_in, names)
    rating = np.array([float(r["rating"]) for r in rows])
    jnd = np.array([[float(r[f"{c}_jnd"]) for c in CRITERIA] for r in rows])
    obj = np.array([names.index(r["object"]) for r in rows])
    table = [("the study's default cost (cost)", rho([float(r["cost"]) for r in rows], rating)),
             ("the paper's cost (paper criteria, range, sum)",
              rho([float(r["cost_paper"]) for r in rows], rating))]
    felt = [r.get("cost_expected") for r in rows]
    if all(f is not None for f in felt):  # a study.json of a version that felt its placements
        table.append(("the default's expected cost over the landings (cost_expected, what --rank "
                      "ranks by)",
                      rho([float(f) for f in felt], rating)))
    for label, criteria in (("default", DEFAULT_CRITERIA), ("paper's seven", PAPER_CRITERIA),
                            ("paper's seven + mass", PAPER_CRITERIA + ("mass",))):
        for pooling, beta in (("quick", 3.5), ("sum", 2.0)):
            table.append((f"{label} criteria, jnd, {pooling}",
                          rho(pooled(jnd, criteria, beta), rating)))
    for c in DEFAULT_CRITERIA:
        table.append((f"default without {c}, quick",
                      rho(pooled(jnd, DEFAULT_CRITERIA, 3.5, left_out=c), rating)))
    # the exponent, chosen without the held-out object
    held = np.empty(len(rows))
    picked = []
    for k in range(len(names)):
        test = obj == k
        scores = [rho(pooled(jnd[~test], DEFAULT_CRITERIA, b), rating[~test]) for b in EXPONENTS]
        beta = EXPONENTS[int(np.argmin(scores))]
        picked.append(beta)
        held[test] = pooled(jnd[test], DEFAULT_CRITERIA, beta)
    table.append(("exponent chosen leaving one object out (picked "
                  f"{', '.join(f'{b:g}' for b in picked)})",
                  rho(held, rating)))
    varying = tuple(c for c in DEFAULT_CRITERIA if jnd[:, CRITERIA.index(c)].max()
                    >= SMALLEST_FITTED_JND)
    ratings = read_ratings(static_ratings_table(rows_in, names), "static ratings", criteria=varying)
    for pooling in ("quick", "sum"):
        fit = calibrate(ratings, pooling=pooling, hold_out="object", force=True)
        weights = ", ".join(f"{c} {fit.fitted_weights[c]:.3g}" for c in varying)
        table.append((f"calibrate, {pooling}, held out by object ({weights})",
                      fit.held_out_spearman))
    # the study's cost is the default pooling of its own differences
    model = CostModel()
    check = model.pool(jnd ** 2)
    study_cost = np.array([float(r["cost"]) for r in rows])
    if not args.study and not np.allclose(check, study_cost, rtol=1e-3, atol=1e-3):
        print("warning: the study's costs differ from the pooled differences", file=sys.stderr)
    width = max(len(label) for label, _ in table)
    print(f"{'cost'.ljust(width)}  rho (36 placements, static ratings)")
    for label, value in table:
        print(f"{label.ljust(width)}  {value:+.3f}")


if __name__ == "__main__":
    main()
