"""The headset's scene mode under IWER: a level around the user, one prop, the hand redirected to it
(body warping) or the object brought by the carousel. As tests/test_headset.py: Chromium, playwright
and ``iwer`` (``npm ci --prefix tests/js``); outside CI skipped when one is missing."""

import json
import math
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
import trimesh
from test_headset import DRIVE, INSTALL, IWER, PROP_POSE, canvas_shot
from test_view import chromium

from conftest import run_cli
from levels import Z_UP_IN_Y_UP, standing_can, tabletop_level

#: the real fingertips move from the hand's start to the physical pinch in this many straight steps
STEPS = 40


@pytest.fixture(scope="module")
def browser():
    yield from chromium((IWER, "npm ci --prefix tests/js"))


@pytest.fixture(scope="module")
def level_out(tmp_path_factory):
    """A kitchen level (a can beside the prop, a can and a box far off) matched with --placement
    fixed and a budget of 15 degrees, a redirection of 15 degrees costing one JND, and the level
    kept intact unless the carousel is 5 JND cheaper: the can beside is redirected, pinched where
    the prop is (its weight hangs as the prop's does), the far ones go to the carousel."""
    folder = tmp_path_factory.mktemp("level")
    box = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    box.apply_translation([0.0, 0.025, 0.0])
    tabletop_level(folder / "kitchen.glb", [("can_near", standing_can(), (0.075, 0.0, 0.0)),
                                           ("can_far", standing_can(), (0.3, 0.0, -0.2)),
                                           ("box_far", box, (-0.3, 0.0, 0.1))])
    (folder / "props.toml").write_text(
        '[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, height_mm = '
        '66 }\n'
        f'pose = {{ position_mm = [0, 0, 0], quaternion_xyzw = {Z_UP_IN_Y_UP} }}\n')
    out = folder / "out"
    from pinchmatch.cli.main import main

    code = main(["match", "--tangible", str(folder / "props.toml"), "--virtual",
                 str(folder / "kitchen.glb"), "--split", "nodes", "--placement", "fixed",
                 "--max-redirect-deg", "15", "--redirect-threshold-deg", "15",
                 "--carousel-margin-jnd", "5", "--count", "200", "--jobs", "1", "-o", str(out)])
    assert code == 0
    return out


@contextmanager
def _in_scene_mode(browser, out: Path, look=None):
    """``out``'s page in the headset's scene mode under IWER, calibrated (PROP_POSE), the view
    turned to ``look`` (eye, target) when given; no page error by the end."""
    context = browser.new_context(viewport={"width": 1200, "height": 800})
    pg = context.new_page()
    errors = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.add_init_script(IWER.read_text() + "\n" + INSTALL)
    pg.goto((out / "index.html").as_uri() + "?mode=scene")
    pg.wait_for_function("window.pinchmatchXR !== undefined && document.body.dataset.shown !== "
                         "undefined")
    pg.add_script_tag(path=str(DRIVE))
    if look is not None:
        pg.evaluate(f"drive.look({list(look[0])}, {list(look[1])})")
    pg.evaluate("localStorage.setItem('pinchmatch.calibration.' + "
                "pinchmatchViewer.DATA.matches[0].tangible, "
                f"JSON.stringify({{refused: false, rms_mm: 0.4, max_mm: 0.6, date: 'test', "
                f"matrix: {json.dumps(PROP_POSE.T.reshape(-1).tolist())}}}))")
    assert pg.eval_on_selector("#scene-mode", "e => e.checked") is True
    pg.click("#enter-vr")
    pg.wait_for_function("pinchmatchXR.scene && pinchmatchXR.scene.state().phase === 'scene'",
                         timeout=15000)
    yield pg
    assert errors == [], errors
    context.close()


@pytest.fixture
def scene_page(browser, level_out):
    with _in_scene_mode(browser, level_out, look=([-0.05, 1.16, -0.08], [0.05, 0.99, -0.38])) as pg:
        yield pg


