"""The viewer page: ``OUT/index.html``, one self-contained file.

The page is built from what a run wrote, ``OUT/matches.json`` and
``OUT/scenes/*.glb``, so it can be made again at any time with
``pinchmatch view OUT``. Everything is inlined: three.js (a bundle shipped
in ``pinchmatch/viewer``, built by ``tools/build_three_bundle.sh``), the
viewer's script and style, the match data and each scene as base64 GLB.
Nothing is loaded from the network and the page works from ``file://``.
"""

from __future__ import annotations

import base64
import functools
import http.server
import json
import logging
import os
import re
import sys
from importlib import resources
from pathlib import Path

import numpy as np

from ..version import __version__
from ..config import finite_number
from ..errors import ConfigError
from ..files import write_atomic
from .documents import (SCHEMA_MATCHES, cost_unit, matches_from_lines, record_contacts, scene_file,
                        scene_stems)
from .study_plan import SCHEMA_PLAN

log = logging.getLogger(__name__)

ASSETS = ("page.html", "viewer.css", "viewer.js", "three.bundle.min.js")


def _asset(name: str) -> str:
    return (resources.files("pinchmatch") / "viewer" / name).read_text(encoding="utf-8")


def read_matches(out: Path) -> dict:
    """``OUT/matches.json`` (or the document ``OUT/matches.jsonl`` holds), checked: a clear error
    when it is missing or not a matches document."""
    out = Path(out)
    if not out.is_dir():
        raise ConfigError(f"{out}: no such folder; give the -o folder of a 'pinchmatch match' or "
                          "'pinchmatch demo' run")
    path = out / "matches.json"
    lines = out / "matches.jsonl"
    if not path.is_file() and lines.is_file():
        _own_file(lines)
        try:
            with open(lines, encoding="utf-8") as fh:
                return matches_from_lines(fh)
        except (UnicodeDecodeError, ValueError, KeyError, TypeError, AttributeError) as exc:
            raise ConfigError(f"{lines}: not a whole pinchmatch matches stream ({exc}); "
                              "run pinchmatch match again to rewrite it") from None
    if not path.is_file():
        raise ConfigError(f"{path}: not found; run 'pinchmatch match -o {out}' (or 'pinchmatch "
                          f"demo -o {out}') first")
    return _document(path, SCHEMA_MATCHES, "matches document", "run pinchmatch again to rewrite it",
                     "point view at the folder a match or demo run wrote")


def _own_file(path: Path, out: Path | None = None, what: str = "") -> None:
    """Refuse a file of the result folder ``out`` (default: the file's folder) that is a link, or
    lies outside it: a folder received from elsewhere may point anywhere, and the page would carry
    what it points to. ``what`` names the file in the message."""
    out = path.parent if out is None else out
    real = Path(os.path.realpath(path))
    if path.is_symlink() or not real.is_relative_to(os.path.realpath(out)):
        raise ConfigError(f"{path}: {what + ' is ' if what else ''}a link (to {real}); view reads "
                          "only the files "
                          f"inside {out}: copy it there or run pinchmatch again with -o {out}")


def _document(path: Path, schema: str, what: str, rewrite: str, otherwise: str) -> dict:
    """A JSON document pinchmatch wrote, with the schema it must have, or a ConfigError naming the
    file."""
    _own_file(path)
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, RecursionError) as exc:
        # not UTF-8, not JSON, or an integer of thousands of digits
        raise ConfigError(f"{path}: not valid JSON ({str(exc)[:80]}); {rewrite}") from None
    if not isinstance(document, dict) or document.get("schema") != schema:
        raise ConfigError(f"{path}: not a pinchmatch {what} (schema {schema!r} expected); "
                          f"{otherwise}")
    return document


def page_data(out: Path, document: dict) -> dict:
    """What the page shows: one entry per match with its scene as base64 GLB, and the unmatched.

    A document with the right schema but a field missing or of the wrong kind is a ConfigError."""
    try:
        return _page_data(Path(out), document)
    except (KeyError, TypeError, AttributeError, ValueError) as exc:
        what = f"field {exc}" if isinstance(exc, KeyError) else f"a malformed field ({exc})"
        raise ConfigError(f"{Path(out) / 'matches.json'}: {what} is missing or malformed; run "
                          "pinchmatch again to rewrite it") from None


