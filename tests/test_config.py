"""The one configuration: the command line is generated from its fields, and no field can be left
out of a cache key (a warm run after any change equals a cold run)."""

import dataclasses
import json
import re
from pathlib import Path

import pytest
import trimesh
from scipy.spatial.transform import Rotation

from pinchmatch.cli.parser import build_parser
from pinchmatch.errors import ConfigError
from pinchmatch.cli.runs import config_of_args
from pinchmatch.grasp.pinches import PinchSettings
from pinchmatch.config import Config
from pinchmatch.match.search import MatchSettings
from pinchmatch.options import flag_of, offered

from conftest import run_cli
from levels import standing_can, tabletop_level

#: a value other than the default for every field the command line offers, as the command line
#: writes it
CHANGED = {
    "friction_cone_deg": "24", "min_width_mm": "3", "max_width_mm": "70",
    "fingertip_radius_mm": "9", "patch_radius_mm": "6", "count": "61", "seed": "3",
    "snap_tolerance_mm": "3", "finger_radius_mm": "6.5", "finger_length_mm": "40",
    "approach_tilt_deg": "20", "finger_splay_deg": "5", "grasp": "tripod",
    "weights": "width=3", "criteria": "paper", "normalize": "range", "pooling": "sum", "top_k": "1",
    "scan_trust": None,
    "one_to_one": None, "keep_upright": None, "distinct_mm": "40", "refine": "off",
    "landing_mm": "3", "rank": "nominal", "placement": "fixed", "hand_start_mm": "40,180,260",
    "redirect_threshold_deg": "6", "max_redirect_deg": "9", "axis_threshold_deg": "25",
    "gain_range": "0.9,1.2", "carousel_margin_jnd": "1.5", "rest_sink_mm_per_jnd": "0.5",
    "rest_float_mm_per_jnd": "20", "user_mm": "100,900,-400",
}
#: fields of the records that are no option: they change how the work is split, never a result
INTERNAL = {"block_rows"}
#: the fields that matter only where the virtual objects stay in the level
PLACED = {"hand_start_mm", "redirect_threshold_deg", "max_redirect_deg", "axis_threshold_deg",
          "gain_range", "carousel_margin_jnd"}


def _fields():
    return [(record, f, opt) for record in (PinchSettings,
                                            MatchSettings) for f, opt in offered(record)]


def _argv(name, value):
    f, opt = next((f, opt) for _, f, opt in _fields() if f.name == name)
    return [flag_of(f, opt)] + ([] if value is None else [value])


def test_every_field_is_an_option_or_internal():
    names = {f.name for record in (PinchSettings, MatchSettings)
             for f in dataclasses.fields(record)}
    assert names == {f.name for _, f, _ in _fields()} | INTERNAL
    assert set(CHANGED) == {f.name for _, f, _ in _fields()}


@pytest.mark.parametrize("command", [["match", "--tangible", "a", "--virtual", "b"],
                                     ["select", "--tangible", "a", "--virtual", "b", "-k", "1"],
                                     ["design", "--virtual", "b"], ["demo"]])
def test_the_command_line_with_no_options_is_the_librarys_default(command):
    config = config_of_args(build_parser().parse_args(command))
    assert config == Config() and config.digest() == Config().digest()


@pytest.mark.parametrize("name", sorted(CHANGED))
def test_each_option_sets_its_own_field_and_no_other(name):
    args = build_parser().parse_args(["match", "--tangible", "a", "--virtual", "b",
                                      *_argv(name, CHANGED[name])])
    config = config_of_args(args)
    default = Config()
    changed = {f.name for part in ("pinch", "match")
               for f in dataclasses.fields(getattr(config, part))
               if getattr(getattr(config, part), f.name) != getattr(getattr(default, part), f.name)}
    # the paper's criteria complete the weights with their own (com weighs 1 there)
    assert changed == ({name, "weights"} if name == "criteria" else {name})
    assert config.digest() != default.digest()


def test_the_help_shows_each_default_from_the_record():
    text = build_parser()._subparsers._group_actions[0].choices["match"].format_help()
    assert "(default 30)" in text and "(default 1000)" in text and "(default quick)" in text
    assert "(default on)" in text and "(default registered)" in text


