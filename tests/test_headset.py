"""The viewer page in an emulated headset: IWER (Meta's Immersive Web Emulation Runtime, npm
``iwer``, a test dependency only) emulates a Quest 3 with tracked hands inside headless Chromium,
and the tests move the hands and read back, through the page's own WebXR session, what it saw.

Needs Chromium and playwright (as tests/test_view.py) and ``iwer`` installed by
``npm ci --prefix tests/js`` (.ci/run does). Outside CI they are skipped when any is missing.
Set PINCHMATCH_SCREENSHOTS=DIR to keep the emulated session's canvas at guidance and at validation.
"""

import csv
import io
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
from test_view import chromium

from pinchmatch.match.calibrate import read_ratings
from pinchmatch.match.cost import CRITERIA

IWER = Path(__file__).parent / "js" / "node_modules" / "iwer" / "build" / "iwer.min.js"
DRIVE = Path(__file__).parent / "js" / "drive_hands.js"
INSTALL = """
window.__device = new IWER.XRDevice(IWER.metaQuest3);
window.__device.installRuntime({forceInstall: true});
window.__device.primaryInputMode = 'hand';
"""
#: where the real prop stands in the emulated room: turned 30 degrees about the vertical, on a table
TURN = math.radians(30.0)
PROP_POSE = np.array([[math.cos(TURN), 0.0, math.sin(TURN), 0.05],
                      [0.0, 1.0, 0.0, 0.92],
                      [-math.sin(TURN), 0.0, math.cos(TURN), -0.38],
                      [0.0, 0.0, 0.0, 1.0]])
#: the emulated hands are configured this far off the targets, then moved on in one step
AWAY = np.array([0.0, 0.0, 0.06])


@pytest.fixture(scope="module")
def browser():
    yield from chromium((IWER, "npm ci --prefix tests/js"))


@pytest.fixture
def headset(browser, demo_out):
    """Open the demo's page in a fresh browser context with an emulated headset; returns
    open(query)."""
    yield from _headset(browser, demo_out)


@pytest.fixture
def tripod_headset(browser, tripod_demo_out):
    """As ``headset``, for the page of ``demo --grasp tripod``."""
    yield from _headset(browser, tripod_demo_out)


def _headset(browser, demo_out):
    context = browser.new_context(viewport={"width": 1200, "height": 800})
    pages = []

    def open_page(query: str = "", *, emulated: bool = True):
        pg = context.new_page()
        pg.errors = []
        pg.on("pageerror", lambda e: pg.errors.append(str(e)))
        if emulated:
            pg.add_init_script(IWER.read_text() + "\n" + INSTALL)
        pg.goto((demo_out / "index.html").as_uri() + query)
        pg.wait_for_function("window.pinchmatchXR !== undefined && document.body.dataset.shown !== "
                             "undefined")
        if emulated:
            pg.add_script_tag(path=str(DRIVE))
            pg.evaluate("drive.look([-0.05, 1.16, -0.08], [0.05, 0.99, -0.38])")
        pages.append(pg)
        return pg

    yield open_page
    for pg in pages:
        assert pg.errors == [], pg.errors
    context.close()


def state(pg) -> dict:
    return pg.evaluate("pinchmatchXR.state()")


def wait_phase(pg, phase: str, timeout_ms: int = 8000) -> None:
    pg.wait_for_function(f"pinchmatchXR.state().phase === {json.dumps(phase)}", timeout=timeout_ms)


def in_room(points) -> list:
    p = np.asarray(points, dtype=float)
    return (p @ PROP_POSE[:3, :3].T + PROP_POSE[:3, 3]).tolist()


def store_calibration(pg) -> None:
    """A calibration of the emulated prop's pose, as a session before this one would have stored
    it."""
    pg.evaluate("localStorage.setItem('pinchmatch.calibration.' + "
                "pinchmatchViewer.DATA.matches[0].tangible, "
                f"JSON.stringify({{refused: false, rms_mm: 0.4, max_mm: 0.6, date: 'test', "
                f"matrix: {json.dumps(PROP_POSE.T.reshape(-1).tolist())}}}))")