#: the text fields of a match that the page shows; every other leaf it reads must be a number, a
#: bool or null
_TEXT_KEYS = {"virtual", "tangible", "reason", "scene_file", "figure_file", "mode",
              "criteria_noticeable", "node"}


def _checked_values(where: str, value, key: str = "") -> None:
    """Refuse, naming ``where``, a value the page would show that is neither a finite number, a
    bool, null nor text under a text key: a received document may carry markup where numbers
    belong."""
    if isinstance(value, dict):
        for k, v in value.items():
            name = str(k) if str(k).isprintable() else repr(str(k))  # a message stays one line
            _checked_values(f"{where}.{name}", v, str(k))
    elif isinstance(value, list):
        for k, v in enumerate(value):
            _checked_values(f"{where}[{k}]", v, key)
    elif isinstance(value, str):
        if key not in _TEXT_KEYS:
            raise ConfigError(f"{where}: text {value[:40]!r} where a number belongs; not a matches "
                              "document pinchmatch wrote: run pinchmatch again to rewrite it")
    elif not (value is None or isinstance(value, bool) or finite_number(value)):
        raise ConfigError(f"{where}: {value!r} is not a number; run pinchmatch again to rewrite it")


#: the parts of a match the page reads whose leaves are numbers (text only under ``_TEXT_KEYS``)
_CHECKED_FIELDS = ("cost", "p_noticed", "noticeable", "criteria", "landing", "equivalent_tangibles",
                   "flipped", "contact_offset_mm", "position_mm", "quaternion_xyzw", "up_turn_deg",
                   "redirection", "transform_virtual_to_tangible", "rest_gap_mm")
#: of each alternative
_ALTERNATIVE_FIELDS = ("tangible", "cost", "flipped", "up_turn_deg",
                       "transform_virtual_to_tangible")


#: the arrays of a match the page draws, by their shapes (a tripod's contacts: three points)
_SHAPES = {"position_mm": (3,), "quaternion_xyzw": (4,), "transform_virtual_to_tangible": (4, 4)}
_POSE_SHAPES = {"p1_mm": (3,), "p2_mm": (3,), "contacts_mm": (3, 3)}
_REDIRECTION_SHAPES = {"hand_start_mm": (3,), "physical_target_mm": (3,), "virtual_target_mm": (3,)}
#: a page over this size (bytes) is more than a browser opens comfortably: the run says so
PAGE_NOTE_BYTES = 200 * 2**20


def _shaped(where: str, value, shape: tuple) -> None:
    """Refuse, naming ``where``, an array the page draws that is not numbers of ``shape``."""
    try:
        ok = np.shape(np.asarray(value, dtype=np.float64)) == shape
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ConfigError(f"{where}: {str(value)[:40]} is not {' x '.join(map(str, shape))} "
                          "numbers, so the page cannot draw it; run pinchmatch again to rewrite it")


def _drawable(where: str, m: dict, props: dict) -> None:
    """What the page draws of a match has the shapes it draws: poses, transform, placement,
    redirection and its prop's pose in the level."""
    if m.get("tangible") is None:
        return
    for field, shape in _SHAPES.items():
        _shaped(f"{where}.{field}", m.get(field), shape)
    for side in ("tangible_pose", "virtual_pose"):
        pose = m.get(side)
        if not isinstance(pose, dict):
            raise ConfigError(f"{where}.{side}: not a pose; run pinchmatch again to rewrite it")
        for field in _pose_fields(pose)[1:]:
            _shaped(f"{where}.{side}.{field}", pose.get(field), _POSE_SHAPES[field])
    if "redirection" in m and m["redirection"] is not None:
        r = m["redirection"]
        if not isinstance(r, dict) or r.get("mode") not in ("redirect", "carousel") or \
                not finite_number(r.get("angle_deg")) or not finite_number(r.get("gain")):
            raise ConfigError(f"{where}.redirection: not a redirection the page can play (its "
                              "mode, angle_deg and gain); run pinchmatch again to rewrite it")
        for field, shape in _REDIRECTION_SHAPES.items():
            _shaped(f"{where}.redirection.{field}", r.get(field), shape)
        pose = props.get(m["tangible"])
        if pose is not None:
            if not isinstance(pose, dict):
                raise ConfigError(f"{where}: its prop's pose is not a pose; run pinchmatch again "
                                  "to rewrite it")
            _shaped(f"{where}: its prop's pose.position_mm", pose.get("position_mm"), (3,))
            _shaped(f"{where}: its prop's pose.quaternion_xyzw", pose.get("quaternion_xyzw"), (4,))


