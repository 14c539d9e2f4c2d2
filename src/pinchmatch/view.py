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
import re
from importlib import resources
from pathlib import Path

from . import __version__
from .errors import ConfigError
from .report import matches_from_lines, SCHEMA_MATCHES, write_atomic
from .scenes import scene_stems

log = logging.getLogger(__name__)

ASSETS = ("page.html", "viewer.css", "viewer.js", "three.bundle.min.js")


def _asset(name: str) -> str:
    return (resources.files("pinchmatch") / "viewer" / name).read_text(encoding="utf-8")


def read_matches(out: Path) -> dict:
    """``OUT/matches.json`` (or the document ``OUT/matches.jsonl`` holds), checked: a clear error when
    it is missing or not a matches document."""
    out = Path(out)
    if not out.is_dir():
        raise ConfigError(f"{out}: no such folder; give the -o folder of a 'pinchmatch match' or 'pinchmatch demo' run")
    path = out / "matches.json"
    lines = out / "matches.jsonl"
    if not path.is_file() and lines.is_file():
        try:
            with open(lines, encoding="utf-8") as fh:
                return matches_from_lines(fh)
        except (UnicodeDecodeError, ValueError, KeyError, TypeError, AttributeError) as exc:
            raise ConfigError(f"{lines}: not a whole pinchmatch matches stream ({exc}); "
                              "run pinchmatch match again to rewrite it") from None
    if not path.is_file():
        raise ConfigError(f"{path}: not found; run 'pinchmatch match -o {out}' (or 'pinchmatch demo -o {out}') first")
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError(f"{path}: not valid JSON ({exc}); run pinchmatch again to rewrite it") from None
    if not isinstance(document, dict) or document.get("schema") != SCHEMA_MATCHES:
        raise ConfigError(f"{path}: not a pinchmatch matches document (schema {SCHEMA_MATCHES!r} expected); "
                          "point view at the folder a match or demo run wrote")
    return document


def page_data(out: Path, document: dict) -> dict:
    """What the page shows: one entry per match with its scene as base64 GLB, and the unmatched."""
    out = Path(out)
    stems = scene_stems([m["virtual"] for m in document["matches"]])
    matches, unmatched = [], []
    for stem, m in zip(stems, document["matches"]):
        if m.get("tangible") is None:
            unmatched.append({"virtual": m["virtual"], "reason": m.get("reason")})
            continue
        glb = out / "scenes" / f"{stem}.glb"
        if not glb.is_file():
            raise ConfigError(f"{glb}: scene missing for {m['virtual']}; run pinchmatch again with -o {out}")
        reference = m.get("reference") or {}
        matches.append({
            "virtual": m["virtual"],
            "tangible": m["tangible"],
            "scene_file": f"scenes/{stem}.glb",
            "cost": m["cost"],
            "flipped": m["flipped"],
            "contact_offset_mm": m["contact_offset_mm"],
            "position_mm": m["position_mm"],
            "quaternion_xyzw": m["quaternion_xyzw"],
            "tangible_width_mm": m["tangible_pose"]["width_mm"],
            "virtual_width_mm": m["virtual_pose"]["width_mm"],
            "reference_cost": reference.get("cost"),
            "criteria": [{"name": name, **values} for name, values in m["criteria"].items()],
            "glb_base64": base64.b64encode(glb.read_bytes()).decode("ascii"),
        })
    settings = document.get("settings", {})
    n_t, n_v = len(document["tangibles"]), len(document["virtuals"])
    criteria = settings.get("criteria", [])
    summary = (f"{len(matches)} of {n_v} virtual objects matched on {n_t} tangible{'s' if n_t != 1 else ''}; "
               f"criteria {', '.join(criteria) if isinstance(criteria, list) else criteria}; "
               f"normalize {settings.get('normalize', 'jnd')}")
    return {"version": document.get("version"), "summary": summary, "matches": matches, "unmatched": unmatched}


def _script_safe_json(data: dict) -> str:
    """JSON that cannot end its <script> element early."""
    return json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")


def render_page(data: dict, *, normalize: str = "jnd") -> str:
    """The page as one HTML string."""
    cost_note = ("squared differences in just-noticeable differences (JND), weighted and summed"
                 if normalize == "jnd" else "differences scaled by the run's ranges, weighted and summed")
    values = {
        "VERSION": __version__,
        "TITLE": f"pinchmatch: {len(data['matches'])} matches",
        "CSS": _asset("viewer.css"),
        "COST_NOTE": cost_note,
        "DATA": _script_safe_json(data),
        "THREE": _asset("three.bundle.min.js"),
        "VIEWER": _asset("viewer.js"),
    }
    # one pass, so nothing inserted is read as a placeholder again
    return re.sub(r"\{\{([A-Z_]+)\}\}", lambda m: values[m.group(1)], _asset("page.html"))


def write_page(out: Path, *, document: dict | None = None) -> Path:
    """Write ``OUT/index.html`` from ``OUT/matches.json`` (or the ``document`` a run has just written
    there) and ``OUT/scenes``; return its path."""
    out = Path(out)
    if document is None:
        document = read_matches(out)
    data = page_data(out, document)
    path = out / "index.html"
    write_atomic(path, render_page(data, normalize=document.get("settings", {}).get("normalize", "jnd")))
    log.info("wrote %s: %d matches", path, len(data["matches"]))
    return path


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format, *args):  # noqa: A002 - the base class's name
        log.info("%s %s", self.address_string(), format % args)


def make_server(out: Path, *, port: int = 0) -> http.server.ThreadingHTTPServer:
    """An HTTP server for ``OUT`` on 127.0.0.1 only; port 0 takes a free port."""
    handler = functools.partial(_QuietHandler, directory=str(Path(out)))
    return http.server.ThreadingHTTPServer(("127.0.0.1", port), handler)