def calibrate(pg) -> dict:
    """Touch the page's marked points where they are on the emulated prop; returns the
    calibration."""
    wait_phase(pg, "calibrating")
    for k, q in enumerate(in_room(pg.evaluate("pinchmatchXR.marks()"))):
        pg.evaluate("([q]) => drive.touch('right', q)", [q])
        pg.wait_for_function(f"pinchmatchXR.state().touched.length === {k + 1} || "
                             f"pinchmatchXR.state().calibration !== null", timeout=4000)
    return state(pg)["calibration"]


def pinch_off_target(pg, turn_deg: float = 0.0, hand: str = "right"):
    """Configure a hand's pinch on the targets moved by AWAY (and turned), without touching them."""
    p1, p2 = (np.array(t) for t in pg.evaluate("pinchmatchXR.targets()"))
    pg.evaluate("([h, a, b]) => drive.pinch(h, a, b)",
                [hand, (p1 + AWAY).tolist(), (p2 + AWAY).tolist()])
    if turn_deg:
        axis = np.cross(p2 - p1, [0.0, 1.0, 0.0])
        pg.evaluate("([h, c, a, d]) => drive.turnAbout(h, c, a, d)",
                    [hand, ((p1 + p2) / 2 + AWAY).tolist(), axis.tolist(), turn_deg])
    return p1, p2


def move_on(pg, extra=(0.0, 0.0, 0.0), hand: str = "right") -> None:
    pg.evaluate("([h, d]) => drive.shift(h, d)", [hand, (-AWAY + np.asarray(extra)).tolist()])


def canvas_shot(pg, name: str) -> None:
    folder = os.environ.get("PINCHMATCH_SCREENSHOTS")
    if folder:
        Path(folder).mkdir(parents=True, exist_ok=True)
        pg.locator("#canvas-main").screenshot(path=str(Path(folder) / name))


def test_without_webxr_there_is_no_vr_button(headset):
    pg = headset(emulated=False)
    assert pg.eval_on_selector("#xr", "e => e.hidden") is True
    assert pg.evaluate("document.body.dataset.xr") is None


def test_calibrate_then_validate_after_one_second_and_not_before(headset):
    pg = headset()
    assert pg.eval_on_selector("#xr", "e => e.hidden") is False
    pg.click("#enter-vr")
    cal = calibrate(pg)
    assert cal["refused"] is False and cal["rms_mm"] < 1.0, cal
    fitted = np.array(pg.evaluate("pinchmatchXR.propMatrix()")).reshape(4, 4).T  # column-major
    assert np.abs(fitted[:3, 3] - PROP_POSE[:3, 3]).max() < 1e-3
    assert np.degrees(np.arccos(np.clip((np.trace(fitted[:3, :3] @ PROP_POSE[:3, :3].T) - 1) / 2,
                                        -1, 1))) < 0.5
    assert pg.evaluate(f"localStorage.getItem({json.dumps('pinchmatch.calibration.')} + "
                       # kept for the next session
                       "pinchmatchViewer.DATA.matches[0].tangible)") is not None
    wait_phase(pg, "guiding")
    pinch_off_target(pg)
    s = state(pg)
    assert s["validated"] is False and not s["check"]["ok"]
    canvas_shot(pg, "headset_guidance.png")
    move_on(pg)
    pg.wait_for_timeout(450)
    s = state(pg)
    assert s["check"]["ok"] and s["validated"] is False and 0.2 < s["held_s"] < 1.0, s["held_s"]
    assert s["check"]["thumb_error_mm"] < 2.0 and s["check"]["index_error_mm"] < 2.0, s["check"]
    pg.wait_for_function("pinchmatchXR.state().validated", timeout=3000)
    s = state(pg)
    assert s["validation"]["time_s"] >= 1.0 and s["phase"] == "done"
    canvas_shot(pg, "headset_validated.png")
    # then the next match of the page, not yet validated
    pg.wait_for_function("pinchmatchXR.state().phase === 'guiding' && pinchmatchViewer.current() "
                         "=== 1", timeout=8000)
    assert state(pg)["validated"] is False