def _page_data(out: Path, document: dict) -> dict:
    props = {t["name"]: t.get("pose") for t in document["tangibles"]}
    for k, m in enumerate(document["matches"]):
        if not isinstance(m, dict):
            raise ConfigError(f"{out / 'matches.json'}: matches[{k}] is not a match; run "
                              "pinchmatch again to rewrite it")
        _drawable(f"{out / 'matches.json'}: matches[{k}]", m, props)
        for field in _CHECKED_FIELDS:
            _checked_values(f"{out / 'matches.json'}: matches[{k}].{field}", m.get(field), field)
        for side in ("tangible_pose", "virtual_pose"):
            pose = m.get(side) or {}
            for field in _pose_fields(pose):
                _checked_values(f"{out / 'matches.json'}: matches[{k}].{side}.{field}",
                                pose.get(field), field)
        reference = m.get("reference") or {}
        _checked_values(f"{out / 'matches.json'}: matches[{k}].reference.cost",
                        reference.get("cost"), "cost")
        for j, a in enumerate(m.get("alternatives") or []):
            where = f"{out / 'matches.json'}: matches[{k}].alternatives[{j}]"
            for field in _ALTERNATIVE_FIELDS:
                _checked_values(f"{where}.{field}", a.get(field) if isinstance(a, dict) else a,
                                field)
            pose = a.get("tangible_pose") if isinstance(a, dict) else None
            for field in _pose_fields(pose or {})[1:]:
                _checked_values(f"{where}.tangible_pose.{field}", (pose or {}).get(field), field)
    stems = scene_stems([m["virtual"] for m in document["matches"]])
    poses = {t["name"]: t.get("pose") for t in document["tangibles"]}
    ups = {v.get("name"): _up_vector(v.get("up")) for v in document.get("virtuals", [])
           if isinstance(v, dict)}
    matches, unmatched = [], []
    for stem, m in zip(stems, document["matches"]):
        if m.get("tangible") is None:
            unmatched.append({"virtual": m["virtual"], "reason": m.get("reason")})
            continue
        name = m.get("scene_file") or scene_file(stem)  # documents that name no scene file: derived
        glb = out / name
        if Path(name).is_absolute() or ".." in Path(name).parts:
            raise ConfigError(f"{out / 'matches.json'}: scene file {name!r} of {m['virtual']} is "
                              f"not inside {out}; run pinchmatch again to rewrite it")
        _own_file(glb, out, f"the scene of {m['virtual']}")
        if not glb.is_file():
            raise ConfigError(f"{glb}: scene missing for {m['virtual']}; run pinchmatch again with "
                              f"-o {out}")
        reference = m.get("reference") or {}
        alternatives = [{
            "tangible": a["tangible"], "cost": a["cost"], "flipped": a["flipped"],
            "up_turn_deg": a.get("up_turn_deg"),
            "transform": [x for row in a["transform_virtual_to_tangible"] for x in row],
            "contacts_mm": record_contacts(a["tangible_pose"]),
        } for a in m.get("alternatives", [])]
        matches.append({
            "virtual": m["virtual"],
            "tangible": m["tangible"],
            "scene_file": Path(name).as_posix(),
            "cost": m["cost"],
            "p_noticed": m.get("p_noticed"),
            "landing": m.get("landing"),
            "noticeable": bool(m.get("noticeable",
                                     any(c["noticeable"] for c in m["criteria"].values()))),
            "flipped": m["flipped"],
            "contact_offset_mm": m["contact_offset_mm"],
            "position_mm": m["position_mm"],
            "quaternion_xyzw": m["quaternion_xyzw"],
            "tangible_width_mm": _width_of(m["tangible_pose"]),
            "virtual_width_mm": _width_of(m["virtual_pose"]),
            "reference_cost": reference.get("cost"),
            "reference_reason": reference.get("reason"),
            "up_turn_deg": m.get("up_turn_deg"),
            "rest_gap_mm": m.get("rest_gap_mm"),
            "virtual_up": ups.get(m["virtual"]),
            "alternatives": alternatives,
            "equivalent_tangibles": m.get("equivalent_tangibles", []),
            "criteria": [{"name": name, **values} for name, values in m["criteria"].items()],
            "glb_base64": base64.b64encode(glb.read_bytes()).decode("ascii"),
        } | _scene_fields(m, poses))
    settings = document.get("settings", {})
    n_t, n_v = len(document["tangibles"]), len(document["virtuals"])
    criteria = settings.get("criteria", [])
    loud = sum(m["noticeable"] for m in matches)
    summary = (f"{len(matches)} of {n_v} virtual objects matched on {n_t} "
               f"tangible{'s' if n_t != 1 else ''} ({loud} with a noticeable difference); "
               f"criteria {', '.join(criteria) if isinstance(criteria, list) else criteria}; "
               f"normalize {settings.get('normalize', 'jnd')}; pooling "
               f"{settings.get('pooling', 'sum')}")
    failed = [{"name": f.get("path", ""), "error": f.get("error", "")}
              for f in document.get("failed", [])]
    return {"version": document.get("version"), "summary": summary, "matches": matches,
            "unmatched": unmatched, "failed": failed,
            "scene": any("redirection" in m for m in matches),
            "study": _study_plan(out, {m["virtual"] for m in matches})}


