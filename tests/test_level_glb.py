"""OUT/level.glb under --placement fixed: the level an engine loads, with the prop at its pose and
each node's match in its extras; valid glTF by the Khronos validator."""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from conftest import run_cli
from levels import counter_kitchen, standing_can, tabletop_level

NODE = shutil.which("node")
VALIDATE = Path(__file__).parent / "js" / "validate_gltf.cjs"
#: the prop turned 30 degrees about the level's up after standing its file's +Z up, 0.5 m off the
#: origin
TURN = Rotation.from_euler("y", 30, degrees=True) * Rotation.from_euler("x", -90, degrees=True)
POSITION_MM = np.array([500.0, 900.0, -250.0])


@pytest.fixture(scope="module")
def level_out(tmp_path_factory):
    folder = tmp_path_factory.mktemp("level")
    counter_kitchen(folder / "kitchen.glb")
    (folder / "props.toml").write_text(
        '[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, height_mm = '
        '66 }\n'
        f"pose = {{ position_mm = {POSITION_MM.tolist()}, quaternion_xyzw = "
        f"{TURN.as_quat().tolist()} }}\n")
    return folder


def _run(capsys, folder, out, *extra):
    code, _, err = run_cli(capsys, "match", "--tangible", folder / "props.toml", "--virtual",
                           folder / "kitchen.glb", "--split", "nodes", "--skip-nodes", "counter",
                           "--count", 120, "-o", out, "--no-view", "--jobs", 1, *extra)
    assert code == 0, err
    return out


def _document(path: Path) -> dict:
    data = path.read_bytes()
    length, = struct.unpack_from("<I", data, 12)
    assert (data[:4] == b"glTF" and struct.unpack_from("<I", data, 8)[0] == len(data)
            and length % 4 == 0)
    return json.loads(data[20:20 + length])


def test_the_level_carries_the_prop_at_its_pose_and_each_node_s_match(level_out, tmp_path, capsys):
    out = _run(capsys, level_out, tmp_path / "out", "--placement", "fixed", "--carousel-margin-jnd",
               "3")
    matches = {m["virtual"]: m for m in json.loads((out / "matches.json").read_text())["matches"]}
    doc = _document(out / "level.glb")
    nodes = {n["name"]: n for n in doc["nodes"]}
    assert {"counter", "can_near", "box_near", "can_far", "pinchmatch_prop_can_prop"} <= set(nodes)
    assert "extras" not in nodes["counter"]  # skipped: the level keeps it, unmatched
    assert doc["scenes"][0]["extras"]["pinchmatch"]["schema"] == "pinchmatch.level/2"
    R = TURN.as_matrix()
    for name, m in matches.items():
        x = nodes[name]["extras"]["pinchmatch"]
        r = m["redirection"]
        assert x["mode"] == r["mode"] and x["prop"] == "can_prop" and x["cost"] == m["cost"]
        assert x["redirect_cost"] == r["redirect_cost"] and x["carousel_cost"] == r["carousel_cost"]
        v = np.array([m["virtual_pose"]["p1_mm"], m["virtual_pose"]["p2_mm"]]) / 1000.0
        np.testing.assert_allclose(np.reshape(x["virtual_contacts_m"], (2, 3)), v, atol=2e-6)
        t = np.array([m["tangible_pose"]["p1_mm"], m["tangible_pose"]["p2_mm"]])
        np.testing.assert_allclose(np.reshape(x["physical_contacts_m"], (2, 3)),
                                   (t @ R.T + POSITION_MM) / 1000.0, atol=2e-6)
        np.testing.assert_allclose(x["hand_start_m"], np.array(r["hand_start_mm"]) / 1000.0,
                                   atol=2e-6)
    assert {x["extras"]["pinchmatch"]["mode"] for n, x in nodes.items()
            if n in matches} == {"redirect", "carousel"}
    # the prop's mesh where its pose puts it: standing on the counter (y = 0.9 m), centred on its
    # position
    scene = trimesh.load(out / "level.glb", force="scene")
    prop = scene.dump(concatenate=False)
    placed = next(g for g in prop if g.metadata.get("name", "").startswith("pinchmatch_prop") or
                  (g.metadata.get("pinchmatch") or {}).get("role") == "prop")
    low, high = placed.bounds
    assert low[1] == pytest.approx(0.9, abs=1e-6) and high[1] == pytest.approx(0.966, abs=1e-6)
    np.testing.assert_allclose((low + high)[[0, 2]] / 2, POSITION_MM[[0, 2]] / 1000.0, atol=1e-3)


def _world(doc: dict) -> dict:
    """{node index: its world matrix} composed here from the file's nodes (TRS or matrix), root
    down."""
    from levels import _trs

    def local(node):
        return (np.array(node["matrix"], dtype=float).reshape(4, 4).T if "matrix" in node
                else _trs(node))

    out = {}

    def walk(i, parent):
        out[i] = parent @ local(doc["nodes"][i])
        for c in doc["nodes"][i].get("children", []):
            walk(c, out[i])

    for root in doc["scenes"][0]["nodes"]:
        walk(root, np.eye(4))
    return out


