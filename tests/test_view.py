"""The viewer page: built from a run's folder, checked in headless Chromium (Debian's package).

The browser tests need playwright (the test extra) and /usr/bin/chromium; .ci/run installs both.
Outside CI they are skipped when either is missing; in CI (CI=true) a missing browser fails.
"""

import io
import json
import os
import shutil
import subprocess
import sys
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

import pinchmatch

from pinchmatch.cli.main import main
from pinchmatch.export.view import page_data, read_matches

CHROMIUM = os.environ.get("PINCHMATCH_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
#: the flags this machine needs: no sandbox as root, no GPU, no background connections to a closed
#: network
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-quic"]
VIEW_BACKGROUND = np.array([0xEE, 0xF1, 0xF5]) / 255.0


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def browser():
    yield from chromium()


def chromium(*needs: tuple):
    """Headless Chromium through playwright, for a module's ``browser`` fixture; ``needs``: more
    (path, how to install it) that the tests need. Outside CI a missing piece skips, in CI it
    fails."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        if os.environ.get("CI"):
            raise
        pytest.skip("playwright is not installed (pip install -e '.[test]')")
    for need, how in ((Path(CHROMIUM), "apt-get install chromium"), *needs):
        if not Path(need).exists():
            if os.environ.get("CI"):
                pytest.fail(f"{need} missing; .ci/run installs it ({how})")
            pytest.skip(f"{need} missing ({how})")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture
def page(browser, demo_out):
    """The demo's index.html opened from file://, with every console message and request
    recorded."""
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    pg = context.new_page()
    pg.messages, pg.requests = [], []
    pg.on("console", lambda m: pg.messages.append((m.type, m.text)))
    pg.on("pageerror", lambda e: pg.messages.append(("pageerror", str(e))))
    pg.on("request", lambda r: pg.requests.append(r.url))
    pg.goto((demo_out / "index.html").as_uri())
    pg.wait_for_selector("body[data-shown='0']", timeout=30_000)
    yield pg
    context.close()


def canvas_pixels(pg, selector):
    """The canvas as it is on screen: (h, w, 3) floats in [0, 1]."""
    return imread(io.BytesIO(pg.locator(selector).screenshot()), format="png")[..., :3]


def drawn_fraction(pixels):
    """Share of pixels that differ from the view's background colour."""
    return float(np.mean(np.abs(pixels - VIEW_BACKGROUND).max(axis=-1) > 0.04))


def test_page_has_one_entry_per_match_and_no_console_errors(page, demo_out):
    doc = json.loads((demo_out / "matches.json").read_text())
    matched = [m for m in doc["matches"] if m["tangible"] is not None]
    entries = page.locator("#matches li.match")
    assert entries.count() == len(matched) == 6
    for k, m in enumerate(matched):
        text = entries.nth(k).inner_text()
        assert m["virtual"] in text and m["tangible"] in text
        loud = [c for c, v in m["criteria"].items() if v["noticeable"]]
        assert all(c in text for c in loud) and (("nothing noticeable" in text)
                                                 == (not loud and not m["noticeable"]))
        assert f"noticed {100 * m['p_noticed']:.0f} %" in text
        landing = m["landing"]  # how it holds when the fingers land off target
        assert ("steady" if not landing["noticeable_worst"] else "noticed" if m["noticeable"]
                else "fragile") in text
    errors = [m for m in page.messages if m[0] in ("error", "pageerror")]
    assert errors == []
    # self-contained: nothing but the file itself (and data: URLs) is requested
    assert all(u.startswith(("file:", "data:", "blob:")) for u in page.requests), page.requests


def test_canvases_are_drawn(page):
    for selector in ("#canvas-main", "#canvas-tangible", "#canvas-virtual"):
        pixels = canvas_pixels(page, selector)
        assert pixels.shape[0] > 100 and pixels.shape[1] > 100
        assert drawn_fraction(pixels) > 0.05, selector


def test_clicking_another_entry_changes_the_view(page):
    before = canvas_pixels(page, "#canvas-main")
    before_virtual = canvas_pixels(page, "#canvas-virtual")
    page.locator("#matches li.match").nth(2).click()
    page.wait_for_selector("body[data-shown='2']", timeout=30_000)
    after = canvas_pixels(page, "#canvas-main")
    assert np.mean(np.abs(after - before).max(axis=-1) > 0.04) > 0.01
    assert np.mean(np.abs(canvas_pixels(page, "#canvas-virtual") - before_virtual).max(axis=-1)
                   > 0.04) > 0.01
    assert "vo3_cube_cylinder_cone.stl" in page.locator("#main-title").inner_text()
    assert page.locator("#matches li.selected").get_attribute("data-index") == "2"
    assert [m for m in page.messages if m[0] in ("error", "pageerror")] == []


def test_virtual_object_can_be_hidden(page):
    shown = canvas_pixels(page, "#canvas-main")
    page.locator("#toggle-virtual").click()
    hidden = canvas_pixels(page, "#canvas-main")
    assert np.mean(np.abs(hidden - shown).max(axis=-1) > 0.04) > 0.005
    page.keyboard.press("v")  # and back; only the checkbox's focus ring may differ
    again = canvas_pixels(page, "#canvas-main")
    assert np.mean(np.abs(again - shown).max(axis=-1) > 0.04) < 0.001


def test_scene_loads_in_three_js_with_the_nodes_and_extras(page, demo_out):
    """three.js's GLTFLoader reads our GLB: node names, the registration matrix and the extras."""
    doc = json.loads((demo_out / "matches.json").read_text())
    info = page.evaluate("""async () => {
        const data = JSON.parse(document.getElementById('pinchmatch-data').textContent);
        const bytes = Uint8Array.from(atob(data.matches[3].glb_base64), c => c.charCodeAt(0));
        const gltf = await new PM3.GLTFLoader().parseAsync(bytes.buffer, '');
        const v = gltf.scene.getObjectByName('virtual');
        const f = gltf.scene.getObjectByName('finger_p1');
        return {names: gltf.scene.children.map(c => c.name), matrix: v.matrix.elements,
                approach: f.userData['pinchmatch:approach'],
                cost: v.userData['pinchmatch:cost'], flipped: v.userData['pinchmatch:flipped'],
                units: gltf.scene.userData['pinchmatch:units']};
    }""")
    m = doc["matches"][3]
    assert sorted(info["names"]) == ["cone_p1", "cone_p2", "finger_p1", "finger_p2", "tangible",
                                     "virtual"]
    np.testing.assert_allclose(info["approach"], m["tangible_pose"]["approach"], atol=1e-6)
    assert info["cost"] == pytest.approx(m["cost"], abs=1e-6) and info["flipped"] == m["flipped"]
    assert info["units"] == "m"
    # the demo's files are z-up: the node matrix is Q R Q^T with Q taking +z to +y, t in metres
    Q = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])
    X = np.array(m["transform_virtual_to_tangible"])
    node = np.array(info["matrix"]).reshape(4, 4).T  # three.js stores column-major
    np.testing.assert_allclose(node[:3, :3], Q @ X[:3, :3] @ Q.T, atol=1e-6)
    np.testing.assert_allclose(node[:3, 3], Q @ X[:3, 3] / 1000.0, atol=1e-7)


