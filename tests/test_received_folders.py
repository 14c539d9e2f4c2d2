"""A result folder received from elsewhere: no record in its control folder ever removes or changes
a file the current run did not write, inside OUT or outside it (``pinchmatch.export.folder``,
``...seal``)."""

import hashlib
import hmac
import json
import os

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from pinchmatch.cli.main import main
from pinchmatch.errors import PinchmatchError
from pinchmatch.export import folder as publish
from pinchmatch.export import seal
from pinchmatch.export.folder import OutputFolder, read_manifest, recover, undo_killed_run
from pinchmatch.export.seal import sealed, unsealed
from pinchmatch.mesh.shapes import ellipsoid

EXAMPLES = int(os.environ.get("PINCHMATCH_FUZZ_EXAMPLES", "0")) or None
FUZZ = settings(max_examples=EXAMPLES or 60, deadline=None, derandomize=EXAMPLES is None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

#: the user's own files: inside OUT (beside a result, in a result's subfolder) and outside it
USER_FILES = ("my_notes.txt", "scenes/mine.glb", "props/keep.stl")


def user_tree(root, *, links=True):
    """OUT with the user's own files in it, a folder outside OUT with a file in it, and links from
    OUT to the outside folder and to the user's file outside (in every place a record may name).
    Returns (out, {path: bytes} of every user file)."""
    out, outside = root / "out", root / "outside"
    outside.mkdir(parents=True)
    (outside / "victim.txt").write_bytes(b"outside: keep me")
    for name in USER_FILES:
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_bytes(f"mine: {name}".encode())
    if links:
        (out / "linked").symlink_to(outside, target_is_directory=True)
        (out / "victim-link.txt").symlink_to(outside / "victim.txt")
    return out, files_of(root)


def files_of(root):
    """{path: bytes} of every regular file under ``root`` outside control folders, links not
    followed."""
    out = {}
    for folder, dirs, names in os.walk(root):
        dirs[:] = [d for d in dirs if d != ".pinchmatch"]
        for n in names:
            p = os.path.join(folder, n)
            if not os.path.islink(p):
                with open(p, "rb") as f:
                    out[os.path.relpath(p, root)] = f.read()
    return out


def foreign(kind, record):
    """``record`` sealed under another user's key (a colleague's folder)."""
    text = json.dumps({"kind": kind, "record": record}, sort_keys=True, separators=(",", ":"))
    return json.dumps({**record,
                       "seal": hmac.new(b"k" * 32, text.encode(), hashlib.sha256).hexdigest()})


@pytest.fixture(scope="module")
def virtuals(tmp_path_factory):
    root = tmp_path_factory.mktemp("v")
    ellipsoid((30.0, 20.0, 15.0), faces=1500, triangulation="random",
              seed=0).mesh.export(root / "e0.stl")
    return root


def test_a_seal_verifies_its_own_record_and_kind_only():
    record = {"files": ["matches.json", "scenes/a.glb"]}
    assert unsealed("manifest", sealed("manifest", record)) == record
    assert unsealed("journal", sealed("manifest", record)) is None  # another kind
    changed = json.loads(sealed("manifest", record))
    changed["files"].append("my_notes.txt")
    assert unsealed("manifest", json.dumps(changed)) is None
    assert unsealed("manifest", json.dumps(record)) is None  # no seal
    assert unsealed("manifest", foreign("manifest", record)) is None  # another user's
    for text in ("", "[]", "{", '{"seal": 3}', '{"seal": "x", "files": NaN}', b"\xff\xfe"):
        assert unsealed("manifest", text) is None


def test_the_key_is_kept_for_the_user_and_drawn_per_process_without_a_home(tmp_path, monkeypatch):
    monkeypatch.setattr(seal, "_KEY", [])
    monkeypatch.setenv("PINCHMATCH_STATE_DIR", str(tmp_path / "state"))
    first = seal.key()
    assert (tmp_path / "state" / "seal.key").read_bytes() == first and len(first) == seal.KEY_BYTES
    assert oct((tmp_path / "state" / "seal.key").stat().st_mode & 0o777) == "0o600"
    monkeypatch.setattr(seal, "_KEY", [])
    assert seal.key() == first  # read back by the next run
    # no place to keep it: one key for the process, the same on every call
    (tmp_path / "ro").mkdir()
    (tmp_path / "ro").chmod(0o500)
    monkeypatch.setattr(seal, "_KEY", [])
    monkeypatch.setenv("PINCHMATCH_STATE_DIR", str(tmp_path / "ro" / "state"))
    try:
        drawn = seal.key()
        assert drawn == seal.key() and len(drawn) == seal.KEY_BYTES
    finally:
        (tmp_path / "ro").chmod(0o700)


@pytest.mark.parametrize("command", ["view", "match"])
def test_a_received_run_record_saying_it_made_the_folder_removes_nothing(
    tmp_path, virtuals, capsys, command):
    """``{"created": true, "undo": []}`` in a received folder: ``view`` and ``match -o`` refuse in
    one line and OUT, with the user's files, stays."""
    # (a folder linked out of OUT is refused by match itself)
    out, before = user_tree(tmp_path, links=False)
    (out / ".pinchmatch").mkdir()
    (out / ".pinchmatch" / "run.json").write_text(json.dumps({"created": True, "undo": []}))
    capsys.readouterr()
    argv = ["view", str(out)] if command == "view" else \
        ["match", "--tangible", str(virtuals / "e0.stl"), "--virtual", str(virtuals / "e0.stl"),
         "--count", "60", "-q", "--jobs", "1", "-o", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "run.json" in err[0] and "delete" in err[0], err
    assert files_of(tmp_path) == before


def test_a_received_journal_removes_no_file_its_manifest_does_not_list(tmp_path, capsys):
    """A received journal removing ``my_notes.txt``: refused. A sealed one (this user's own) whose
    manifest lists only matches.json removes matches.json and leaves ``my_notes.txt``."""
    out, before = user_tree(tmp_path)
    control = out / ".pinchmatch"
    control.mkdir()
    (out / "matches.json").write_text("{}")
    (control / "manifest.json").write_text(json.dumps({"files": ["matches.json"]}))
    (control / "commit.json").write_text(json.dumps({
        "new": [], "staged": [], "remove": ["my_notes.txt"]}))
    assert main(["view", str(out)]) == 2
    assert "commit.json" in capsys.readouterr().err
    assert files_of(tmp_path) == {**before, "out/matches.json": b"{}"}
    (control / "manifest.json").write_text(sealed("manifest", {"files": ["matches.json"]}))
    (control / "commit.json").write_text(sealed("journal", {"new": [], "staged": [],
                                                            "remove": [
                                                                "my_notes.txt", "matches.json"]}))
    publish.finish_commit(out)
    assert files_of(tmp_path) == before and read_manifest(out) == []


def test_a_received_manifest_lists_nothing_the_next_run_deletes(tmp_path, virtuals):
    out, before = user_tree(tmp_path, links=False)
    (out / ".pinchmatch").mkdir()
    (out / ".pinchmatch" / "manifest.json").write_text(json.dumps({"files": list(USER_FILES)}))
    assert read_manifest(out) == []
    (out / ".pinchmatch"
     / "manifest.json").write_text(foreign("manifest", {"files": list(USER_FILES)}))
    assert read_manifest(out) == []
    assert main(["match", "--tangible", str(virtuals / "e0.stl"), "--virtual",
                 str(virtuals / "e0.stl"), "--count", "60", "-q", "--jobs", "1", "--no-view", "-o",
                 str(out)]) == 0
    after = files_of(tmp_path)
    assert {k: v for k, v in after.items() if k in before} == before
    assert ("out/matches.json" in after
            and "out/matches.json" in {f"out/{f}" for f in read_manifest(out)})


@pytest.mark.parametrize("where", ["added", "replaced", "kept"])
def test_a_sealed_run_record_never_reaches_through_a_linked_folder(tmp_path, where):
    """This user's own run record, naming a file behind a folder that is now a link out of OUT (as
    an added file, as a replaced one, or as the file kept aside): taking it back touches nothing
    outside OUT."""
    out, before = user_tree(tmp_path)
    control = out / ".pinchmatch"
    (control / "replaced").mkdir(parents=True)
    (control / "replaced" / "linked").symlink_to(tmp_path / "outside", target_is_directory=True)
    undo = {"added": [["linked/victim.txt", None], ["victim-link.txt", None]],
            "replaced": [["linked/victim.txt", "replaced/x.txt"]],
            "kept": [["my_notes.txt", "replaced/linked/victim.txt"]]}[where]
    (control / "replaced" / "x.txt").write_bytes(b"kept aside")
    (control / "run.json").write_text(sealed("run", {"created": False, "undo": undo}))
    undo_killed_run(out)
    after = files_of(tmp_path)
    assert (after["outside/victim.txt"] == b"outside: keep me" and after["out/my_notes.txt"]
            == b"mine: my_notes.txt")
    assert (out / "linked").is_symlink() and (tmp_path / "outside" / "victim.txt").exists()


def test_a_failed_run_into_a_new_folder_keeps_what_the_user_put_there(tmp_path):
    """A run that made OUT and failed removes OUT, unless the user put a file there while it ran."""
    out = tmp_path / "new"
    with pytest.raises(KeyboardInterrupt):
        with OutputFolder(out):
            raise KeyboardInterrupt
    assert not out.exists()
    with pytest.raises(KeyboardInterrupt):
        with OutputFolder(out):
            (out / "dropped.txt").write_text("mine")
            raise KeyboardInterrupt
    assert (out / "dropped.txt").read_text() == "mine"


names = st.sampled_from(list(USER_FILES)
                        + ["linked/victim.txt", "victim-link.txt", "linked", "scenes",
                           "../outside/victim.txt",
                         str("/tmp/outside/victim.txt"), "matches.json", ".pinchmatch/run.json", "",
                         ".", "props"])
entries = st.lists(st.one_of(st.lists(st.one_of(names, st.none(), st.integers()), max_size=3),
                             names, st.none()),
                   max_size=5)
records = st.fixed_dictionaries({},
                                optional={"created": st.one_of(
                                    st.booleans(), st.none(), st.text(max_size=3)),
                                              "undo": st.one_of(entries, st.integers()),
                                              "new": st.lists(names, max_size=4),
                                              "staged": st.lists(names, max_size=4),
                                              "remove": st.lists(names, max_size=4),
                                              "files": st.lists(names, max_size=4)})


@FUZZ
@given(run=records, journal=records, manifest=records, how=st.sampled_from(["plain", "foreign"]),
       staged=st.lists(names, max_size=3), step=st.sampled_from(["recover", "undo", "run"]))
def test_received_control_folders_never_touch_a_users_file(
    tmp_path_factory, run, journal, manifest, how, staged,
                                                          step):
    """Any run record, journal and manifest (not sealed, or sealed under another user's key), with
    staged and kept-aside files under any name: finishing the folder (``view``'s recovery), taking
    back a killed run, or a new run into it, removes and changes no file the current run did not
    write, inside OUT or outside, and ends in a result or a one-line refusal."""
    root = tmp_path_factory.mktemp("r")
    out, before = user_tree(root)
    control = out / ".pinchmatch"
    control.mkdir()
    for sub in ("staging", "replaced"):
        for name in staged:
            target = control / sub / name
            if (name and ".." not in name and not name.startswith("/")
                and not (control / sub / name).exists()):
                try:
                    target.parent.mkdir(parents=True, exist_ok=True)
                    target.write_bytes(b"received")
                except OSError:
                    pass
    write = json.dumps if how == "plain" else None
    for name, kind, value in (("run.json", "run", run), ("commit.json", "journal", journal),
                              ("manifest.json", "manifest", manifest)):
        if value:
            (control / name).write_text(write(value) if write else foreign(kind, value))
    try:
        if step == "recover":
            recover(out)
        elif step == "undo":
            undo_killed_run(out)
        else:
            with OutputFolder(out) as stage:
                (stage / "matches.json").write_text("{}")
    except PinchmatchError as exc:
        assert "\n" not in str(exc)
    after = files_of(root)
    assert {k: after.get(k) for k in before} == before
    assert set(after) - set(before) <= {"out/matches.json"}


def test_the_key_lives_in_the_users_state_folder(tmp_path, monkeypatch):
    monkeypatch.delenv("PINCHMATCH_STATE_DIR", raising=False)
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "xdg"))
    assert seal.key_path() == tmp_path / "xdg" / "pinchmatch" / "seal.key"
    monkeypatch.delenv("XDG_STATE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert seal.key_path() == tmp_path / "home" / ".local" / "state" / "pinchmatch" / "seal.key"
    (tmp_path / "short.key").write_bytes(b"x" * (seal.KEY_BYTES - 1))  # a cut key file is no key
    assert seal._read_key(tmp_path / "short.key") is None
    (tmp_path / "long.key").write_bytes(b"x" * (seal.KEY_BYTES + 1))
    assert seal._read_key(tmp_path / "long.key") is None