def test_a_carousel_object_parented_to_its_tracked_prop_rests_on_the_table(
    level_out, tmp_path, capsys):
    """Every carousel object is a node below its prop's node; placed by that local transform under
    the prop where the pose puts it, and again under the prop moved and turned elsewhere (as a
    tracker moves it), its mesh rests on the prop's table (within 2 mm below, 10 mm above); its
    fingertip joints are the pads of matches.json's contacts, named as OpenXR's joints; masses under
    OMI_physics_body."""
    out = _run(capsys, level_out, tmp_path / "out", "--placement", "fixed", "--max-redirect-deg",
               "0.5")
    matches = {m["virtual"]: m for m in json.loads((out / "matches.json").read_text())["matches"]}
    doc = _document(out / "level.glb")
    world = _world(doc)
    index = {n["name"]: i for i, n in enumerate(doc["nodes"])}
    prop = index["pinchmatch_prop_can_prop"]
    np.testing.assert_allclose(world[prop][:3, :3], TURN.as_matrix(), atol=1e-6)
    np.testing.assert_allclose(world[prop][:3, 3], POSITION_MM / 1000.0, atol=1e-6)
    assert "OMI_physics_body" in doc["extensionsUsed"]
    assert "motion" in doc["nodes"][prop]["extensions"]["OMI_physics_body"]
    table = 0.9
    tracked = np.eye(4)
    tracked[:3, :3] = Rotation.from_euler("y", -70, degrees=True).as_matrix() @ TURN.as_matrix()
    tracked[:3, 3] = [-1.2, world[prop][1, 3] + 0.3, 2.0]  # elsewhere, on a table 0.3 m higher
    carousels = [n for n in doc["nodes"] if n["name"].startswith("carousel_")]
    assert {n["name"] for n in carousels} == {f"carousel_{name}" for name, m in matches.items()
                                              if m["redirection"]["mode"]
                                              == "carousel"} and carousels
    scene = trimesh.load(out / "level.glb", force="scene")
    for node in carousels:
        i = index[node["name"]]
        assert i in doc["nodes"][prop]["children"]
        name = node["extras"]["pinchmatch"]["node"]
        mesh = scene.geometry[scene.graph[name][1]]  # the level node's own mesh, in its own frame
        local = np.linalg.inv(world[prop]) @ world[i]
        for place, floor in ((world[prop], table), (tracked, table + 0.3)):
            seen = (place @ local @ np.c_[mesh.vertices, np.ones(len(mesh.vertices))].T).T[:, :3]
            gap_mm = (seen[:, 1].min() - floor) * 1000.0
            assert -2.0 - 1e-3 <= gap_mm <= 10.0, (name, gap_mm)
            assert gap_mm == pytest.approx(matches[name]["rest_gap_mm"], abs=0.05)
        joints = {doc["nodes"][c]["name"]: world[c][:3, 3] for c in node.get("children", [])}
        v = matches[name]["virtual_pose"]
        T = np.array(matches[name]["transform_virtual_to_tangible"])
        for joint, p, n in (("thumb_tip", v["p1_mm"], v["n1"]), ("index_tip", v["p2_mm"], v["n2"])):
            # the seen pad, registered onto the prop, into the level
            pad = np.array(p) + 8.0 * np.array(n)
            expected = world[prop] @ np.r_[(T[:3, :3] @ pad + T[:3, 3]) / 1000.0, 1.0]
            np.testing.assert_allclose(joints[joint], expected[:3], atol=2e-6)
        assert {"pinch_center", "wrist"} <= set(joints)
        wrist = np.linalg.norm(joints["wrist"] - joints["pinch_center"]) * 1000.0
        assert wrist == pytest.approx(110.0, abs=1e-3)


def test_no_level_is_written_under_the_registered_placement(level_out, tmp_path, capsys):
    out = _run(capsys, level_out, tmp_path / "out")
    assert not (out / "level.glb").exists()


