"""Criterion weights fitted to ratings (``pinchmatch calibrate``) and used by ``match
--weights-file``."""

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

TRUE = {"width": 2.0, "tilt": 0.0, "normal": 1.0, "kmax": 0.25, "mass": 0.5}
A, B = 6.5, 4.5  # the rating of a perfect match, and how far a surely noticed difference lowers it


def noticed_probability(jnd: np.ndarray, weights: np.ndarray, beta: float = 3.5) -> np.ndarray:
    """The cost's own psychometric form, written out: P = 1 - prod_c 2^(-w_c x_c^beta)."""
    return 1.0 - np.prod(0.5 ** (weights * jnd ** beta), axis=1)


def ratings_csv(weights: dict, *, pairs: int = 60, repeats: int = 3, noise: float = 0.3,
                seed: int = 1, integer: bool = False, beta: float = 3.5) -> str:
    """Rated pose pairs whose ratings fall with the probability that known ``weights`` notice
    them."""
    rng = np.random.default_rng(seed)
    names = list(weights)
    jnd = rng.uniform(0.0, 1.6, (pairs, len(names)))
    p = noticed_probability(jnd, np.array([weights[c] for c in names]), beta)
    out = io.StringIO()
    w = csv.writer(out)
    w.writerow(["trial", "participant", "object", "pose_source", "rating"]
               + [f"{c}_jnd" for c in names])
    trial = 0
    for r in range(repeats):
        for i in range(pairs):
            rating = A - B * p[i] + rng.normal(0.0, noise)
            if integer:
                rating = float(np.clip(np.round(rating), 1, 7))
            trial += 1
            w.writerow([trial, f"P{r}", f"object{i}", "ours", repr(float(rating)) if noise == 0
                        else f"{rating:.4f}"]
                       + [repr(float(v)) if noise == 0 else f"{v:.5f}" for v in jnd[i]])
    return out.getvalue()


@pytest.mark.parametrize("pooling, beta", [("quick", 3.5), ("sum", 2.0)])
def test_noiseless_ratings_give_back_the_generating_weights_and_intercept(pooling, beta):
    fit = calibrate(read_ratings(ratings_csv(TRUE, noise=0.0, beta=beta, repeats=1), "t.csv"),
                    pooling=pooling)
    got = np.array([fit.fitted_weights[c] for c in TRUE])
    np.testing.assert_allclose(got, list(TRUE.values()), atol=1e-6)
    assert fit.intercept == pytest.approx(A, abs=1e-6) and fit.drop == pytest.approx(B, abs=1e-6)
    # a criterion without a column keeps its default: 1 (the literature's JND), 0 for com
    assert fit.weights["axis"] == 1.0 and fit.weights["kmin"] == 1.0 and fit.weights["com"] == 0.0


def test_the_fit_tells_the_cost_it_is_used_with_from_a_linear_one():
    """Ratings made by the sum of squares are not fitted exactly by the quick pooling, and the other
    way round: the fit is of the cost's own form, not of any line through the differences."""
    table = read_ratings(ratings_csv(TRUE, noise=0.0, beta=2.0, repeats=1), "t.csv")
    exact, other = calibrate(table, pooling="sum"), calibrate(table, pooling="quick")
    got = np.array([other.fitted_weights[c] for c in TRUE])
    assert np.abs(got - list(TRUE.values())).max() > 0.05
    assert np.allclose([exact.fitted_weights[c] for c in TRUE], list(TRUE.values()), atol=1e-6)


def test_known_weights_are_recovered_from_noisy_ratings():
    fit = calibrate(read_ratings(ratings_csv(TRUE), "t.csv"))
    got = np.array([fit.fitted_weights[c] for c in TRUE])
    assert np.allclose(got, list(TRUE.values()), atol=0.35), got
    assert fit.rows == 180 and fit.pairs == 60 and fit.folds == 5 and fit.kept == "fitted"
    # held out by pose pair, the fitted weights rank the pairs better than equal weights do
    assert fit.held_out_spearman < fit.default_spearman < 0
    assert fit.held_out_spearman < -0.85


