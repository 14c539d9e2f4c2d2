"""The Unity package (unity/com.pinchmatch.unity): its C# built with Mono and its NUnit tests run
(unity/build.sh), and its core's answers against the Python's.

Parity: the console entry (the core, under Mono) places the demo's matches (pinch and tripod) and a
level's (``--placement fixed``: redirected and carousel objects) on props tracked at poses turned
about two axes, off the origin. Each placement and target is worked out here from what the Python
wrote (matches.json, the match scenes' matrices, the props' poses, level.glb's nodes), mirrored
to Unity's frame by this file's own S = diag(-1, 1, 1), never by the core's conversion; the warp
along a hand path is the page's own (xr_core.js, run in node).

Needs Mono (Debian's mono-mcs, mono-runtime, nunit-console; .ci/run installs them) and node for the
warp; outside CI each is skipped when missing.
"""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "unity" / "com.pinchmatch.unity"
S = np.diag([-1.0, 1.0, 1.0])
TOL_M, TOL_RAD = 1e-6, 1e-6


def _need(tool: str, install: str):
    if shutil.which(tool) is None:
        if os.environ.get("CI"):
            pytest.fail(f"{tool} missing; .ci/run installs {install}")
        pytest.skip(f"{tool} is not installed ({install})")


@pytest.fixture(scope="module")
def build(tmp_path_factory) -> Path:
    """The package built and its C# tests run (unity/build.sh): the folder of the binaries."""
    _need("mcs", "Debian's mono-mcs")
    _need("nunit-console", "Debian's nunit-console")
    out = tmp_path_factory.mktemp("unity")
    proc = subprocess.run(["bash", str(ROOT / "unity" / "build.sh"), str(out)],
                          capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-4000:]
    return out