@pytest.fixture(scope="module")
def level(tmp_path_factory):
    """A prop standing off the origin, turned, in a y-up level of two objects (m)."""
    folder = tmp_path_factory.mktemp("level")
    box = trimesh.creation.box(extents=(0.05, 0.04, 0.045))
    box.apply_translation([0.0, 0.0225, 0.0])
    tabletop_level(folder / "level.glb", [("can", standing_can(), (0.14, 0.0, -0.07)),
                                          ("box", box, (0.06, 0.0, -0.11))])
    # the can stands (its z up along the level's y) turned 35 degrees about the level's up; the
    # block lies on its side, its z along the level's x
    stand = Rotation.from_euler("y", 35, degrees=True) * Rotation.from_euler("x", -90, degrees=True)
    lie = Rotation.from_euler("y", 90, degrees=True)
    (folder / "props.toml").write_text(
        '[[object]]\nname = "can_prop"\nshape = { kind = "cylinder", diameter_mm = 54, height_mm = '
        '66 }\n'
        f"pose = {{ position_mm = [120, 0, -80], quaternion_xyzw = {stand.as_quat().tolist()} }}\n"
        '[[object]]\nname = "block"\nshape = { kind = "box", size_mm = [40, 30, 60] }\n'
        f"pose = {{ position_mm = [-60, 20, -40], quaternion_xyzw = {lie.as_quat().tolist()} }}\n")
    return folder


def _run(capsys, level, out, *extra, cache=None):
    argv = ["match", "--tangible", level / "props.toml", "--virtual", level / "level.glb",
            "--split", "nodes", "--count", 60, "--jobs", 1, "-o", out, "--no-view", "-q",
            *(["--cache", cache] if cache else ["--no-cache"]), *extra]
    code, _, err = run_cli(capsys, *argv)
    assert code == 0, err
    return (out / "matches.json").read_bytes()


def test_a_warm_run_after_any_change_equals_a_cold_run(tmp_path, capsys, level):
    """For every field: a run into a cache, then the run with that field changed on the same cache,
    equals the changed run without a cache, byte for byte (and a repeat of it, read back whole)."""
    cache = tmp_path / "cache"
    for k, name in enumerate(sorted(CHANGED)):
        first = ["--placement", "fixed"] if name in PLACED else []
        _run(capsys, level, tmp_path / f"base{k}", *first, cache=cache)
        change = first + _argv(name, CHANGED[name])
        warm = _run(capsys, level, tmp_path / f"warm{k}", *change, cache=cache)
        again = _run(capsys, level, tmp_path / f"again{k}", *change, cache=cache)
        cold = _run(capsys, level, tmp_path / f"cold{k}", *change)
        assert warm == cold, name
        assert again == cold, name
        doc = json.loads(cold)
        assert doc["matches"], name


def _documented(flag: str) -> set:
    """The numbers the README and docs give with ``flag``: "`--flag` (N)", "`--flag N`" (a default,
    or an example), "(default **N°**)"."""
    text = "\n".join(p.read_text() for p in [Path(__file__).parents[1] / "README.md",
                                              *sorted((
                                                  Path(__file__).parents[1]
                                                  / "docs").glob("*.md"))])
    number = r"(-?\d+(?:\.\d+)?)"
    found = set()
    for pattern in (rf"`{re.escape(flag)}`\s*\({number}\)", rf"`{re.escape(flag)} {number}`",
                    rf"{re.escape(flag)}`\s*\(default \*\*{number}"):
        found |= {float(m) for m in re.findall(pattern, text)}
    return found


def test_every_number_a_record_defaults_to_is_the_one_the_documents_give():
    """The record is where defaults live; the README and docs quote them: a changed default must
    change there too."""
    missing = []
    for _, f, opt in _fields():
        if opt.kind not in ("float", "int"):
            continue
        documented = _documented(flag_of(f, opt))
        if not documented:
            missing.append(flag_of(f, opt))
        else:
            assert float(f.default) in documented, (f.name, documented, f.default)
    assert not missing, f"not documented with a default: {missing}"


def test_a_list_of_criteria_is_kept_as_the_tuple_it_names():
    settings = MatchSettings(criteria=["width", "tilt", "normal", "axis", "kmax", "kmin", "mass"])
    assert type(settings.criteria) is tuple and settings == MatchSettings()
    assert Config(match=settings).digest() == Config().digest()


@pytest.mark.parametrize("field, value", [
    ("distinct_mm", -1.0), ("distinct_mm", float("nan")), ("distinct_mm", float("inf")),
    ("distinct_mm", "8"), ("distinct_mm", True), ("top_k", -1), ("top_k", 1.5),
    ("landing_mm", -0.1), ("landing_mm", 20.5), ("normalize", "rank"), ("pooling", "max"),
    ("placement", "here"), ("refine", "on"), ("hand_start_mm", (0.0, 1.0)),
    ("hand_start_mm", (0.0, float("nan"), 1.0)), ("hand_start_mm", (2e5, 0.0, 0.0)),
    ("max_redirect_deg", 0.0), ("redirect_threshold_deg", 91.0), ("axis_threshold_deg", -5.0),
    ("criteria", ("width",)), ("gain_range", (1.1, 1.2)), ("gain_range", (0.9,)),
    ("gain_range", (0.9, float("inf"))), ("gain_range", (0.0, 1.1)), ("carousel_margin_jnd", -0.1),
    ("carousel_margin_jnd", float("nan")),
])
def test_a_match_setting_out_of_bounds_is_refused(field, value):
    from pinchmatch.errors import ConfigError

    with pytest.raises(ConfigError):
        MatchSettings(**{field: value})