def scene_state(pg):
    return pg.evaluate("pinchmatchXR.scene.state()")


def task_of(pg, name: str) -> int:
    s = scene_state(pg)
    names = pg.evaluate("pinchmatchViewer.DATA.matches.map((m) => m.virtual)")
    return s["tasks"].index(names.index(name))


def test_the_hand_is_led_from_its_start_to_the_virtual_pinch(scene_page):
    pg = scene_page
    pg.evaluate(f"pinchmatchXR.scene.go({task_of(pg, 'can_near')})")
    t = pg.evaluate("pinchmatchXR.scene.targets()")
    start, (q1, q2), (v1,
                      v2) = np.array(t["start"]), np.array(t["physical"]), np.array(t["virtual"])
    mid = (q1 + q2) / 2
    assert np.linalg.norm((v1 + v2) / 2 - mid) > 0.02  # a redirection worth the name
    # the pinch set up at the start: thumb and index as on the prop, shifted to the hand's start
    pg.evaluate("([h, a, b]) => drive.pinch(h, a, b)",
                ["right", (q1 - mid + start).tolist(), (q2 - mid + start).tolist()])
    rendered, real = [], []
    for k in range(STEPS + 1):
        s = scene_state(pg)
        h = next(i for i, x in enumerate(s["real"]) if x and x["handedness"] == "right")
        real.append(np.array([s["real"][h]["thumb"], s["real"][h]["index"]]))
        rendered.append(np.array([s["rendered"][h]["thumb"], s["rendered"][h]["index"]]))
        if k < STEPS:
            here = real[-1].mean(axis=0)
            target = start + (mid - start) * (k + 1) / STEPS
            pg.evaluate("([h, d]) => drive.shift(h, d)", ["right", (target - here).tolist()])
    offsets = [r - q for r, q in zip(rendered, real)]
    assert np.linalg.norm(offsets[0], axis=1).max() < 0.0005  # at the start: no offset
    jumps = [np.linalg.norm(b - a, axis=1).max() for a, b in zip(offsets, offsets[1:])]
    assert max(jumps) < 0.002, jumps  # no jump over 2 mm between frames
    # at contact: the rendered fingertips on the virtual pinch (in either finger order)
    end = rendered[-1]
    err = min(max(np.linalg.norm(end[0] - v1), np.linalg.norm(end[1] - v2)),
              max(np.linalg.norm(end[0] - v2), np.linalg.norm(end[1] - v1)))
    # the warp moves the hand, it does not turn it: a pinch axis that turns by some angle between
    # the prop and the object leaves each fingertip up to half the width times that angle off
    cos = (q2 - q1) @ (v2 - v1) / np.linalg.norm(q2 - q1) / np.linalg.norm(v2 - v1)
    turn = math.acos(min(1.0, abs(cos)))
    assert (err < 0.001 + np.linalg.norm(real[-1].mean(axis=0) - mid) + 0.5
            * np.linalg.norm(q2 - q1) * turn), err
    pg.wait_for_function("pinchmatchXR.scene.state().validated", timeout=4000)
    canvas_shot(pg, "headset_scene_redirected.png")


def test_the_carousel_brings_each_object_onto_the_prop(scene_page):
    pg = scene_page
    s = scene_state(pg)
    assert len(s["queue"]) == 2
    names = pg.evaluate("pinchmatchViewer.DATA.matches.map((m) => m.virtual)")
    assert {names[i] for i in s["queue"]} == {"can_far", "box_far"}
    button = pg.evaluate("pinchmatchXR.scene.button()")
    away = (np.array(button) + [0.0, 0.12, 0.0]).tolist()
    brought = []
    for turn in range(2):
        pg.evaluate("([q]) => drive.touch('right', q)", [away])
        pg.evaluate("([q]) => drive.touch('right', q)", [button])
        pg.wait_for_function(f"pinchmatchXR.scene.state().carousel_turns === {turn + 1}",
                             timeout=4000)
        i = scene_state(pg)["on_prop"]
        brought.append(i)
        placed = np.array(pg.evaluate(f"pinchmatchXR.scene.objectInRoom({i})")).reshape(4, 4).T
        registered = np.array(pg.evaluate(f"pinchmatchXR.scene.registeredInRoom({i})")).reshape(
            4, 4).T
        assert np.abs(placed - registered).max() < 1e-6  # on the prop, registered
    assert sorted(brought) == sorted(s["queue"])
    canvas_shot(pg, "headset_scene_carousel.png")