def test_page_data_lists_unmatched_objects_apart(demo_out, tmp_path):
    doc = read_matches(demo_out)
    doc["matches"][1] = {"virtual": doc["matches"][1]["virtual"], "tangible": None, "cost": None,
                         "reason": "no tangible left (--one-to-one)"}
    data = page_data(demo_out, doc)
    assert (len(data["matches"]) == 5
            and data["unmatched"][0]["reason"].startswith("no tangible left"))


def test_view_cli_rewrites_the_page(demo_out, tmp_path, capsys):
    out = tmp_path / "run"
    shutil.copytree(demo_out, out)
    (out / "index.html").unlink()
    code, stdout, err = run(capsys, "view", out)
    assert code == 0, err
    assert (out / "index.html").is_file() and f"wrote {out / 'index.html'}" in stdout


def test_view_takes_the_result_document_and_opens_the_page_where_there_is_a_display(
    demo_out, tmp_path, capsys,
                                                                                    monkeypatch):
    import webbrowser

    out = tmp_path / "run"
    shutil.copytree(demo_out, out)
    (out / "index.html").unlink()
    opened = []
    monkeypatch.setattr(webbrowser, "open", lambda url: opened.append(url) or True)
    monkeypatch.setenv("DISPLAY", ":0")
    code, stdout, err = run(capsys, "view", out / "matches.json", "--open")
    assert code == 0, err
    assert (out / "index.html").is_file() and opened == [(out / "index.html").resolve().as_uri()]
    monkeypatch.delenv("DISPLAY")
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    code, stdout, err = run(capsys, "view", out, "--open")
    assert (code == 0 and len(opened) == 1
            and "no display to open a browser on; open file://" in stdout)
    (out / "notes.txt").write_text("mine")
    code, _, err = run(capsys, "view", out / "notes.txt")
    assert code == 2 and "not a result document of pinchmatch" in err and "matches.json" in err