@pytest.mark.parametrize("field, value", [
    ("friction_cone_deg", 0.0), ("friction_cone_deg", 90.0), ("min_width_mm", -0.1),
    ("max_width_mm", 0.4), ("max_width_mm", 301.0), ("fingertip_radius_mm", 1.9),
    ("fingertip_radius_mm", 25.1), ("patch_radius_mm", 0.4), ("patch_radius_mm", 50.1),
    ("count", 0), ("count", 100_001), ("count", 10.0), ("count", True), ("seed", -1),
    ("snap_tolerance_mm", 0.0), ("finger_radius_mm", 0.3), ("finger_radius_mm", 8.1),
    ("finger_length_mm", 4.9), ("finger_length_mm", 150.1), ("approach_tilt_deg", -1.0),
    ("approach_tilt_deg", 90.0), ("friction_cone_deg", float("nan")),
])
def test_a_pinch_setting_out_of_bounds_is_refused(field, value):
    from pinchmatch.errors import ConfigError

    with pytest.raises(ConfigError):
        PinchSettings(**{field: value})


@pytest.mark.parametrize("field, value",
                         [("distinct_mm", 0.0), ("top_k", 0), ("landing_mm", 20.0),
                          ("landing_mm", 0.0),
                                          ("max_redirect_deg", 90.0),
                                          ("hand_start_mm", (1e5, -1e5, 0.0)),
                                          ("redirect_threshold_deg", 0.5),
                                          ("axis_threshold_deg", 0.25), ("gain_range", (1.0, 1.0)),
                                          ("carousel_margin_jnd", 0.0)])
def test_a_match_setting_at_its_bound_is_taken(field, value):
    assert getattr(MatchSettings(**{field: value}), field) == value


def test_a_digest_sees_every_number_of_an_array_a_record_holds():
    """Arrays enter a digest by their bytes, not their printed form (which elides the middle of a
    long one)."""
    import numpy as np

    from pinchmatch.options import digest

    @dataclasses.dataclass(frozen=True)
    class Holder:
        values: object
        scale: object = 1.0

    a = np.zeros(5000)
    b = a.copy()
    b[2500] = 1e-9
    assert digest(Holder(a)) != digest(Holder(b))
    assert digest(Holder(a)) == digest(Holder(a.copy()))
    # a numpy number is its value
    assert digest(Holder(a, np.float64(2.0))) == digest(Holder(a, 2.0))
    assert (digest({"m": Holder(a)}) != digest({"m": Holder(b)})
            and digest([Holder(a)]) != digest([Holder(b)]))


def test_a_configuration_is_changed_field_by_field_in_either_part():
    from pinchmatch.errors import ConfigError

    changed = Config().replace(top_k=1, count=300, pooling="sum")
    assert (changed.match.top_k, changed.pinch.count, changed.match.pooling) == (1, 300, "sum")
    assert (changed.pinch == PinchSettings(count=300) and changed.match
            == MatchSettings(top_k=1, pooling="sum"))
    assert Config().replace() == Config()
    with pytest.raises(ConfigError, match="no setting named 'topk'"):
        Config().replace(topk=1)
    for pinch, match in ((MatchSettings(), PinchSettings()), (PinchSettings(), PinchSettings()),
                         (MatchSettings(), MatchSettings())):  # a part in the wrong place, or both
        with pytest.raises(ConfigError):
            Config(pinch, match)


def _numeric_fields(record_type):
    from pinchmatch.options import field_default, offered

    return [(f, opt.kind, field_default(f)) for f, opt in offered(record_type)
            if opt.kind in ("float", "int") and isinstance(field_default(f), (int, float))
            and not isinstance(field_default(f), bool)]


@pytest.mark.parametrize("record_type", ["PinchSettings", "MatchSettings"])
def test_equal_settings_have_equal_digests_and_a_bool_is_not_a_number(record_type):
    """Every numeric option: its default given as an int or as a float makes equal records with
    equal digests; True in its place is refused in one line, as any other non-number is."""
    import dataclasses

    import pinchmatch
    from pinchmatch import Config

    record = getattr(pinchmatch, record_type)
    fields = _numeric_fields(record)
    assert fields
    for f, kind, default in fields:
        if kind == "float" and float(default).is_integer():
            # (a whole-number option takes whole numbers only)
            a, b = record(**{f.name: int(default)}), record(**{f.name: float(default)})
            assert a == b
            configs = [Config(x) if record_type == "PinchSettings" else Config(match=x)
                       for x in (a, b)]
            assert configs[0].digest() == configs[1].digest(), f.name
        with pytest.raises(ConfigError) as refused:
            record(**{f.name: True})
        assert "\n" not in str(refused.value), f.name
    assert dataclasses.fields(record)