def _console(build: Path, *args) -> dict:
    proc = subprocess.run(["mono", str(build / "pinchmatch-unity.exe"), *map(str, args)],
                          capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def _tracked(seed: int) -> tuple[np.ndarray, str]:
    """A prop's tracked pose in Unity (a 4x4), turned about two axes and off the origin, and the
    console's argument for it."""
    rng = np.random.default_rng(seed)
    turn = Rotation.from_euler("yx", rng.uniform(-170, 170, 2), degrees=True)
    at = rng.uniform(-1.5, 1.5, 3)
    P = np.eye(4)
    P[:3, :3], P[:3, 3] = turn.as_matrix(), at
    return P, ",".join(repr(float(x)) for x in [*at, *turn.as_quat()])


def _h(p) -> np.ndarray:
    return np.append(np.asarray(p, dtype=float), 1.0)


def _pose_close(M: np.ndarray, pose: dict):
    """The console's pose (position, rotation_xyzw) against a rigid 4x4."""
    np.testing.assert_allclose(pose["position"], M[:3, 3], atol=TOL_M, rtol=0)
    R = Rotation.from_matrix(M[:3, :3])
    angle = (R.inv() * Rotation.from_quat(pose["rotation_xyzw"])).magnitude()
    assert angle <= TOL_RAD, angle


def _glb(path: Path) -> dict:
    data = path.read_bytes()
    (length,) = struct.unpack_from("<I", data, 12)
    return json.loads(data[20:20 + length])


def _node_matrix(node: dict) -> np.ndarray:
    """A glTF node's local 4x4: its matrix, or its translation, rotation and scale."""
    if "matrix" in node:
        return np.array(node["matrix"], dtype=float).reshape(4, 4).T
    M = np.eye(4)
    M[:3, :3] = Rotation.from_quat(node.get("rotation", [0, 0, 0, 1])).as_matrix() * node.get(
        "scale", [1.0, 1.0, 1.0])
    M[:3, 3] = node.get("translation", [0.0, 0.0, 0.0])
    return M


def _mirrored(M: np.ndarray) -> np.ndarray:
    """A 4x4 of glTF's frame (mm or m) written in Unity's: S M S."""
    S4 = np.diag([-1.0, 1.0, 1.0, 1.0])
    return S4 @ M @ S4


def test_the_package_builds_and_its_csharp_tests_pass(build):
    """unity/build.sh built every assembly (the components against the stubs) and the NUnit run
    passed at least 50 tests (the XML report, read here)."""
    import xml.etree.ElementTree as ET

    for name in ("Pinchmatch.Core.dll", "Pinchmatch.Unity.dll", "pinchmatch-unity.exe"):
        assert (build / name).is_file()
    report = ET.parse(build / "TestResult.xml").getroot()
    assert int(report.get("failures")) == 0 and int(report.get("errors")) == 0
    assert int(report.get("total")) >= 50


def _demo_parity(build: Path, out: Path):
    doc = json.loads((out / "matches.json").read_text())
    radius = doc["settings"]["fingertip_radius_mm"]
    poses = {t["name"]: _tracked(k + 3) for k, t in enumerate(doc["tangibles"])}
    got = _console(build, out, *[a for name, (_, arg) in poses.items()
                                 for a in ("--prop-pose", f"{name}={arg}")])
    checked = 0
    for m, placed in zip(doc["matches"], got["matches"]):
        assert placed["virtual"] == m["virtual"] and placed["tangible"] == m["tangible"]
        P = poses[m["tangible"]][0]
        scene = _glb(out / m["scene_file"])
        C = np.array(scene["scenes"][0]["extras"]["pinchmatch:file_mm_to_gltf_m"]).reshape(4, 4)
        B = np.diag([-1.0, 1.0, 1.0, 1.0]) @ C  # file mm to Unity m, the scene's bake mirrored
        T = np.array(m["transform_virtual_to_tangible"])
        _pose_close(P @ B @ T @ np.linalg.inv(B), placed["virtual_pose"])
        # the same, from the scene's virtual node as the Python wrote it
        node = next(n for n in scene["nodes"] if n.get("name") == "virtual")
        _pose_close(P @ _mirrored(_node_matrix(node)), placed["virtual_pose"])
        pose = m["tangible_pose"]
        contacts = pose.get("contacts_mm") or [pose["p1_mm"], pose["p2_mm"]]
        normals = pose.get("normals") or [pose["n1"], pose["n2"]]
        names = ["ThumbTip", "IndexTip", "MiddleTip"][:len(contacts)]
        assert list(placed["fingertips"]) == names
        for name, c, n in zip(names, contacts, normals):
            want = (P @ B @ _h(np.array(c) + radius * np.array(n)))[:3]
            np.testing.assert_allclose(placed["fingertips"][name], want, atol=TOL_M, rtol=0)
        checked += 1
    assert checked == len(doc["matches"]) >= 3


def test_the_demos_placements_and_targets_are_the_pythons(build, demo_out):
    _demo_parity(build, demo_out)


def test_the_tripod_demos_placements_and_targets_are_the_pythons(build, tripod_demo_out):
    _demo_parity(build, tripod_demo_out)


@pytest.fixture(scope="module")
def level_out(tmp_path_factory) -> Path:
    """A kitchen with a counter and three objects, a can prop turned and moved onto the counter;
    ``--placement fixed``: two objects redirected, one brought by the carousel."""
    from levels import counter_kitchen
    from pinchmatch.cli.main import main

    folder = tmp_path_factory.mktemp("unity_level")
    counter_kitchen(folder / "kitchen.glb")
    turn = Rotation.from_euler("y", 35, degrees=True) * Rotation.from_euler("x", -90, degrees=True)
    (folder / "props.toml").write_text(
        '[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, '
        'height_mm = 66 }\n'
        f"pose = {{ position_mm = [500, 900, -250], quaternion_xyzw = "
        f"{turn.as_quat().tolist()} }}\n")
    out = folder / "out"
    code = main(["match", "--tangible", str(folder / "props.toml"), "--virtual",
                 str(folder / "kitchen.glb"), "--split", "nodes", "--skip-nodes", "counter",
                 "--placement", "fixed", "--count", "120", "-o", str(out), "--no-view",
                 "--jobs", "1", "-q"])
    assert code == 0
    return out


def _prop_pose_mm(out: Path) -> np.ndarray:
    """The prop's pose in the level (mm), as the run's record of its manifest gives it."""
    doc = _glb(out / "level.glb")
    node = next(n for n in doc["nodes"] if n.get("name") == "pinchmatch_prop_can_prop")
    M = np.eye(4)
    M[:3, :3] = Rotation.from_quat(node["rotation"]).as_matrix()
    M[:3, 3] = np.array(node["translation"]) * 1000.0
    return M


def test_a_levels_placements_and_targets_are_the_pythons(build, level_out):
    """Redirected objects stay where the level has them, their seen fingertips on the level's
    object, the real ones and the warp's physical target on the tracked prop; the carousel's object
    rides on the prop. Each worked out here from matches.json and the prop's level pose."""
    doc = json.loads((level_out / "matches.json").read_text())
    radius = doc["settings"]["fingertip_radius_mm"]
    P, arg = _tracked(11)
    got = {m["virtual"]: m for m in _console(build, level_out, "--prop-pose", arg)["matches"]}
    nodes = {n.get("name"): n for n in _glb(level_out / "level.glb")["nodes"]}
    in_level = _prop_pose_mm(level_out)
    mm_to_m = np.diag([0.001, 0.001, 0.001, 1.0])
    prop_to_unity = P @ np.diag([-1.0, 1.0, 1.0, 1.0]) @ mm_to_m  # the prop node's frame, mirrored
    modes = set()
    for m in doc["matches"]:
        placed, mode = got[m["virtual"]], m["redirection"]["mode"]
        modes.add(mode)
        assert placed["mode"] == mode
        node = nodes[m["virtual"]]
        world = _node_matrix(node)  # the level node's world (it has no parent)
        pose = m["tangible_pose"]
        for name, c, n in zip(("ThumbTip", "IndexTip"), (pose["p1_mm"], pose["p2_mm"]),
                              (pose["n1"], pose["n2"])):
            want = (prop_to_unity @ _h(np.array(c) + radius * np.array(n)))[:3]
            np.testing.assert_allclose(placed["fingertips"][name], want, atol=TOL_M, rtol=0)
        if mode == "carousel":
            T = np.array(m["transform_virtual_to_tangible"])  # world mm to the prop's file mm
            world_mm = np.linalg.inv(mm_to_m) @ world
            _pose_close(prop_to_unity @ T @ world_mm @ np.diag([-1.0, 1.0, 1.0, 1.0]),
                        placed["virtual_pose"])
            assert placed["seen_fingertips"] == placed["fingertips"]
            continue
        _pose_close(_mirrored(world), placed["virtual_pose"])
        v = m["virtual_pose"]
        for name, c, n in zip(("ThumbTip", "IndexTip"), (v["p1_mm"], v["p2_mm"]),
                              (v["n1"], v["n2"])):
            want = S @ (np.array(c) + radius * np.array(n)) / 1000.0
            np.testing.assert_allclose(placed["seen_fingertips"][name], want, atol=TOL_M, rtol=0)
        r = m["redirection"]
        np.testing.assert_allclose(placed["hand_start"], S @ np.array(r["hand_start_mm"]) / 1000,
                                   atol=TOL_M, rtol=0)
        np.testing.assert_allclose(placed["virtual_target"],
                                   S @ np.array(r["virtual_target_mm"]) / 1000, atol=TOL_M, rtol=0)
        in_prop = np.linalg.inv(in_level) @ _h(r["physical_target_mm"])
        np.testing.assert_allclose(placed["physical_target"], (prop_to_unity @ in_prop)[:3],
                                   atol=TOL_M, rtol=0)
    assert modes == {"redirect", "carousel"}


def test_the_warp_along_a_hand_path_is_the_pages(build, level_out, tmp_path):
    """A redirected object, the prop tracked where the level has it: a noisy reach from the hand's
    start to the prop and a little beyond, warped by the page's xr_core.js (node, in the level's
    frame) and by the core (Unity's frame, mirrored here): the same seen fingertips."""
    _need("node", "Debian's nodejs")
    doc = json.loads((level_out / "matches.json").read_text())
    m = next(m for m in doc["matches"] if m["redirection"]["mode"] == "redirect")
    r = m["redirection"]
    start, physical, virtual = (np.array(r[k]) / 1000 for k in
                                ("hand_start_mm", "physical_target_mm", "virtual_target_mm"))
    rng = np.random.default_rng(4)
    along = np.linspace(-0.1, 1.1, 41)[:, None]
    middles = start + along * (physical - start) + rng.normal(0, 0.01, (41, 3))
    grip = np.array([0.02, 0.004, -0.011])
    frames = np.stack([middles - grip, middles + grip], axis=1)  # thumb, index (level, m)
    script = (
        f"const XR = require({json.dumps(str(ROOT / 'src/pinchmatch/viewer/xr_core.js'))});\n"
        f"const frames = {json.dumps(frames.tolist())};\n"
        f"const s = {json.dumps(start.tolist())}, p = {json.dumps(physical.tolist())}, "
        f"v = {json.dumps(virtual.tolist())};\n"
        "const out = frames.map((tips) => {\n"
        "  const mid = [0, 1, 2].map((k) => (tips[0][k] + tips[1][k]) / 2);\n"
        "  const d = XR.warpOffset(s, p, v, mid);\n"
        "  return tips.map((t) => t.map((x, k) => x + d[k]));\n"
        "});\n"
        "console.log(JSON.stringify(out));\n")
    page = json.loads(subprocess.run(["node", "-e", script], capture_output=True, text=True,
                                     check=True, timeout=60).stdout)
    path = tmp_path / "path.json"
    path.write_text(json.dumps({"virtual": m["virtual"],
                                "frames": (frames @ S.T).tolist()}))  # mirrored into Unity's
    in_level = _prop_pose_mm(level_out)
    in_level[:3, 3] /= 1000.0  # the prop tracked where the level has it, in metres
    P = _mirrored(in_level)
    pose = [*P[:3, 3], *Rotation.from_matrix(P[:3, :3]).as_quat()]
    got = _console(build, level_out, "--prop-pose", ",".join(repr(float(x)) for x in pose),
                   "--hand-path", path)["warped"]
    assert got["mode"] == "redirect"
    seen = np.array(got["frames"]) @ S.T  # back into the level's frame
    np.testing.assert_allclose(seen, np.array(page), atol=TOL_M, rtol=0)
    moved = np.linalg.norm(np.array(page) - frames, axis=2)
    assert moved[0].max() == 0 and moved[-1].max() > 0.01  # none at the start, all at the prop


def test_the_console_refuses_bad_input_in_one_line(build, demo_out, tmp_path):
    for args, words in (((tmp_path,), "no matches.json"),
                        ((demo_out, "--prop-pose", "1,2,3"), "X,Y,Z,QX,QY,QZ,QW"),
                        ((demo_out, "--prop-pose", "0,0,0,0,0,0,2"), "length"),
                        ((demo_out,), "no --prop-pose"),
                        ((demo_out, "--frobnicate"), "unknown option")):
        proc = subprocess.run(["mono", str(build / "pinchmatch-unity.exe"), *map(str, args)],
                              capture_output=True, text=True, timeout=60, check=False)
        assert proc.returncode == 2 and proc.stdout == ""
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and words in lines[0] and "Exception" not in lines[0], proc.stderr


#: Unity's package manifest (docs.unity3d.com, "Package manifest"): the fields this package uses
PACKAGE_SCHEMA = {
    "type": "object",
    "required": ["name", "version", "displayName", "description", "unity"],
    "properties": {
        "name": {"type": "string", "pattern": r"^com\.[a-z0-9-]+(\.[a-z0-9-]+)+$",
                 "maxLength": 214},
        "version": {"type": "string", "pattern": r"^\d+\.\d+\.\d+(-[0-9A-Za-z.-]+)?$"},
        "displayName": {"type": "string", "minLength": 1},
        "description": {"type": "string", "minLength": 1},
        "unity": {"type": "string", "pattern": r"^\d{4}\.\d+$"},
        "license": {"type": "string"},
        "keywords": {"type": "array", "items": {"type": "string"}},
        "author": {"type": "object", "required": ["name"]},
        "dependencies": {"type": "object", "additionalProperties": {
            "type": "string", "pattern": r"^\d+\.\d+\.\d+(-[0-9A-Za-z.-]+)?$"}},
        "samples": {"type": "array", "items": {
            "type": "object", "required": ["displayName", "description", "path"],
            "properties": {"path": {"type": "string", "pattern": r"^Samples~/"}}}},
    },
    "additionalProperties": False,
}

#: an assembly definition (docs.unity3d.com, "Assembly Definition file format")
ASMDEF_SCHEMA = {
    "type": "object",
    "required": ["name"],
    "properties": {
        "name": {"type": "string", "pattern": r"^[A-Za-z][A-Za-z0-9_.]*$"},
        "rootNamespace": {"type": "string"},
        "references": {"type": "array", "items": {"type": "string"}},
        "includePlatforms": {"type": "array", "items": {"type": "string"}},
        "excludePlatforms": {"type": "array", "items": {"type": "string"}},
        "allowUnsafeCode": {"type": "boolean"},
        "overrideReferences": {"type": "boolean"},
        "precompiledReferences": {"type": "array", "items": {"type": "string"}},
        "autoReferenced": {"type": "boolean"},
        "defineConstraints": {"type": "array", "items": {"type": "string"}},
        "versionDefines": {"type": "array"},
        "noEngineReferences": {"type": "boolean"},
    },
    "additionalProperties": False,
}


def test_the_manifest_and_assembly_definitions_are_what_unity_reads():
    """package.json and every .asmdef against their schemas; the core references no engine, the
    components need XR Hands (a dependency of the package), the tests are editor-only NUnit, each
    sample's folder exists, and the C# of each folder is in its assembly's namespace."""
    import jsonschema

    manifest = json.loads((PACKAGE / "package.json").read_text())
    jsonschema.validate(manifest, PACKAGE_SCHEMA)
    asmdefs = {p.parent.relative_to(PACKAGE).as_posix(): json.loads(p.read_text())
               for p in PACKAGE.rglob("*.asmdef")}
    for a in asmdefs.values():
        jsonschema.validate(a, ASMDEF_SCHEMA)
    core, components = asmdefs["Runtime/Core"], asmdefs["Runtime/Components"]
    assert core["noEngineReferences"] is True and core["references"] == []
    assert "Unity.XR.Hands" in components["references"]
    assert "com.unity.xr.hands" in manifest["dependencies"]
    tests = asmdefs["Tests/Core"]
    assert tests["includePlatforms"] == ["Editor"]
    assert "nunit.framework.dll" in tests["precompiledReferences"]
    assert "UNITY_INCLUDE_TESTS" in tests["defineConstraints"]
    for sample in manifest["samples"]:
        assert (PACKAGE / sample["path"]).is_dir() and any((PACKAGE / sample["path"]).iterdir())
    for folder, a in asmdefs.items():
        for source in (PACKAGE / folder).glob("*.cs"):
            assert f"namespace {a['rootNamespace']}" in source.read_text(), source
    for name in ("CHANGELOG.md", "LICENSE.md", "Documentation~/index.md",
                 "Documentation~/console.md"):
        assert (PACKAGE / name).is_file(), name


def test_every_asset_unity_imports_has_its_meta_file():
    """A package added by git URL is read-only: Unity ignores an asset without a .meta file. Every
    file and folder Unity imports has one, with a GUID of its own; none is left for a file that is
    gone; the hidden folders (``~``) have none."""
    import re

    sys.path.insert(0, str(ROOT / "tools"))
    from unity_meta import assets, hidden

    seen = {}
    for path in assets(PACKAGE):
        meta = path.with_name(path.name + ".meta")
        assert meta.is_file(), f"{path} has no .meta (python tools/unity_meta.py writes it)"
        text = meta.read_text()
        found = re.search(r"^guid: ([0-9a-f]{32})$", text, re.M)
        assert found and text.startswith("fileFormatVersion: 2\n"), meta
        assert found.group(1) not in seen, (meta, seen.get(found.group(1)))
        seen[found.group(1)] = meta
        assert ("folderAsset: yes" in text) == path.is_dir()
    for meta in PACKAGE.rglob("*.meta"):
        assert not hidden(meta, PACKAGE), meta
        assert meta.with_name(meta.name[:-len(".meta")]).exists(), f"{meta} names nothing"
    assert len(seen) >= 25