def test_a_fingertip_6_mm_off_or_a_direction_15_degrees_off_is_not_validated(headset):
    pg = headset()
    store_calibration(pg)
    pg.click("#enter-vr")
    wait_phase(pg, "guiding")  # the stored calibration is reused
    assert "stored calibration" in state(pg)["status"] or state(pg)["phase"] == "guiding"
    p1, p2 = pinch_off_target(pg)
    side = np.cross(p2 - p1, [0.0, 1.0, 0.0])
    move_on(pg, 0.006 * side / np.linalg.norm(side))  # both fingertips 6 mm to the side
    pg.wait_for_timeout(1500)
    s = state(pg)
    assert s["validated"] is False and not s["check"]["ok"]
    assert (5.5 < s["check"]["index_error_mm"] < 6.5 and 5.5 < s["check"]["thumb_error_mm"]
            < 6.5), s["check"]

    # positions loose: the direction alone decides; the left hand pinches
    pg = headset("?pos_mm=50")
    pg.click("#enter-vr")
    wait_phase(pg, "guiding")
    pinch_off_target(pg, turn_deg=15.0, hand="left")
    move_on(pg, hand="left")
    pg.wait_for_timeout(1500)
    s = state(pg)
    assert s["validated"] is False and abs(s["check"]["angle_error_deg"] - 15.0) < 0.5, s["check"]
    p1, p2 = (np.array(t) for t in pg.evaluate("pinchmatchXR.targets()"))
    pg.evaluate("([c, a, d]) => drive.turnAbout('left', c, a, d)",
                [((p1 + p2) / 2).tolist(), np.cross(p2 - p1, [0.0, 1.0, 0.0]).tolist(), -2.0])
    pg.wait_for_function("pinchmatchXR.state().validated", timeout=3000)
    assert abs(state(pg)["validation"]["angle_error_deg"] - 13.0) < 0.5


def test_a_touch_on_the_wrong_point_is_refused(headset):
    pg = headset()
    pg.click("#enter-vr")
    wait_phase(pg, "calibrating")
    marks = in_room(pg.evaluate("pinchmatchXR.marks()"))
    marks[2] = (np.array(marks[2]) + [0.03, 0.0, 0.0]).tolist()  # 30 mm off
    for k, q in enumerate(marks):
        pg.evaluate("([q]) => drive.touch('right', q)", [q])
        pg.wait_for_function(f"pinchmatchXR.state().touched.length === {k + 1} || "
                             "pinchmatchXR.state().calibration !== null", timeout=4000)
    s = state(pg)
    assert s["calibration"]["refused"] is True and s["calibration"]["rms_mm"] > 6.0
    assert s["phase"] == "calibrating" and s["touched"] == [] and "refused" in s["status"]