@pytest.fixture(scope="module")
def shelf_out(tmp_path_factory):
    """A prop standing off the level's origin, turned about the level's up; the level's own can
    where the prop stands (redirected, in place) and eight boxes far off, 90 mm across (the
    carousel's)."""
    from scipy.spatial.transform import Rotation

    folder = tmp_path_factory.mktemp("shelf")
    turn = Rotation.from_euler("y", 40, degrees=True) * Rotation.from_euler("x", -90, degrees=True)
    places = [("can_here", standing_can(), (0.35, 0.0, -0.2))]
    for k in range(8):
        box = trimesh.creation.box(extents=(0.09, 0.06, 0.09))
        box.apply_translation([0.0, 0.03, 0.0])
        places.append((f"box_{k}", box, (-0.6 + 0.15 * k, 0.0, -0.9)))
    tabletop_level(folder / "kitchen.glb", places)
    (folder / "props.toml").write_text(
        '[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, height_mm = '
        '66 }\n'
        f'pose = {{ position_mm = [350, 0, -200], quaternion_xyzw = {turn.as_quat().tolist()} }}\n')
    out = folder / "out"
    from pinchmatch.cli.main import main

    code = main(["match", "--tangible", str(folder / "props.toml"), "--virtual",
                 str(folder / "kitchen.glb"), "--split", "nodes", "--placement", "fixed", "--count",
                 "120", "--jobs", "1", "-o", str(out)])
    assert code == 0
    return out


def test_the_carousel_holds_its_objects_apart_and_the_level_s_own_object_gives_way(
    browser, shelf_out):
    """Eight boxes wait on the carousel, no two touching; while one of them is on the prop, the
    level's can that stands where the prop stands is hidden and the prompt names the box on the
    prop; the can's own task sends the box back and shows the can."""
    with _in_scene_mode(browser, shelf_out) as pg:
        names = pg.evaluate("pinchmatchViewer.DATA.matches.map((m) => m.virtual)")
        s = scene_state(pg)
        assert sorted(names[i] for i in s["queue"]) == [f"box_{k}" for k in range(8)]
        here = names.index("can_here")
        assert pg.evaluate(f"pinchmatchXR.scene.atProp({here})") is True
        boxes = [np.array(pg.evaluate(f"pinchmatchXR.scene.boxInRoom({i})")) for i in s["queue"]]
        for a in range(len(boxes)):
            for b in range(a + 1, len(boxes)):
                (lo_a, hi_a), (lo_b, hi_b) = boxes[a], boxes[b]
                apart = (hi_a[[0, 2]] < lo_b[[0, 2]]) | (hi_b[[0, 2]] < lo_a[[0, 2]])
                assert apart.any(), (names[s["queue"][a]], names[s["queue"][b]])
        pg.evaluate("pinchmatchXR.scene.turn()")
        s = scene_state(pg)
        assert (s["on_prop"] is not None
                and pg.evaluate(f"pinchmatchXR.scene.visible({here})") is False)
        # the box on the prop, to pinch
        pg.evaluate(f"pinchmatchXR.scene.go({s['tasks'].index(s['on_prop'])})")
        assert (f"On the prop: {names[s['on_prop']]}. Pinch "
                f"{names[s['on_prop']]}" in pg.locator("#xr-status").inner_text())
        at = np.mean(pg.evaluate("pinchmatchXR.scene.targets()")["physical"], axis=0)
        pg.evaluate(f"drive.look({(at + [0.1, 0.35, 0.45]).tolist()}, "
                    f"{(at + [0.15, -0.05, 0.0]).tolist()})")
        pg.wait_for_timeout(300)
        canvas_shot(pg, "headset_scene_shelf.png")
        # a box still on the carousel
        pg.evaluate(f"pinchmatchXR.scene.go({s['tasks'].index(s['queue'][1])})")
        assert f"On the prop: {names[s['on_prop']]}." in pg.locator("#xr-status").inner_text()
        pg.evaluate(f"pinchmatchXR.scene.go({s['tasks'].index(here)})")
        assert (scene_state(pg)["on_prop"] is None
                and pg.evaluate(f"pinchmatchXR.scene.visible({here})") is True)


