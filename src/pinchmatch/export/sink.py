"""Writing a run's results as they come: scenes, figures, and ``matches.json`` or
``matches.jsonl``."""

from __future__ import annotations

import json
from pathlib import Path

from ..files import AtomicFile, write_atomic
from ..match.candidates import Candidates
from .documents import (SCHEMA_MATCH_LINES, cost_matrix_section, figure_file, json_number,
                        matches_header, matches_rows, object_entry, scene_file, to_json)


class MatchesSink:
    """Writes a run's results as they come: each scene and criteria figure at once, and either
    ``matches.json`` at the end or ``matches.jsonl`` line by line (docs/output-format.md).

    Every file appears whole (a temporary file, then a rename); a run that stops early leaves no
    result file. The tables for the summary are kept (one short row per object).
    """

    def __init__(self, out: Path, fmt: str, stems: list[str]):
        self.out, self.fmt, self.stems = Path(out), fmt, stems
        self.result_path = self.out / f"matches.{fmt}"
        self.scenes = 0
        self.objects = [("object", "role", "faces", "feasible poses")]
        self._fixed = False
        self.rows = matches_rows({"matches": []})
        self.redirections: list[dict] = []  # under --placement fixed, each match's
        self.references: list[tuple] = []  # (virtual, why its reference has no cost, or None)
        self.equivalents: list[tuple] = []  # (virtual, its prop, [the equivalent props' names])
        # (virtual, its rest gap in mm) where it is shown on a prop that stands
        self.rests: list[tuple] = []
        # (virtual, elevation, azimuth in deg) where its prop stands
        self.approaches: list[tuple] = []
        self._header = None
        self._virtuals, self._matches, self._names, self._cost_rows, self._chosen = ([], [], [], [],
                                                                                     [])
        self._lines = None  # the AtomicFile of matches.jsonl while it is being written

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self._lines is not None:  # stopped before finish: no half-written result
            self._lines.abort()
            self._lines = None

    def _line(self, record: dict) -> None:
        self._lines.write(json.dumps(record, allow_nan=False, separators=(",", ":")) + "\n")

    def start(self, settings: dict, tangibles: list[Candidates], dump_poses: bool) -> None:
        entries = [object_entry(t, dump_poses=dump_poses) for t in tangibles]
        self.objects += [(e["name"], "tangible", e["faces"], e["pose_count"]) for e in entries]
        self._header = matches_header(settings, entries)
        self._fixed = settings.get("placement") == "fixed"
        self.rows = matches_rows({"matches": []}, placed_fixed=self._fixed)
        if self.fmt == "jsonl":
            self._lines = AtomicFile(self.result_path)
            self._line({"record": "header", **self._header, "schema": SCHEMA_MATCH_LINES})

    def add(self, k: int, r) -> None:
        """Write virtual object ``k``'s result ``r`` (a
        :class:`pinchmatch.runner.tasks.VirtualResult`)."""
        stem = self.stems[k]
        if r.scene_glb is not None:
            write_atomic(self.out / scene_file(stem), r.scene_glb)
            r.match.update(scene_file=scene_file(stem), figure_file=None)
            self.scenes += 1
        if r.figure_png is not None:
            write_atomic(self.out / figure_file(stem), r.figure_png)
            r.match["figure_file"] = figure_file(stem)
        self.objects.append((r.name, "virtual", r.entry["faces"], r.entry["pose_count"]))
        self.rows += matches_rows({"matches": [r.match]}, placed_fixed=self._fixed)[1:]
        self._names.append(r.name)
        self._cost_rows.append(r.row)
        self._chosen.append(r.match.get("tangible"))
        if r.match.get("redirection") is not None:
            self.redirections.append(r.match["redirection"])
        if r.match.get("rest_gap_mm") is not None:
            self.rests.append((r.name, r.match["rest_gap_mm"]))
        if r.match.get("approach_elevation_deg") is not None:
            self.approaches.append((r.name, r.match["approach_elevation_deg"],
                                    r.match.get("approach_azimuth_deg")))
        if r.match.get("tangible") is not None:
            self.references.append((r.name, (r.match.get("reference") or {}).get("reason")))
        if r.match.get("equivalent_tangibles"):
            self.equivalents.append((r.name, r.match["tangible"],
                                     [e["tangible"] for e in r.match["equivalent_tangibles"]]))
        if self._lines is not None:
            self._line({"record": "match", "object": r.entry,
                        "cost_row": [json_number(x, 6) for x in r.row], "match": r.match})
        else:
            self._virtuals.append(r.entry)
            self._matches.append(r.match)

    def overview(self) -> dict:
        """The cost matrix and the chosen tangibles, as
        :func:`pinchmatch.export.figures.cost_matrix_figure` reads them."""
        return {"cost_matrix": cost_matrix_section(self._names,
                                                   [t["name"] for t in self._header["tangibles"]],
                                                   self._cost_rows),
                "matches": [{"virtual": n, "tangible": t}
                            for n, t in zip(self._names, self._chosen)]}

    def finish(self, result) -> dict | None:
        """Close the result file (``result``: the run's
        :class:`pinchmatch.runner.matching.RunResult`); return the matches document (None for jsonl,
        never held whole)."""
        failed = [f.as_dict() for f in result.failed]
        if self._lines is None:
            doc = self._header | {"virtuals": self._virtuals, "matches": self._matches,
                                  "failed": failed, "cost_matrix": self.overview()["cost_matrix"]}
            write_atomic(self.result_path, to_json(doc))
            return doc
        for f in failed:
            self._line({"record": "failed", **f})
        self._line({"record": "end", "virtual_count": len(self._names),
                    "matched_count": sum(t is not None for t in self._chosen),
                    "failed_count": len(failed)})
        self._lines.commit()
        self._lines = None
        return None