def test_a_short_study_with_ratings_writes_the_csv(headset, demo_out):
    plan = json.loads((demo_out / "study_plan.json").read_text())
    pg = headset("?trials=3")
    store_calibration(pg)
    pg.check("#study-mode")
    pg.fill("#participant", "P07")
    pg.click("#enter-vr")
    ratings = [5, 2, 7]
    for k, rating in enumerate(ratings):
        pg.wait_for_function(f"pinchmatchXR.state().trial === {k} && pinchmatchXR.state().phase "
                             "=== 'guiding'",
                             timeout=8000)
        pinch_off_target(pg)
        move_on(pg)
        wait_phase(pg, "rating")
        button = next(b for b in pg.evaluate("pinchmatchXR.buttons()") if b["value"] == rating)
        pg.evaluate("([q]) => drive.touch('right', q)", [button["position"]])
        pg.wait_for_function(f"pinchmatchXR.state().results.length === {k + 1}", timeout=4000)
    wait_phase(pg, "done")
    # the session ends by itself
    pg.wait_for_function("document.body.dataset.xr === 'ready'", timeout=8000)
    with pg.expect_download() as download:
        pg.click("#download-csv")
    text = Path(download.value.path()).read_text()
    assert download.value.suggested_filename == "pinchmatch-study-P07.csv"
    rows = list(csv.DictReader(io.StringIO(text)))
    assert [int(r["rating"]) for r in rows] == ratings
    for r, trial in zip(rows, plan["trials"][:3]):
        pair = plan["pairs"][trial["pair"]]
        assert (int(r["trial"]), r["object"], r["pose_source"], r["participant"]) == \
            (trial["trial"], pair["virtual"], pair["pose_source"], "P07")
        assert float(r["time_to_validation_s"]) >= 1.0
        assert float(r["thumb_error_mm"]) <= 5.0 and float(r["index_error_mm"]) <= 5.0
        assert float(r["angle_error_deg"]) <= 14.0
        for c, v in pair["criteria_jnd"].items():
            assert float(r[f"{c}_jnd"]) == pytest.approx(v, abs=1e-4)
    # the table pinchmatch calibrate reads, pairs grouped by object and placement
    table = read_ratings(text, "study.csv")
    assert (table.criteria == CRITERIA and table.rating.tolist() == ratings
            and table.jnd.shape == (3, 8))


def test_the_dynamic_task_waits_for_the_lift_before_the_rating(headset):
    pg = headset("?trials=1")
    store_calibration(pg)
    pg.check("#study-mode")
    pg.check("#lift")
    pg.click("#enter-vr")
    wait_phase(pg, "guiding")
    pinch_off_target(pg)
    move_on(pg)
    wait_phase(pg, "lifting")
    pg.evaluate("drive.shift('right', [0, 0.05, 0])")  # not high enough
    pg.evaluate("drive.shift('right', [0, -0.05, 0])")
    pg.wait_for_timeout(300)
    assert state(pg)["phase"] == "lifting"
    pg.evaluate("drive.shift('right', [0, 0.1, 0])")  # lifted 10 cm and put back
    pg.evaluate("drive.shift('right', [0, -0.1, 0])")
    wait_phase(pg, "rating", 3000)


def test_a_tripod_is_validated_when_all_three_fingertips_are_on_their_targets(tripod_headset):
    pg = tripod_headset()
    store_calibration(pg)
    pg.click("#enter-vr")
    wait_phase(pg, "guiding")
    targets = np.array(pg.evaluate("pinchmatchXR.targets()"))
    assert targets.shape == (3, 3)
    # the middle fingertip 6 mm off its target, the thumb and the index on theirs: not validated
    side = np.cross(targets[2] - targets[1], [0.0, 1.0, 0.0])
    aim = targets + AWAY
    aim[2] += 0.006 * side / np.linalg.norm(side)
    pg.evaluate("([h, a, b, c]) => drive.tripod(h, a, b, c)", ["right", *aim.tolist()])
    move_on(pg)
    pg.wait_for_timeout(1500)
    s = state(pg)
    assert s["validated"] is False and not s["check"]["ok"], s["check"]
    assert (5.0 < s["check"]["middle_error_mm"] < 7.0 and s["check"]["thumb_error_mm"]
            < 2.0), s["check"]
    # every fingertip on its target: validated after the hold
    pg.evaluate("([d]) => drive.shift('right', d)", [AWAY.tolist()])
    pg.evaluate("([h, a, b, c]) => drive.tripod(h, a, b, c)", ["right", *(targets + AWAY).tolist()])
    move_on(pg)
    pg.wait_for_function("pinchmatchXR.state().validated", timeout=4000)
    v = state(pg)["validation"]
    assert max(v["thumb_error_mm"], v["index_error_mm"], v["middle_error_mm"]) < 2.0, v