def test_a_desktop_previews_the_scene_mode(browser, shelf_out):
    """Without a headset, index.html?mode=scene shows the scene mode's level in the main view: the
    can in place, the boxes on the carousel's ring (apart), the first task's prompt in the title,
    naming the prop, and the table the prop stands on under the prop and the ring, the boxes resting
    on it."""
    from test_view import VIEW_BACKGROUND, canvas_pixels, drawn_fraction

    context = browser.new_context(viewport={"width": 1400, "height": 900})
    pg = context.new_page()
    errors = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.goto((shelf_out / "index.html").as_uri() + "?mode=scene")
    pg.wait_for_selector("body[data-preview='scene']", timeout=30_000)
    assert pg.locator("#main-title").inner_text().startswith("scene preview (as the headset shows "
                                                             "it): ")
    s = pg.evaluate("pinchmatchXR.preview.state()")
    assert s["phase"] == "scene" and len(s["queue"]) == 8
    boxes = [np.array(pg.evaluate(f"pinchmatchXR.preview.boxInRoom({i})")) for i in s["queue"]]
    for a in range(len(boxes)):
        for b in range(a + 1, len(boxes)):
            (lo_a, hi_a), (lo_b, hi_b) = boxes[a], boxes[b]
            assert ((hi_a[[0, 2]] < lo_b[[0, 2]]) | (hi_b[[0, 2]] < lo_a[[0, 2]])).any()
    pg.wait_for_timeout(300)
    assert drawn_fraction(canvas_pixels(pg, "#canvas-main")) > 0.01 and VIEW_BACKGROUND is not None
    # the table the prop stands on: its top at the prop's lowest point, under the prop and the whole
    # ring; the boxes brought by the carousel rest on it (each one registered on the prop), and the
    # prompt names the prop
    (low, high) = np.array(pg.evaluate("pinchmatchXR.preview.table()"))
    prop = np.array(pg.evaluate("""(() => {
        const t = pinchmatchViewer.view.scene.getObjectByProperty('name', 'tangible');
        const b = new PM3.THREE.Box3().setFromObject(t);
        return [b.min.toArray(), b.max.toArray()]; })()"""))
    assert high[1] == pytest.approx(prop[0][1], abs=1e-6)
    for lo, hi in [prop, *boxes]:
        assert (low[[0, 2]] <= lo[[0, 2]]).all() and (hi[[0, 2]] <= high[[0, 2]]).all()
    for i in s["queue"]:
        rest = pg.evaluate(f"pinchmatchViewer.DATA.matches[{i}].rest_gap_mm")
        lowest = pg.evaluate(f"pinchmatchXR.preview.boxInRoom({i})")[0][1]
        assert (lowest - high[1] == pytest.approx(rest / 1000.0, abs=2e-4) and -0.002 - 1e-6
                <= rest / 1000.0 <= 0.01)
    assert "can_prop" in pg.locator("#main-title").inner_text()
    assert errors == [], errors
    context.close()
