"""Criterion weights fitted to ratings (``pinchmatch calibrate``) and used by ``match --weights-file``."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest
import trimesh

from pinchmatch.cli.main import main
from pinchmatch.errors import ConfigError
from pinchmatch.match.calibrate import calibrate, read_ratings
from pinchmatch.match.cost import CRITERIA

TRUE = {"width": 2.0, "com": 0.5, "tilt": 0.0, "normal": 1.0, "kmax": 0.25}


def ratings_csv(weights: dict, *, pairs: int = 60, repeats: int = 3, noise: float = 0.3, seed: int = 1,
                integer: bool = False) -> str:
    """Rated pose pairs whose ratings fall with the cost of known ``weights``, plus noise."""
    rng = np.random.default_rng(seed)
    names = list(weights)
    jnd = rng.uniform(0.0, 1.6, (pairs, len(names)))
    cost = (jnd ** 2) @ np.array([weights[c] for c in names])
    out = io.StringIO()
    w = csv.writer(out)
    w.writerow(["trial", "participant", "object", "pose_source", "rating"] + [f"{c}_jnd" for c in names])
    trial = 0
    for r in range(repeats):
        for i in range(pairs):
            rating = 6.5 - 0.6 * cost[i] + rng.normal(0.0, noise)
            if integer:
                rating = float(np.clip(np.round(rating), 1, 7))
            trial += 1
            w.writerow([trial, f"P{r}", f"object{i}", "ours", f"{rating:.4f}"] + [f"{v:.5f}" for v in jnd[i]])
    return out.getvalue()


def test_known_weights_are_recovered():
    fit = calibrate(read_ratings(ratings_csv(TRUE), "t.csv"))
    expected = np.array(list(TRUE.values())) * len(TRUE) / sum(TRUE.values())  # scaled to sum to the count
    got = np.array([fit.weights[c] for c in TRUE])
    assert np.allclose(got, expected, atol=0.12), (got, expected)
    assert all(fit.weights[c] == 0.0 for c in CRITERIA if c not in TRUE)
    assert fit.rows == 180 and fit.pairs == 60 and fit.folds == 5
    # held out by pose pair, the fitted weights rank the pairs better than equal weights do
    assert fit.held_out_spearman < fit.default_spearman < 0
    assert fit.held_out_spearman < -0.9


def test_a_seven_point_scale_still_recovers_the_order_of_the_weights():
    fit = calibrate(read_ratings(ratings_csv(TRUE, integer=True, noise=0.5), "t.csv"))
    got = [fit.weights[c] for c in TRUE]
    assert got[0] > got[3] > got[1] > got[2] - 0.05 and got[2] < 0.2
    assert fit.held_out_spearman < fit.default_spearman


def test_pairs_are_grouped_so_repetitions_never_straddle_folds():
    r = read_ratings(ratings_csv(TRUE, pairs=10, repeats=4), "t.csv")
    assert r.pair.max() + 1 == 10 and np.bincount(r.pair).tolist() == [4] * 10


@pytest.mark.parametrize("change, message", [
    (lambda rows: rows[:4], "rated rows cannot fix"),
    (lambda rows: [dict(r, width_jnd="0.5") for r in rows], "width never changes"),
    (lambda rows: [dict(r, com_jnd=r["width_jnd"]) for r in rows], "move together"),
    (lambda rows: [dict(r, rating="4") for r in rows], "every rating is 4"),
    (lambda rows: [dict(r, rating=str(1 + sum(float(r[f"{c}_jnd"]) ** 2 for c in TRUE))) for r in rows],
     "do not fall"),
    (lambda rows: [dict(r, object="same") for r in rows], "distinct pose pairs"),
    (lambda rows: [dict(r, kmax_jnd="nan") for r in rows], "not finite"),
    (lambda rows: [dict(r, tilt_jnd="wide") for r in rows], "is not a number"),
])
def test_data_that_cannot_determine_the_weights_is_refused(change, message):
    rows = list(csv.DictReader(io.StringIO(ratings_csv(TRUE, pairs=20, repeats=1))))
    rows = change(rows)
    out = io.StringIO()
    w = csv.DictWriter(out, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    with pytest.raises(ConfigError, match=message):
        calibrate(read_ratings(out.getvalue(), "t.csv"))


def test_calibrate_then_match_with_the_weights_file(tmp_path, write_mesh):
    box_stl = write_mesh(trimesh.creation.box(extents=(40.0, 30.0, 50.0)), "box.stl")
    table = tmp_path / "ratings.csv"
    table.write_text(ratings_csv(TRUE))
    weights = tmp_path / "weights.json"
    assert main(["calibrate", str(table), "-o", str(weights), "-q"]) == 0
    doc = json.loads(weights.read_text())
    assert doc["schema"] == "pinchmatch.weights/1" and set(doc["weights"]) == set(CRITERIA)
    assert doc["fit"]["held_out_spearman_fitted"] < doc["fit"]["held_out_spearman_default"]
    out = tmp_path / "out"
    assert main(["match", "--tangible", str(box_stl), "--virtual", str(box_stl), "--count", "200",
                 "--weights-file", str(weights), "--no-cache", "--no-view", "-o", str(out), "-q"]) == 0
    used = json.loads((out / "matches.json").read_text())["settings"]["weights"]
    assert used == pytest.approx(doc["weights"])


@pytest.mark.parametrize("argv, message", [
    (["calibrate", "{missing}"], "no such ratings table"),
    (["calibrate", "{empty}"], "no rated rows"),
    (["calibrate", "{table}", "--criteria", "width,grip"], "unknown grip"),
    (["calibrate", "{table}", "--criteria", "width,axis"], "no column axis_jnd"),
    (["match", "--tangible", "{table}", "--virtual", "{table}", "--weights-file", "{table}"], "not JSON"),
    (["match", "--tangible", "{table}", "--virtual", "{table}", "--weights-file", "{weights}", "--weights",
      "width=1"], "give one of them"),
])
def test_bad_calibration_input_is_one_line_and_exit_2(tmp_path, capsys, argv, message):
    files = {"missing": tmp_path / "nope.csv", "empty": tmp_path / "empty.csv", "table": tmp_path / "t.csv",
             "weights": tmp_path / "w.json"}
    files["empty"].write_text("")
    files["table"].write_text(ratings_csv(TRUE, pairs=20, repeats=1))
    files["weights"].write_text(json.dumps({"weights": {"width": 1}}))
    argv = [a.format(**files) for a in argv]
    assert main(argv + ["-o", str(tmp_path / "o.json" if argv[0] == "calibrate" else tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and "Traceback" not in err[0], err
    assert not (tmp_path / "o.json").exists() and not (tmp_path / "o").exists()
