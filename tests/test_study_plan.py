"""The headset study's plan: the method's 18 pose pairs x 2 algorithms x 3 repetitions, seeded."""

import json
from collections import Counter

import numpy as np
import pytest

from pinchmatch.errors import ConfigError
from pinchmatch.match.cost import DEFAULT_CRITERIA, QUICK_EXPONENT
from pinchmatch.export.study_plan import study_plan


def test_the_demo_writes_the_methods_plan(demo_out, demo):
    plan = json.loads((demo_out / "study_plan.json").read_text())
    assert plan["schema"] == "pinchmatch.study-plan/1" and plan["sources"] == ["paper", "ref"]
    assert len(plan["pairs"]) == 36 and len(plan["trials"]) == 108
    # three blocks, each every pair once, in different orders
    blocks = [[t["pair"] for t in plan["trials"] if t["repetition"] == r] for r in (1, 2, 3)]
    assert all(sorted(b) == list(range(36)) for b in blocks)
    assert (blocks[0] != blocks[1] != blocks[2] and [t["trial"] for t in plan["trials"]]
            == list(range(1, 109)))
    names = {m["virtual"] for m in json.loads((demo_out / "matches.json").read_text())["matches"]}
    assert {p["virtual"] for p in plan["pairs"]} == names
    assert Counter(p["pose_source"] for p in plan["pairs"]) == {"paper": 18, "ref": 18}


def test_each_pair_places_the_virtual_fingers_on_the_props(demo_out):
    """The transform takes the virtual contacts onto the tangible contacts (the fingers meet), and
    the per-criterion differences pool to the pair's cost under the default weights and pooling."""
    plan = json.loads((demo_out / "study_plan.json").read_text())
    for p in plan["pairs"]:
        T = np.array(p["transform_virtual_to_tangible"])
        assert (np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-5)
                and np.linalg.det(T[:3, :3]) > 0)
        v = np.array([p["virtual_p1_mm"], p["virtual_p2_mm"]])
        if p["finger_order_swapped"]:
            v = v[::-1]
        placed = v @ T[:3, :3].T + T[:3, 3]
        t = np.array([p["tangible_p1_mm"], p["tangible_p2_mm"]])
        if p["pose_source"] == "ref":  # superimposed: the fingers close along the same line
            assert np.allclose(T, np.eye(4))
            u = (t[1] - t[0]) / np.linalg.norm(t[1] - t[0])
            off_line = placed - t[0] - np.outer((placed - t[0]) @ u, u)
            assert np.abs(off_line).max() < 1e-3
        else:  # registered: the midpoints meet and the pinch lines are parallel
            assert np.allclose(placed.mean(axis=0), t.mean(axis=0), atol=0.05)
            a, b = placed[1] - placed[0], t[1] - t[0]
            assert np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b) > 1 - 1e-6
        total = sum(v ** QUICK_EXPONENT for c, v in p["criteria_jnd"].items()
                    if c in DEFAULT_CRITERIA)
        assert total ** (1 / QUICK_EXPONENT) == pytest.approx(p["cost"], rel=2e-3, abs=2e-4), p


def test_the_order_is_seeded(demo):
    rows, names = demo.study.rows, [v.name for v in demo.study.virtuals]
    a, b = study_plan(rows, names, seed=3), study_plan(rows, names, seed=3)
    assert a == b and a["trials"] != study_plan(rows, names, seed=4)["trials"]
    three = study_plan(rows, names, seed=0, sources=("ours", "paper", "ref"), repetitions=1)
    assert len(three["trials"]) == len(three["pairs"]) == 54
    with pytest.raises(ConfigError, match="choose from"):
        study_plan(rows, names, seed=0, sources=("mine",))


def test_the_page_leaves_out_the_trials_of_objects_it_has_no_scene_for(demo_out):
    from pinchmatch.export.view import page_data, read_matches

    doc = read_matches(demo_out)
    gone = doc["matches"][1]["virtual"]
    doc["matches"][1] = {"virtual": gone, "tangible": None, "cost": None,
                         "reason": "no tangible left"}
    study = page_data(demo_out, doc)["study"]
    assert study["left_out"] == [gone] and len(study["pairs"]) == 30 and len(study["trials"]) == 90
    assert all(study["pairs"][t["pair"]]["virtual"] == t["virtual"] != gone
               for t in study["trials"])
    assert [p["pair"] for p in study["pairs"]] == list(range(30))