def test_the_level_is_valid_gltf(level_out, tmp_path, capsys):
    if NODE is None or not (VALIDATE.parent / "node_modules" / "gltf-validator").is_dir():
        if os.environ.get("CI"):
            pytest.fail("node or the glTF validator missing; .ci/run installs both")
        pytest.skip("node or tests/js's gltf-validator is not installed (npm ci --prefix tests/js)")
    out = _run(capsys, level_out, tmp_path / "out", "--placement", "fixed")
    proc = subprocess.run([NODE, str(VALIDATE), str(out / "level.glb"),
                           *map(str, sorted((out / "scenes").glob("*.glb")))],
                          capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    reports = [json.loads(line) for line in proc.stdout.splitlines()]
    assert len(reports) >= 2
    for report in reports:
        assert report["errors"] == 0, report


@pytest.fixture(scope="module")
def browser():
    from test_view import chromium

    yield from chromium()


def test_the_desktop_page_says_each_object_s_mode_and_lists_the_failed_node(
    level_out, tmp_path, capsys, browser):
    """The page of a fixed run on a level with a crate no hand can pinch: each entry says redirect
    (with its angle and gain) or carousel, the title says whether the object stays or is brought
    onto the prop, and the failed node is listed with its reason."""
    crate = trimesh.creation.box(extents=(0.4, 0.25, 0.3))
    crate.apply_translation([0.0, 0.125, 0.0])
    folder = tmp_path / "level"
    folder.mkdir()
    (folder / "props.toml").write_text((level_out / "props.toml").read_text())
    tabletop_level(folder / "kitchen.glb", [("can_near", standing_can(), (0.52, 0.9, -0.25)),
                                           ("can_far", standing_can(), (0.9, 0.9, -0.5)),
                                           ("crate", crate, (0.0, 0.9, 0.3))])
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", folder / "props.toml", "--virtual",
                           folder / "kitchen.glb", "--split", "nodes", "--count", 120, "-o", out,
                           "--jobs", 1, "--placement", "fixed", "--carousel-margin-jnd", "3")
    assert code == 3, err  # the crate failed, the others are matched
    matches = {m["virtual"]: m for m in json.loads((out / "matches.json").read_text())["matches"]}
    pg = browser.new_page(viewport={"width": 1400, "height": 900})
    try:
        errors = []
        pg.on("pageerror", lambda e: errors.append(str(e)))
        pg.goto((out / "index.html").as_uri())
        pg.wait_for_selector("body[data-shown='0']", timeout=30_000)
        entries = pg.locator("#matches li.match")
        for k in range(entries.count()):
            text = entries.nth(k).inner_text()
            name = next(n for n in matches if n in text)
            r = matches[name]["redirection"]
            if r["mode"] == "redirect":
                assert f"redirect {r['angle_deg']:.1f}° ×{r['gain']:.2f}" in text
            else:
                assert "carousel" in text
            entries.nth(k).click()
            pg.wait_for_timeout(300)
            title = pg.locator("#main-title").inner_text()
            assert title == (f"{name} stays in the level; the hand is led to can_prop" if r["mode"]
                             == "redirect"
                             else f"{name} brought onto can_prop (carousel)")
        failed = pg.locator("#matches li.failed").inner_text()
        assert "crate" in failed and "wider than the largest pinch" in failed
        assert errors == []
    finally:
        pg.close()


def test_three_js_places_a_carousel_object_on_its_prop_s_table(
    level_out, tmp_path, capsys, browser):
    """The level as three.js's GLTFLoader reads it (the page's own bundle): each carousel node, a
    child of its prop's node, has its mesh resting on the prop's table at y = 0.9 m; moving the
    prop's node (as a tracker does) carries it along, still resting on the prop's table, now 0.3 m
    higher."""
    import base64

    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "match", "--tangible", level_out / "props.toml", "--virtual",
                           level_out / "kitchen.glb", "--split", "nodes", "--count", 120, "-o", out,
                           "--jobs", 1, "--placement", "fixed", "--max-redirect-deg", "0.5",
                           "--no-figures")
    assert code == 0, err
    pg = browser.new_page()
    try:
        pg.goto((out / "index.html").as_uri())
        pg.wait_for_selector("body[data-shown='0']", timeout=30_000)
        lows = pg.evaluate("""async (data) => {
            const { THREE, GLTFLoader } = PM3;
            const bytes = Uint8Array.from(atob(data), (c) => c.charCodeAt(0)).buffer;
            const gltf = await new Promise(
                (ok, fail) => new GLTFLoader().parse(bytes, "", ok, fail));
            const prop = gltf.scene.getObjectByName("pinchmatch_prop_can_prop");
            const lowest = () => {
                gltf.scene.updateMatrixWorld(true);
                const out = {};
                prop.children.filter((c) => c.name.startsWith("carousel_")).forEach((c) => {
                    const box = new THREE.Box3();
                    c.traverse((o) => { if (o.isMesh) box.expandByObject(o, true); });
                    out[c.name] = box.min.y;
                });
                return out;
            };
            const before = lowest();
            prop.position.y += 0.3;
            prop.rotateOnWorldAxis(new THREE.Vector3(0, 1, 0), 1.2);  // turned about the vertical
            return [before, lowest()];
        }""", base64.b64encode((out / "level.glb").read_bytes()).decode())
    finally:
        pg.close()
    before, after = lows
    assert before and set(before) == set(after)
    for name in before:
        assert -0.002 - 1e-6 <= before[name] - 0.9 <= 0.010, (name, before[name])
        assert after[name] - before[name] == pytest.approx(0.3, abs=1e-4)