def test_a_seven_point_scale_still_recovers_the_order_of_the_weights():
    fit = calibrate(read_ratings(ratings_csv(TRUE, integer=True, noise=0.5), "t.csv"))
    got = [fit.fitted_weights[c] for c in TRUE]
    assert got[0] > got[2] > got[3] and got[1] < 0.2
    assert fit.held_out_spearman < fit.default_spearman


def test_weights_worse_than_the_defaults_held_out_are_not_written_unless_forced():
    """Twelve noisy rows of six placements made with the default weights: the fit chases the
    noise."""
    equal = {"width": 1.0, "kmax": 1.0}
    table = read_ratings(ratings_csv(equal, pairs=6, repeats=2, noise=0.8, seed=0), "t.csv")
    fit = calibrate(table)
    assert fit.held_out_spearman > fit.default_spearman
    assert fit.kept == "defaults" and all(fit.weights[c] == 1.0 for c in equal)
    assert fit.fitted_weights != fit.weights
    forced = calibrate(table, force=True)
    assert forced.kept == "fitted" and forced.weights == forced.fitted_weights


def test_one_placement_reached_from_two_pairs_is_one_group():
    rows = ["pair,rating,width_jnd,kmax_jnd"] + [f"p{i},{5 - i / 10},{i / 10},{i / 20}"
                                                 for i in range(8)]
    rows.append("p9,4.9,0.1,0.05")  # the same differences as p1: the same placement
    r = read_ratings("\n".join(rows) + "\n", "t.csv")
    assert r.pair[8] == r.pair[1] and r.pair.max() + 1 == 8


def test_the_static_study_is_held_out_by_virtual_object(demo_out):
    table = read_ratings((demo_out / "ratings_static.csv").read_text(), "static",
                         criteria=("normal", "kmax", "mass"))
    assert len(table.rating) == 36 and table.obj.max() + 1 == 6
    fit = calibrate(table, hold_out="object")
    assert fit.folds == 6 and fit.held_out_spearman < -0.8


def test_pairs_are_grouped_so_repetitions_never_straddle_folds():
    r = read_ratings(ratings_csv(TRUE, pairs=10, repeats=4), "t.csv")
    assert r.pair.max() + 1 == 10 and np.bincount(r.pair).tolist() == [4] * 10