def _pose_fields(pose: dict) -> tuple:
    """The fields of a pose record the page reads: a pinch's width and contacts, a tripod's aperture
    and contacts."""
    return ("aperture_mm", "contacts_mm") if "contacts_mm" in pose else ("width_mm", "p1_mm",
                                                                         "p2_mm")


def _width_of(pose: dict):
    return pose["aperture_mm"] if "contacts_mm" in pose else pose["width_mm"]


def _up_vector(label) -> list | None:
    """An object's up (``z``, ``-y``, ...) as a unit vector of its file's axes, or None for anything
    else."""
    if not isinstance(label, str) or label.lstrip("-") not in ("x", "y", "z"):
        return None
    vector = [0.0, 0.0, 0.0]
    vector["xyz".index(label.lstrip("-"))] = -1.0 if label.startswith("-") else 1.0
    return vector


def _scene_fields(m: dict, poses: dict) -> dict:
    """Under ``--placement fixed``, what the headset's scene mode needs of a match: its redirection,
    the virtual pinch in the level's frame (mm) and where its prop stands in the level."""
    if m.get("redirection") is None:
        return {}
    contacts = record_contacts(m["virtual_pose"])
    return {"redirection": m["redirection"], "virtual_contacts_mm": contacts,
            "virtual_p1_mm": contacts[0], "virtual_p2_mm": contacts[1],
            "prop_pose": poses.get(m["tangible"])}


def _study_plan(out: Path, matched: set) -> dict | None:
    """``OUT/study_plan.json`` for the headset's study mode, when the run wrote one (``demo``). A
    pair shows its virtual object in that object's match scene, so the pairs of objects without a
    match here are left out with their trials (listed in ``left_out``); no pair left, no study."""
    path = out / "study_plan.json"
    if not path.is_file():
        return None
    plan = _document(path, SCHEMA_PLAN, "study plan", "run pinchmatch demo again to rewrite it",
                     "remove it or run pinchmatch demo again")
    missing = sorted({p["virtual"] for p in plan["pairs"]} - matched)
    if missing:
        log.warning("%s: %s has no match in this folder; its trials are left out of the page's "
                    "study",
                    path, ", ".join(missing))
        kept = [p for p in plan["pairs"] if p["virtual"] in matched]
        index = {p["pair"]: k for k, p in enumerate(kept)}
        trials = [dict(t, pair=index[t["pair"]]) for t in plan["trials"] if t["pair"] in index]
        plan = dict(plan, pairs=[dict(p, pair=index[p["pair"]]) for p in kept], trials=trials,
                    left_out=missing)
    return plan if plan["trials"] else None


