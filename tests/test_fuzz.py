"""Property-based fuzzing of what users feed the command line: mesh files, poses files, options.

Every input ends with exit 0, or exit 2 and at most three lines on stderr: never a traceback,
never exit 1. The example counts keep CI within a minute or two; for a longer run:

    PINCHMATCH_FUZZ_EXAMPLES=2000 python -m pytest tests/test_fuzz.py
"""

import json
import math
import os

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings, strategies as st

from pinchmatch.grasp.analysis import load_poses_file
from pinchmatch.cli.main import main
from pinchmatch.cli.runs import match_settings_of, pinch_settings_of
from pinchmatch.cli.parser import build_parser, check_option_names
from pinchmatch.errors import ConfigError, PinchmatchError

EXAMPLES = int(os.environ.get("PINCHMATCH_FUZZ_EXAMPLES", "0")) or None
FUZZ = settings(max_examples=EXAMPLES or 25, deadline=None, derandomize=EXAMPLES is None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


def _seeds() -> dict[str, bytes]:
    """A small valid mesh in every format the loader reads."""
    mesh = trimesh.creation.icosphere(subdivisions=1, radius=20.0)
    out = {
        "stl": trimesh.exchange.stl.export_stl(mesh),
        "ascii.stl": trimesh.exchange.stl.export_stl_ascii(mesh).encode(),
        "obj": trimesh.exchange.obj.export_obj(mesh).encode(),
        "ply": trimesh.exchange.ply.export_ply(mesh, encoding="binary"),
        "ascii.ply": trimesh.exchange.ply.export_ply(mesh, encoding="ascii"),
        "off": trimesh.exchange.off.export_off(mesh).encode(),
        "glb": trimesh.exchange.gltf.export_glb(trimesh.Scene(mesh)),
    }
    gltf = trimesh.exchange.gltf.export_gltf(trimesh.Scene(mesh), embed_buffers=True)
    out["gltf"] = gltf["model.gltf"]
    return out


SEEDS = _seeds()


@st.composite
def mutated(draw, seed: bytes):
    data = bytearray(seed)
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["truncate", "flip", "insert", "delete", "splice"]))
        if not data:
            break
        at = draw(st.integers(0, len(data) - 1))
        if kind == "truncate":
            data = data[:at]
        elif kind == "flip":
            data[at] ^= 1 << draw(st.integers(0, 7))
        elif kind == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=16))
        elif kind == "delete":
            del data[at:at + draw(st.integers(1, 64))]
        else:  # a run of digits or a huge number where text numbers are
            data[at:at] = draw(st.sampled_from([b"1e308", b"nan", b"-inf", b"99999999999", b"-0",
                                                b"\n", b" "]))
    return bytes(data)


def assert_contract(code: int, err: str) -> None:
    assert "Traceback" not in err, err
    assert code in (0, 2), (code, err)
    if code == 2:
        assert 1 <= len(err.strip().splitlines()) <= 3, err


@pytest.mark.parametrize("fmt", sorted(SEEDS))
def test_mutated_mesh_files_end_cleanly(fmt, tmp_path, capsys):
    @FUZZ
    @given(mutated(SEEDS[fmt]))
    def check(data):
        path = tmp_path / f"m.{fmt.split('.')[-1]}"
        path.write_bytes(data)
        out = tmp_path / "o.json"
        code = main(["poses", str(path), "--units", "mm", "--count", "5", "-q", "-o", str(out)])
        _, err = capsys.readouterr()
        assert_contract(code, err)
        assert out.exists() == (code == 0)
        out.unlink(missing_ok=True)

    check()


json_values = st.recursive(
    st.none() | st.booleans() | st.floats(allow_nan=True, allow_infinity=True) | st.integers()
    | st.text(max_size=8),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(
        st.sampled_from(["p1_mm", "p2_mm", "poses", "x"]) | st.text(max_size=4), children,
        max_size=4),
    max_leaves=20)


@FUZZ
@given(json_values)
def test_any_json_poses_file_is_read_or_refused_in_one_line(tmp_path_factory, value):
    path = tmp_path_factory.mktemp("poses") / "poses.json"
    path.write_text(json.dumps(value, allow_nan=True))
    try:
        p1, p2 = load_poses_file(path)
    except ConfigError as exc:
        assert "\n" not in str(exc) and str(path) in str(exc)
        return
    assert (p1.shape == p2.shape and p1.shape[1] == 3 and np.isfinite(p1).all()
            and np.isfinite(p2).all())


@FUZZ
@given(st.binary(max_size=300) | st.text(max_size=300).map(str.encode))
def test_any_bytes_as_a_poses_file_are_read_or_refused(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("poses") / "poses.json"
    path.write_bytes(data)
    try:
        load_poses_file(path)
    except ConfigError as exc:
        assert "\n" not in str(exc)


def test_poses_files_through_the_command_line(tmp_path, capsys):
    cases = [b"", b"[", b"[]", b'[{"p1_mm": [1e400, 0, 0], "p2_mm": [0, 0, 1]}]', b"\xff\xfe",
             json.dumps([{"p1_mm": [-20, 0, 20], "p2_mm": [20, 0, 20]}]).encode(), b"[" * 100_000]
    for k, data in enumerate(cases):
        path = tmp_path / f"p{k}.json"
        path.write_bytes(data)
        code = main(["poses", "--example", "--poses", str(path), "-q", "-o",
                     str(tmp_path / f"o{k}.json")])
        _, err = capsys.readouterr()
        assert_contract(code, err)


numbers = (st.floats(allow_nan=True, allow_infinity=True).map(repr)
           | st.integers(-10**12, 10**12).map(str)
           | st.sampled_from(["", "1e999", "-0", "0x10", "1_000", "nan", "inf", " 3", "3 ", "8mm",
                              "1,2"]))
OPTIONS = ["--count", "--seed", "--friction-cone-deg", "--min-width-mm", "--max-width-mm",
           "--fingertip-radius-mm", "--patch-radius-mm", "--finger-radius-mm", "--finger-length-mm",
           "--approach-tilt-deg", "--snap-tolerance-mm", "--top-k", "--distinct-mm"]
weights = st.lists(st.tuples(st.sampled_from(["width", "com", "tilt", "normal", "axis", "kmax",
                                              "kmin", "mass", "widht", "", "x"]),
                             numbers),
                             max_size=5).map(lambda items: ",".join(f"{k}={v}" for k, v in items)) \
    | st.text(max_size=30)


@FUZZ
@given(st.dictionaries(st.sampled_from(OPTIONS), numbers, max_size=4), weights)
def test_numeric_options_and_weights_are_taken_or_refused_in_one_line(values, weight_text):
    argv = ["match", "--tangible", "t.stl", "--virtual", "v.stl", "--weights", weight_text]
    for option, value in values.items():
        argv.append(f"{option}={value}")
    try:
        parser = build_parser()
        check_option_names(parser, argv)
        args = parser.parse_args(argv)
        pinch = pinch_settings_of(args, count=args.count, seed=args.seed)
        match = match_settings_of(args)
    except PinchmatchError as exc:
        assert "\n" not in str(exc)
        return
    assert pinch.count >= 1 and math.isfinite(pinch.fingertip_radius_mm)
    assert any(w > 0 for w in match.weights.values())