@pytest.mark.parametrize("change, message", [
    (lambda rows: rows[:4], "rated rows cannot fix"),
    (lambda rows: [dict(r, width_jnd="0.5") for r in rows], "width never changes"),
    (lambda rows: [dict(r, kmax_jnd=str(float(r["kmax_jnd"]) / 20)) for r in rows],
     "kmax never differs by 0.1"),
    (lambda rows: [dict(r, kmax_jnd="1.2" if r["trial"] == "1" else "0.05") for r in rows],
     "kmax differs by 0.1 JND or more in one placement only"),
    (lambda rows: [dict(r, width_jnd="0.5", kmax_jnd=str(float(r["kmax_jnd"]) / 20)) for r in rows],
     "width never changes; kmax never differs by 0.1 JND or more in the table, so their weights "
     "cannot be "
     "determined; leave them out with --criteria tilt,normal,mass$"),
    (lambda rows: [dict(r, width_jnd="0.5", tilt_jnd="0.5", normal_jnd="0",
                        kmax_jnd=str(float(r["kmax_jnd"]) / 20),
                        mass_jnd=str(float(r["mass_jnd"]) / 20)) for r in rows],
     "width, tilt, normal never change; kmax, mass never differ by 0.1 JND or more in the table, "
     "so no weight"),
    (lambda rows: [dict(r, tilt_jnd=r["width_jnd"]) for r in rows], "move together"),
    (lambda rows: [dict(r, rating="4") for r in rows], "every rating is 4"),
    (lambda rows: [dict(r, rating=str(1 + sum(float(r[f"{c}_jnd"]) ** 2 for c in TRUE)))
                   for r in rows],
     "check the rating scale"),
    (lambda rows: [dict(r, rating=str(3 + (int(r["trial"]) * 7 % 11) / 3)) for r in rows],
     "these criteria do not predict the ratings"),
    (lambda rows: [dict(r, object="same", width_jnd="0.5", tilt_jnd="0.5", normal_jnd="0.5",
                        kmax_jnd="0.5", mass_jnd="0.5") for r in rows], "distinct placements"),
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


def test_without_criteria_the_fit_leaves_out_what_the_table_cannot_determine_and_says_so(
    tmp_path, capsys):
    rows = list(csv.DictReader(io.StringIO(ratings_csv(TRUE, pairs=30, repeats=2))))
    rng = np.random.default_rng(3)
    # tilt flat, com present
    rows = [dict(r, tilt_jnd="0.0", com_jnd=f"{rng.uniform(0, 2):.4f}") for r in rows]
    table = tmp_path / "ratings.csv"
    with table.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    auto, named = tmp_path / "auto.json", tmp_path / "named.json"
    assert main(["calibrate", str(table), "-o", str(auto)]) == 0
    shown = capsys.readouterr().out
    assert main(["calibrate", str(table), "--criteria", "width,normal,kmax,mass", "-o", str(named),
                 "-q"]) == 0
    a, n = json.loads(auto.read_text()), json.loads(named.read_text())
    assert a["fit"].pop("not_fitted") == {"com": "is not a default criterion (name it with "
                                                 "--criteria)",
                                          "tilt": "never changes"}
    # the same fit as naming the others
    assert a["weights"] == n["weights"] and a["fit"] == n["fit"]
    assert a["weights"]["tilt"] == 1.0 and a["weights"]["com"] == 0.0  # kept at their defaults
    assert "not fitted, kept at their defaults: com is not a default criterion" in shown
    # the table's title is one line, not folded to the table's width
    assert "weights fitted to 60 ratings of 30 placements (quick pooling)\n" in shown


def test_calibrate_then_match_with_the_weights_file(tmp_path, write_mesh):
    box_stl = write_mesh(trimesh.creation.box(extents=(40.0, 30.0, 50.0)), "box.stl")
    table = tmp_path / "ratings.csv"
    table.write_text(ratings_csv(TRUE))
    weights = tmp_path / "weights.json"
    assert main(["calibrate", str(table), "-o", str(weights), "-q"]) == 0
    doc = json.loads(weights.read_text())
    assert doc["schema"] == "pinchmatch.weights/1" and set(doc["weights"]) == set(CRITERIA)
    assert doc["pooling"] == "quick" and doc["fit"]["kept"] == "fitted"
    assert doc["fit"]["held_out_spearman_fitted"] < doc["fit"]["held_out_spearman_default"]
    out = tmp_path / "out"
    assert main(["match", "--tangible", str(box_stl), "--virtual", str(box_stl), "--count", "200",
                 "--weights-file", str(weights), "--no-cache", "--no-view", "-o", str(out),
                 "-q"]) == 0
    used = json.loads((out / "matches.json").read_text())["settings"]["weights"]
    assert used == pytest.approx({c: w for c, w in doc["weights"].items() if c != "com"})


@pytest.mark.parametrize("argv, message", [
    (["calibrate", "{missing}"], "no such ratings table"),
    (["calibrate", "{empty}"], "no rated rows"),
    (["calibrate", "{table}", "--criteria", "width,grip"], "unknown grip"),
    (["calibrate", "{table}", "--criteria", "width,axis"], "no column axis_jnd"),
    (["match", "--tangible", "{table}", "--virtual", "{table}", "--weights-file", "{table}"],
     "not JSON"),
    (["match", "--tangible", "{table}", "--virtual", "{table}", "--weights-file", "{weights}",
      "--weights", "width=1"], "give one of them"),
])
def test_bad_calibration_input_is_one_line_and_exit_2(tmp_path, capsys, argv, message):
    files = {"missing": tmp_path / "nope.csv", "empty": tmp_path / "empty.csv",
             "table": tmp_path / "t.csv", "weights": tmp_path / "w.json"}
    files["empty"].write_text("")
    files["table"].write_text(ratings_csv(TRUE, pairs=20, repeats=1))
    files["weights"].write_text(json.dumps({"weights": {"width": 1}}))
    argv = [a.format(**files) for a in argv]
    assert main(argv + ["-o",
                        str(tmp_path / "o.json" if argv[0] == "calibrate" else tmp_path
                            / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and "Traceback" not in err[0], err
    assert not (tmp_path / "o.json").exists() and not (tmp_path / "o").exists()


def test_demo_runs_the_study_under_calibrated_weights_and_another_pooling(tmp_path, demo_out):
    weights = tmp_path / "static.json"
    assert main(["calibrate", str(demo_out / "ratings_static.csv"), "--criteria",
                 "normal,kmax,mass", "--pooling", "sum", "-o", str(weights), "-q"]) == 0
    fitted = json.loads(weights.read_text())
    assert fitted["pooling"] == "sum"
    out = tmp_path / "demo"
    assert main(["demo", "--pooling", "sum", "--weights-file", str(weights), "--no-figures",
                 "--no-view", "-o", str(out), "-q"]) == 0
    settings = json.loads((out / "study.json").read_text())["settings"]
    assert settings["pooling"] == "sum"
    assert settings["weights"] == pytest.approx({c: w for c, w in fitted["weights"].items()
                                                 if c != "com"})
    # weights fitted for one pooling are refused by a run with the other, in one line
    assert main(["demo", "--weights-file", str(weights), "-o", str(tmp_path / "other"), "-q"]) == 2
    assert not (tmp_path / "other").exists()


def test_the_fits_jacobian_is_the_model_s_derivative():
    from pinchmatch.match.calibrate import rating_jacobian, rating_model

    rng = np.random.default_rng(3)
    x_beta = rng.uniform(0.0, 3.0, size=(12, 3))
    theta = np.array([6.2, 3.1, 0.8, 0.3, 1.7])
    numeric = np.empty((12, 5))
    for k in range(5):
        step = np.zeros(5)
        step[k] = 1e-6
        numeric[:, k] = (rating_model(theta + step, x_beta)
                         - rating_model(theta - step, x_beta)) / 2e-6
    np.testing.assert_allclose(rating_jacobian(theta, x_beta), numeric, rtol=1e-6, atol=1e-8)


def test_the_criteria_that_move_together_are_named():
    rows = list(csv.DictReader(io.StringIO(ratings_csv(TRUE, pairs=20, repeats=1))))
    rows = [dict(r, tilt_jnd=r["width_jnd"]) for r in rows]
    text = ",".join(rows[0]) + "\n" + "\n".join(",".join(r.values()) for r in rows) + "\n"
    with pytest.raises(ConfigError, match=r"the differences in width, tilt move together"):
        calibrate(read_ratings(text, "t.csv"))


def test_ratings_that_rise_with_the_differences_are_refused_by_the_fit_itself():
    """One criterion, rated higher the more it is noticed: no positive weight with a positive drop
    fits better than none, and the refusal says to check the scale."""
    from pinchmatch.match import calibrate as module

    jnd = np.linspace(0.0, 2.0, 16)
    rows = ["pair,width_jnd,rating"] + [f"{k},{x:.4f},{2 + 4 * (1 - 0.5 ** (x ** 3.5)):.6f}"
                                        for k, x in enumerate(jnd)]
    table = read_ratings("\n".join(rows) + "\n", "t.csv")
    w, _, drop = module._fit(table.jnd ** 3.5, table.rating)
    # the refusal comes from the fit, not from a check before it
    assert not (w > 0).any() or drop <= 1e-9
    with pytest.raises(ConfigError, match="check the rating scale"):
        calibrate(table)


@pytest.mark.parametrize("text",
                         ['[1, 2]', '"weights"', '{"weights": [1, 2]}',
                          '{"weights": {"width": true}}'])
def test_a_weights_file_that_is_not_an_object_of_numbers_is_refused(text):
    from pinchmatch.match.calibrate import read_weights_file

    with pytest.raises(ConfigError, match="needs a 'weights' object"):
        read_weights_file(text, "w.json")


def test_a_rating_far_below_any_scale_is_refused():
    rows = list(csv.DictReader(io.StringIO(ratings_csv(TRUE, pairs=20, repeats=1))))
    rows[3]["rating"] = "-2e6"
    text = ",".join(rows[0]) + "\n" + "\n".join(",".join(r.values()) for r in rows) + "\n"
    with pytest.raises(ConfigError, match="a rating beyond"):
        read_ratings(text, "t.csv")


def test_the_criteria_a_table_can_determine_are_counted_by_placement():
    from pinchmatch.match.calibrate import fittable_criteria

    rows = ["pair,width_jnd,com_jnd,tilt_jnd,normal_jnd,kmax_jnd,mass_jnd,rating",
            # kmax reaches 0.1 JND in placement a only, rated twice
            "a,0.1,0.5,0.3,0.099,1.5,0.2,5",
            "a,0.1,0.5,0.3,0.099,1.5,0.2,4",
            "b,0.1,0.1,0.3,0.05,0.0,0.9,3",  # width exactly 0.1 JND in a second placement
            "c,0.0,0.9,0.3,0.0,0.05,0.0,6",
            "d,0.0,0.2,0.3,0.02,0.0,1.4,2"]
    table = read_ratings("\n".join(rows) + "\n", "t.csv")
    fitted, left_out = fittable_criteria(table)
    assert fitted == ("width", "mass")
    assert left_out == {"com": "is not a default criterion (name it with --criteria)",
                        "tilt": "never changes", "normal": "never differs by 0.1 JND or more",
                        "kmax": "differs by 0.1 JND or more in one placement only"}


def test_a_calibration_document_is_plain_json():
    fit = calibrate(read_ratings(ratings_csv(TRUE, pairs=20, repeats=2), "t.csv"))
    document = fit.as_dict("t.csv")
    assert json.loads(json.dumps(document)) == document  # no numpy numbers left in it
    assert type(fit.pairs) is int and type(fit.rows) is int and fit.pairs == 20


def test_weights_fitted_with_com_are_read_back_by_a_run_of_the_papers_criteria(
    tmp_path, capsys, write_mesh):
    """A fit that names com writes the paper's criteria set into its file; a run with --criteria
    paper reads it back, a default run is refused in one line naming the fix (before: no run could
    read it)."""
    box_stl = write_mesh(trimesh.creation.box(extents=(40.0, 30.0, 50.0)), "box.stl")
    paper = {"width": 2.0, "com": 1.0, "normal": 1.0, "kmax": 0.25}
    table = tmp_path / "ratings.csv"
    table.write_text(ratings_csv(paper))
    weights = tmp_path / "weights.json"
    assert main(["calibrate", str(table), "--criteria", "width,com,normal,kmax", "--force", "-o",
                 str(weights), "-q"]) == 0
    doc = json.loads(weights.read_text())
    assert (doc["criteria"] == "paper" and doc["weights"]["com"] > 0 and doc["weights"]["mass"]
            == 0.0)
    out = tmp_path / "out"
    argv = ["match", "--tangible", str(box_stl), "--virtual", str(box_stl), "--count", "150",
            "--weights-file", str(weights), "--no-cache", "--no-view", "-q"]
    assert main(argv + ["--criteria", "paper", "-o", str(out)]) == 0
    used = json.loads((out / "matches.json").read_text())["settings"]["weights"]
    assert used == pytest.approx({c: w for c, w in doc["weights"].items() if c != "mass"})
    capsys.readouterr()
    assert main(argv + ["-o", str(tmp_path / "refused")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--criteria paper" in err[0] and not (tmp_path / "refused").exists()
    # com and mass both charge the lever arm: a fit of both is refused before any work
    both = tmp_path / "both.csv"
    both.write_text(ratings_csv({"width": 1.0, "com": 1.0, "mass": 1.0}, pairs=20, repeats=1))
    assert main(["calibrate", str(both), "--criteria", "width,com,mass", "-o",
                 str(tmp_path / "both.json"), "-q"]) == 2
    assert "com and mass" in capsys.readouterr().err


def _study(seed=0):
    """A synthetic study: 74 placements rated by 3 raters on a 7-point scale, true weights width 3,
    kmax 0.3, axis 1 and normal 1; axis differs by 0.5 JND in one placement and 0.15 in another
    (0.05 elsewhere), normal never above 0.3: neither is ever near noticeable, so the ratings cannot
    tell their weights."""
    rng = np.random.default_rng(seed)
    n = 74
    jnd = np.column_stack([rng.uniform(0.0, 1.6, n), rng.uniform(0.0, 3.0, n), np.full(n, 0.05),
                           rng.uniform(0.0, 0.3, n)])
    jnd[7, 2], jnd[30, 2] = 0.5, 0.15
    p = 1.0 - 2.0 ** -(jnd ** 3.5 @ np.array([3.0, 0.3, 1.0, 1.0]))
    lines = ["pair,width_jnd,kmax_jnd,axis_jnd,normal_jnd,rating"]
    for k in range(n):
        for _ in range(3):
            rating = float(np.clip(np.round(6.5 - 5.0 * p[k] + rng.normal(0.0, 0.6)), 1, 7))
            lines.append(f"{k},{','.join(f'{v:.4f}' for v in jnd[k])},{rating:g}")
    return "\n".join(lines) + "\n"


def test_weights_the_table_cannot_determine_keep_their_defaults_with_an_interval_each():
    fit = calibrate(read_ratings(_study(), "study.csv"))
    assert set(fit.intervals) == {"width", "kmax", "axis", "normal"}
    lo, hi = fit.intervals["width"]
    assert lo <= 3.0 <= hi and hi <= 4.0 * lo  # determined, and the truth inside
    assert {"axis", "normal"} <= set(fit.undetermined)
    assert fit.weights["axis"] == 1.0 and fit.weights["normal"] == 1.0  # left at their defaults
    assert "width" not in fit.undetermined and fit.weights["width"] == fit.fitted_weights["width"]
    doc = fit.as_dict("study.csv")["fit"]
    assert (set(doc["undetermined"]) >= {"axis", "normal"}
            and len(doc["weight_intervals_90"]["width"]) == 2)
    again = calibrate(read_ratings(_study(), "study.csv"))
    assert again.intervals == fit.intervals  # seeded


def test_tables_as_spreadsheets_write_them_are_read_alike():
    """Semicolons with decimal commas, tabs, and CR-only line endings give the table the comma CSV
    gives."""
    text = _study()
    plain = read_ratings(text, "a.csv")
    for variant in (text.replace(",", ";").replace(".", ","), text.replace(",", "\t"),
                    text.replace("\n", "\r"), text.replace("\n", "\r\n")):
        r = read_ratings(variant, "b.csv")
        assert r.criteria == plain.criteria
        np.testing.assert_array_equal(r.rating, plain.rating)
        np.testing.assert_array_equal(r.jnd, plain.jnd)


def test_a_bad_cell_is_named_by_its_line():
    """Line numbers count the file's lines (a blank line and an unrated trial before the bad
    cell)."""
    text = "pair,width_jnd,rating\n1,0.2,6\n\n2,0.4,\n3,abc,5\n"
    with pytest.raises(ConfigError, match=r"b.csv: line 5: width_jnd = 'abc' is not a number"):
        read_ratings(text, "b.csv")
    with pytest.raises(ConfigError,
                       match=r"no 'rating' column \(the header reads 'pair', 'width_jnd'\)"):
        read_ratings("pair;width_jnd\n1;0,2\n", "b.csv")


def test_a_table_the_defaults_rank_is_kept_at_the_defaults_when_no_fit_predicts(monkeypatch):
    """When the fit finds no weight, a table that the default weights do rank is not refused: the
    defaults are written, as when a fit ranks held-out ratings no better than they do."""
    from pinchmatch.match import calibrate as module

    r = read_ratings(_study(), "study.csv")
    monkeypatch.setattr(module, "_fit", lambda x, rating: (np.zeros(x.shape[1]), 5.0, 0.0))
    fit = module.calibrate(r)
    assert fit.kept == "defaults" and fit.default_spearman < 0
    assert all(fit.weights[c] == v for c, v in module.complete_weights({}).items())