#: characters that can end or change a <script> element's text, or a line of JavaScript, as JSON
#: escapes
_SCRIPT_ESCAPES = str.maketrans({"<": "\\u003c", ">": "\\u003e", "&": "\\u0026",
                                 "\u2028": "\\u2028",
                                  "\u2029": "\\u2029"})


def _script_safe_json(data: dict) -> str:
    """JSON that reads the same but cannot end its <script> element early or open a comment
    (``</script>``, ``<!--``), whatever the names in it."""
    text = json.dumps(data, separators=(",", ":"), allow_nan=False)
    return text.translate(_SCRIPT_ESCAPES)


def render_page(data: dict, *, settings: dict | None = None) -> str:
    """The page as one HTML string."""
    cost_note = cost_unit(settings or {})
    values = {
        "VERSION": __version__,
        "TITLE": f"pinchmatch: {len(data['matches'])} matches",
        "CSS": _asset("viewer.css"),
        "COST_NOTE": cost_note,
        "DATA": _script_safe_json(data),
        "THREE": _asset("three.bundle.min.js"),
        "VIEWER": _asset("viewer.js"),
        "XR_CORE": _asset("xr_core.js"),
        "SCENE_XR": _asset("scene_xr.js"),
        "IMMERSIVE": _asset("immersive.js"),
    }
    # one pass, so nothing inserted is read as a placeholder again
    return re.sub(r"\{\{([A-Z_]+)\}\}", lambda m: values[m.group(1)], _asset("page.html"))


def write_page(out: Path, *, document: dict | None = None) -> Path:
    """Write ``OUT/index.html`` from ``OUT/matches.json`` (or the ``document`` a run has just
    written there) and ``OUT/scenes``; return its path."""
    out = Path(out)
    if document is None:
        document = read_matches(out)
    data = page_data(out, document)
    path = out / "index.html"
    page = render_page(data, settings=document.get("settings", {}))
    if len(page) > PAGE_NOTE_BYTES:
        log.warning("%s is %.1f MB (%d matches, each with its scene): more than a browser opens "
                    "comfortably; "
                    "view a part of the result (a run over fewer objects) or open the scenes in "
                    "scenes/ one by one",
                    path, len(page) / 2**20, len(data["matches"]))
    write_atomic(path, page)
    log.info("wrote %s: %d matches", path, len(data["matches"]))
    return path


class _OutHandler(http.server.SimpleHTTPRequestHandler):
    """Serves the files of OUT: only to requests addressed to this server (a Host header naming
    another site is refused, against DNS rebinding), never a folder listing, and never a file
    that a link leads to outside OUT."""

    allowed_hosts: frozenset = frozenset()

    def log_message(self, format, *args):  # noqa: A002 - the base class's name
        log.info("%s %s", self.address_string(), format % args)

    def send_head(self):
        if self.headers.get("Host", "").lower() not in self.allowed_hosts:
            self.send_error(403, "Host not served here")
            return None
        root = Path(self.directory).resolve()
        try:
            path = Path(self.translate_path(self.path))
            inside = path.resolve().is_relative_to(root)
        except (OSError, ValueError):  # ValueError: a NUL byte in the path
            path, inside = root, False
        if not inside or path.resolve().is_dir() and not (path / "index.html").is_file():
            self.send_error(404, "File not found")
            return None
        return super().send_head()

    def list_directory(self, path):
        self.send_error(404, "File not found")
        return None


class _QuietServer(http.server.ThreadingHTTPServer):
    """A client that goes away mid-answer is logged (with --verbose), not printed as a traceback."""

    def handle_error(self, request, client_address):
        if isinstance(sys.exc_info()[1], (ConnectionError, TimeoutError)):
            log.info("%s went away: %s", client_address[0], sys.exc_info()[1])
            return
        super().handle_error(request, client_address)


def make_server(out: Path, *, port: int = 0) -> http.server.ThreadingHTTPServer:
    """An HTTP server for ``OUT`` on 127.0.0.1 only; port 0 takes a free port."""
    handler = type("Handler", (_OutHandler,), {})
    server = _QuietServer(("127.0.0.1", port), functools.partial(handler, directory=str(Path(out))))
    bound = server.server_address[1]
    handler.allowed_hosts = frozenset({f"127.0.0.1:{bound}", f"localhost:{bound}"})
    return server