@pytest.mark.parametrize("damage, message", [
    ("no folder", "no such folder"),
    ("no matches", "matches.json: not found; run 'pinchmatch match -o"),
    ("bad json", "matches.json: not valid JSON"),
    ("other schema", "not a pinchmatch matches document"),
    ("no scene", "scene missing for"),
    ("missing field", "field 'cost' is missing or malformed"),
    ("wrong kind", "is missing or malformed"),
    ("markup weight",
     "criteria.width.weight: text '<img src=x onerror=alert(1)>' where a number belongs"),
    ("markup landings",
     "landing.landings: text '<script>alert(1)</script>' where a number belongs"),
    ("markup radius", "landing.radius_mm: text '1<b>' where a number belongs"),
    ("markup alternative", "alternatives[0].cost: text"),
    ("infinite cost", "matches[0].cost: inf is not a number"),
    ("huge integer", "matches.json: not valid JSON"),
    ("scene link", "is a link (to"),
    ("scene folder link", "is a link (to"),
    ("matches link", "matches.json: a link (to"),
    ("plan link", "study_plan.json: a link (to"),
])
def test_view_cli_fails_cleanly(demo_out, tmp_path, capsys, damage, message):
    out = tmp_path / "run"
    if damage != "no folder":
        shutil.copytree(demo_out, out)
        (out / "index.html").unlink()
    if damage == "no matches":
        (out / "matches.json").unlink()
    elif damage == "bad json":
        (out / "matches.json").write_text('{"schema": ')
    elif damage == "other schema":
        (out / "matches.json").write_text('{"schema": "pinchmatch.study/1"}')
    elif damage == "no scene":
        next((out / "scenes").glob("*.glb")).unlink()
    elif damage in ("missing field", "wrong kind"):
        doc = json.loads((out / "matches.json").read_text())
        if damage == "missing field":
            del doc["matches"][0]["cost"]
        else:
            doc["matches"][0]["criteria"] = [1, 2]
        (out / "matches.json").write_text(json.dumps(doc))
    elif damage.startswith(("markup", "infinite")):
        doc = json.loads((out / "matches.json").read_text())
        m = doc["matches"][0]
        markup = "<img src=x onerror=alert(1)>"
        m["criteria"]["width"]["weight"] = markup if damage == "markup weight" else 1.0
        if damage in ("markup landings", "markup radius"):
            m["landing"] = dict(m.get("landing") or {}, landings="<script>alert(1)</script>",
                                radius_mm=5.0)
            if damage == "markup radius":
                m["landing"].update(landings=25, radius_mm="1<b>")
        if damage == "markup alternative":
            m["alternatives"] = [dict(m["alternatives"][0],
                                      cost="<i>")] if m.get("alternatives") else [{"cost": "<i>"}]
        if damage == "infinite cost":
            m["cost"] = float("inf")
        (out / "matches.json").write_text(json.dumps(doc))
    elif damage == "huge integer":
        text = (out / "matches.json").read_text()
        (out / "matches.json").write_text(text.replace(
            '"cost": ', '"cost": ' + "9" * 5000 + ", \"x\": ", 1))
    elif damage in ("matches link", "plan link"):
        name = "matches.json" if damage == "matches link" else "study_plan.json"
        secret = tmp_path / "secret"
        secret.mkdir()
        if (out / name).exists():
            (secret / name).write_bytes((out / name).read_bytes())
            (out / name).unlink()
        else:
            (secret / name).write_text('{"schema": "pinchmatch.study-plan/1", "pairs": []}')
        (out / name).symlink_to(secret / name)
    elif damage in ("scene link", "scene folder link"):
        secret = tmp_path / "secret"
        secret.mkdir()
        scene = next((out / "scenes").glob("*.glb"))
        (secret / scene.name).write_bytes(scene.read_bytes())
        if damage == "scene link":
            scene.unlink()
            scene.symlink_to(secret / scene.name)
        else:
            shutil.rmtree(out / "scenes")
            (out / "scenes").symlink_to(secret, target_is_directory=True)
    code, stdout, err = run(capsys, "view", out)
    assert code == 2 and message in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert not (out / "index.html").exists()


def test_view_serve_binds_loopback_and_serves_the_page(demo_out):
    proc = subprocess.Popen([sys.executable, "-m", "pinchmatch", "view", str(demo_out), "--serve",
                             "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert (line.startswith(f"serving {demo_out} at http://127.0.0.1:")), (
            line, proc.stderr.read())
        url = line.split(" at ")[1].split()[0]
        with urllib.request.urlopen(url, timeout=10) as response:
            body = response.read().decode("utf-8")
        assert response.status == 200 and 'id="pinchmatch-data"' in body
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_names_cannot_end_the_script_element(demo_out, tmp_path):
    """An object named like markup stays text: the page's data element parses back to the names."""
    from pinchmatch.export.view import render_page

    doc = read_matches(demo_out)
    evil = "<!--<script>x</script>&\u2028.stl"
    doc["matches"][0]["virtual"] = evil
    html = render_page(page_data(demo_out, doc))
    start = html.index('id="pinchmatch-data"')
    body = html[html.index(">", start) + 1:html.index("</script>", start)]
    assert "<" not in body and ">" not in body and "&" not in body
    assert json.loads(body)["matches"][0]["virtual"] == evil


def _get(url, host=None):
    request = urllib.request.Request(url, headers={"Host": host} if host else {})
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            return response.status, response.read()
    except urllib.error.HTTPError as exc:
        return exc.code, b""


def test_serve_answers_only_its_own_host_lists_no_folder_and_follows_no_link_out(
    demo_out, tmp_path):
    import threading

    from pinchmatch.export.view import make_server

    out = tmp_path / "run"
    shutil.copytree(demo_out, out)
    secret = tmp_path / "secret.txt"
    secret.write_text("not yours")
    (out / "link.txt").symlink_to(secret)
    (out / "scenes" / "up").symlink_to(tmp_path, target_is_directory=True)
    server = make_server(out)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        port = server.server_address[1]
        base = f"http://127.0.0.1:{port}"
        assert _get(f"{base}/index.html")[0] == 200
        assert _get(f"{base}/index.html", host=f"localhost:{port}")[0] == 200
        assert _get(f"{base}/index.html", host=f"attacker.example:{port}")[0] == 403
        assert _get(f"{base}/index.html", host="127.0.0.1")[0] == 403  # another port
        assert _get(f"{base}/scenes/")[0] == 404
        assert _get(f"{base}/link.txt")[0] == 404
        assert _get(f"{base}/scenes/up/secret.txt")[0] == 404
        assert _get(f"{base}/../secret.txt")[0] == 404
    finally:
        server.shutdown()
        server.server_close()


def test_the_list_filters_sorts_and_counts_and_the_scene_shows_alternatives_and_a_see_through_prop(
        page, demo_out):
    doc = json.loads((demo_out / "matches.json").read_text())
    matched = [m for m in doc["matches"] if m["tangible"] is not None]
    loud = sum(any(c["noticeable"] for c in m["criteria"].values()) for m in matched)
    counts = page.locator("#counts").inner_text()
    assert (counts == f"{len(doc['matches'])} of {len(doc['matches'])} shown; {loud} of them with "
                      "a noticeable difference")
    # filter by name: only the entries whose names hold the text
    page.fill("#filter", "vo3")
    visible = page.locator("#matches li:not([hidden]) .names").all_inner_texts()
    assert len(visible) == 1 and "vo3" in visible[0].replace("\u200b", "")
    page.fill("#filter", "")
    # sort by cost: the entries in the order of the documents' costs
    page.select_option("#sort", "cost")
    names = [t.split("→")[0].strip()
             for t in page.locator("#matches li.match .names").all_inner_texts()]
    assert names == [m["virtual"] for m in sorted(matched, key=lambda m: m["cost"])]
    page.select_option("#sort", "-cost")
    names = [t.split("→")[0].strip()
             for t in page.locator("#matches li.match .names").all_inner_texts()]
    assert names == [m["virtual"] for m in sorted(matched, key=lambda m: -m["cost"])]
    # the prop can be made see-through
    page.check("#toggle-prop-transparent")
    page.wait_for_selector("body[data-prop-opacity='0.3']")
    page.keyboard.press("t")
    page.wait_for_selector("body[data-prop-opacity='1']")
    # an alternative moves the virtual object: the main view changes, and back
    page.locator("#matches li.match").first.click()
    page.wait_for_selector("#choices button[data-choice='0']")
    before = canvas_pixels(page, "#canvas-main")
    page.click("#choices button[data-choice='0']")
    page.wait_for_selector("body[data-choice='alternative 1']")
    after = canvas_pixels(page, "#canvas-main")
    assert np.abs(after - before).max(axis=-1).mean() > 0.001
    page.click("#choices button[data-choice='-1']")
    page.wait_for_selector("body[data-choice='best']")
    # how far the object was turned, in words; "flipped" only beyond 90 degrees
    facts = page.locator("#details .facts").inner_text()
    assert "upright" in facts or "turned" in facts
    assert not [m for m in page.messages if m[0] in ("error", "pageerror")], page.messages


def test_long_names_wrap_at_separators_not_mid_word(browser, tmp_path):
    # the page's own breakable(): a name breaks after _ - . / and between a lower-case and a capital
    # letter
    pg = browser.new_page()
    pg.set_content("<div id='n' style='width:60px'></div>")
    script = (Path(pinchmatch.__file__).parent / "viewer" / "viewer.js").read_text()
    body = script[script.index("const escape ="):script.index("const turned =")]
    html = pg.evaluate(f"(() => {{ {body}; return breakable('kitchen_shelf-LeftJar.001/lid'); "
                       f"}})()")
    assert html == "kitchen_<wbr>shelf-<wbr>Left<wbr>Jar.<wbr>001/<wbr>lid"
    pg.close()


def test_the_page_says_how_far_an_object_is_turned_and_why_a_reference_is_missing(
    demo_out, tmp_path):
    out = tmp_path / "run"
    shutil.copytree(demo_out, out)
    doc = json.loads((out / "matches.json").read_text())
    doc["matches"][0]["reference"] = {**doc["matches"][0]["reference"], "cost": None,
                                      "reason": "the paper's p2 meets nothing on the virtual "
                                                "object"}
    (out / "matches.json").write_text(json.dumps(doc))
    data = page_data(out, read_matches(out))
    first = data["matches"][0]
    assert (first["reference_cost"] is None
            and first["reference_reason"].startswith("the paper's p2"))
    turns = {m["virtual"]: m["up_turn_deg"] for m in data["matches"]}
    flips = {m["virtual"]: m["flipped"] for m in data["matches"]}
    assert all((turns[v] > 90.0) == flips[v] for v in turns)  # flipped is a turn beyond 90 degrees


def test_serve_answers_a_nul_byte_and_departing_clients_without_a_traceback(
    demo_out, tmp_path, capsys):
    import socket
    import threading

    from pinchmatch.export.view import make_server

    server = make_server(demo_out)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        port = server.server_address[1]
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            s.sendall(f"GET /index%00.html HTTP/1.0\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
            assert s.recv(64).startswith(b"HTTP/1.0 404")
        for _ in range(40):  # clients that ask for the page and leave before the answer
            s = socket.create_connection(("127.0.0.1", port), timeout=5)
            s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
            s.sendall(f"GET /index.html HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
            s.close()
        assert _get(f"http://127.0.0.1:{port}/index.html")[0] == 200
    finally:
        server.shutdown()
        server.server_close()
    err = capsys.readouterr().err
    assert "Traceback" not in err, err


def test_view_does_not_rewrite_the_page_of_a_folder_a_run_is_writing(demo_out, tmp_path, capsys):
    import fcntl

    out = tmp_path / "run"
    shutil.copytree(demo_out, out)
    page = (out / "index.html").read_bytes()
    fd = os.open(out / ".pinchmatch" / "lock", os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # as a running pinchmatch holds it
        assert main(["view", str(out), "-q"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "a pinchmatch run is writing this folder" in err[0], err
        assert (out / "index.html").read_bytes() == page
    finally:
        os.close(fd)
    assert main(["view", str(out), "-q"]) == 0


def test_a_tripod_demo_shows_three_cones_per_grasp_and_its_alternatives(browser, tripod_demo_out):
    """``demo --grasp tripod``: every scene has a cone and a finger per fingertip, the page draws
    them in the three views, and an alternative's three cones replace the best's."""
    doc = json.loads((tripod_demo_out / "matches.json").read_text())
    assert doc["grasp"] == "tripod"
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    pg = context.new_page()
    errors = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    pg.goto((tripod_demo_out / "index.html").as_uri())
    pg.wait_for_selector("body[data-shown='0']", timeout=30_000)
    info = pg.evaluate("""async () => {
        const data = JSON.parse(document.getElementById('pinchmatch-data').textContent);
        const bytes = Uint8Array.from(atob(data.matches[1].glb_base64), c => c.charCodeAt(0));
        const gltf = await new PM3.GLTFLoader().parseAsync(bytes.buffer, '');
        const cones = ['cone_p1', 'cone_p2', 'cone_p3'].map(
            n => gltf.scene.getObjectByName(n).userData['pinchmatch:contact_mm']);
        return {names: gltf.scene.children.map(c => c.name), cones,
                virtual: gltf.scene.getObjectByName('virtual')
                    .userData['pinchmatch:virtual_contacts_mm']};
    }""")
    assert sorted(info["names"]) == ["cone_p1", "cone_p2", "cone_p3", "finger_p1", "finger_p2",
                                     "finger_p3", "tangible", "virtual"]
    m = doc["matches"][1]
    np.testing.assert_allclose(info["cones"], m["tangible_pose"]["contacts_mm"], atol=1e-3)
    assert len(info["virtual"]) == 9
    for selector in ("#canvas-main", "#canvas-tangible", "#canvas-virtual"):
        assert drawn_fraction(canvas_pixels(pg, selector)) > 0.01, selector
    pg.locator("#matches li.match").nth(1).click()
    pg.wait_for_selector("#choices button[data-choice='0']")
    pg.click("#choices button[data-choice='0']")
    pg.wait_for_selector("body[data-choice='alternative 1']")
    assert errors == [], errors
    context.close()


@pytest.mark.parametrize("virtual_up", ["y", "z"])
def test_the_virtual_pose_view_stands_each_object_on_its_own_up(
    browser, tmp_path, capsys, virtual_up):
    """A tall bottle, as a y-up GLB (metres) and as a z-up STL (mm), matched on a z-up box prop: in
    the virtual pose view it stands upright (its longest side along the view's vertical), and its
    rest on the prop is said."""
    import trimesh

    # mm, its axis along z
    bottle = trimesh.creation.cylinder(radius=30.0, height=180.0, sections=32)
    if virtual_up == "y":
        # axis along y
        bottle.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
        bottle.apply_scale(0.001)
        bottle.export(tmp_path / "bottle.glb")
        virtual = tmp_path / "bottle.glb"
    else:
        bottle.export(tmp_path / "bottle.stl")
        virtual = tmp_path / "bottle.stl"
    trimesh.creation.box(extents=(60.0, 60.0, 120.0)).export(tmp_path / "prop.stl")
    out = tmp_path / "out"
    code, _, err = run(capsys, "match", "--tangible", tmp_path / "prop.stl", "--virtual", virtual,
                       "--count", 150, "--no-figures", "--no-cache", "--jobs", 1, "-o", out)
    assert code == 0, err
    pg = browser.new_page(viewport={"width": 1400, "height": 900})
    pg.goto((out / "index.html").as_uri())
    pg.wait_for_selector("body[data-shown='0']", timeout=30_000)
    size = pg.evaluate("""(() => {
        const { THREE } = PM3;
        const own = window.pinchmatchViewer.views.virtual.content.children[0];
        own.updateMatrixWorld(true);
        const s = new THREE.Box3().setFromObject(own).getSize(new THREE.Vector3());
        return [s.x, s.y, s.z];
    })()""")
    assert size[1] > 2.5 * max(size[0], size[2]), size  # 180 mm tall, 60 mm across
    assert "table" in pg.inner_text("#details")
    pg.close()
