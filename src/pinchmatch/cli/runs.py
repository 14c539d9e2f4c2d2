"""What the commands that run ``match`` share: options into settings, the run's tasks, its outputs.

``match``, ``select`` and ``design`` all end in a matching run written into an output folder; this
module turns their options into settings and writes that run (:func:`write_matches`).
"""

from __future__ import annotations

from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from ..errors import ConfigError, RunError
from ..export.documents import OPTIONAL_COLUMNS, matches_legend, scene_stems
from ..export.notes import (comfort_note, equivalent_note, flipped_note, redirection_note,
                            reference_note, rest_note, scan_note)
from ..export.sink import MatchesSink
from ..export.view import write_page
from ..files import check_writable, read_input, write_atomic
from ..grasp.analysis import load_poses_file, load_tripods_file
from ..grasp.pinches import PinchSettings
from ..config import CAROUSEL_MARGIN_JND, GAIN_RANGE, MAX_REACH_MM, Config
from ..match.cost import complete_weights, parse_weights
from ..match.search import MatchSettings
from ..runner.matching import run_match
from ..runner.tasks import Job, ObjectTask
from .parser import record_of

#: exit code of a run that went on without some files
EXIT_SOME_FAILED = 3


def pinch_settings_of(args, **extra) -> PinchSettings:
    """The pinch rules' settings from the command's options (sampling options where it offers
    them)."""
    return record_of(PinchSettings, args, **extra)


def match_settings_of(args) -> MatchSettings:
    """The match settings from the command's options; the weights from --weights or
    --weights-file."""
    field = MatchSettings.__dataclass_fields__["criteria"]
    criteria = field.metadata["option"].value(args.criteria)
    if getattr(args, "weights_file", None):
        if getattr(args, "weights", None):
            raise ConfigError("--weights and --weights-file: give one of them")
        from ..match.calibrate import read_weights_file

        given, pooling, fitted_for = read_weights_file(read_input(args.weights_file,
                                                                  "weights file (JSON)",
                                                                  limit_bytes=2**20),
                                                                  args.weights_file)
        if pooling is not None and pooling != args.pooling:
            raise ConfigError(f"{args.weights_file}: its weights were fitted for --pooling "
                              f"{pooling}; run with "
                              f"--pooling {pooling}, or calibrate again with --pooling "
                              f"{args.pooling}")
        if fitted_for is not None and fitted_for != args.criteria:
            raise ConfigError(f"{args.weights_file}: its weights are for --criteria {fitted_for}; "
                              f"run with --criteria {fitted_for}")
        weights = complete_weights(given, criteria=criteria)
    else:
        weights = parse_weights(getattr(args, "weights", None), criteria=criteria)
    user = {}
    if getattr(args, "user_mm", None) is None and getattr(args, "tangible", None):
        from ..mesh.manifest import manifest_user

        if (at := manifest_user(args.tangible)) is not None:
            # the props manifest's, where --user-at gives none
            user = {"user_mm": at}
    return record_of(MatchSettings, args, weights=weights, **user)


def config_of_args(args) -> Config:
    """The run's one configuration from the command's options."""
    return Config(pinch_settings_of(args), match_settings_of(args))


def check_placement(settings: MatchSettings, tangible_specs: list, virtual_specs: list, ui, *,
                    units: str | None = None, up: str | None = None) -> None:
    """What ``--placement`` needs of the objects, checked before any work: under ``fixed`` every
    virtual object placed by a level and the hand's start outside every prop (read in the run's
    ``units`` and ``up`` where its spec gives none); under ``registered`` the options of the
    redirection are not used (a note says so), while a prop's pose still says where it stands: on
    which table, and on which side of it the user is (:mod:`pinchmatch.match.comfort`)."""
    if settings.redirect is None:
        unused = [flag for flag, given in (("--hand-start", settings.hand_start_mm is not None),
                                           ("--gain-range",
                                            tuple(settings.gain_range) != GAIN_RANGE),
                                           ("--carousel-margin-jnd",
                                            settings.carousel_margin_jnd != CAROUSEL_MARGIN_JND))
                  if given]
        if unused:
            ui.note(f"{', '.join(unused)} {'is' if len(unused) == 1 else 'are'} used with "
                    "--placement fixed only; ignored under --placement registered")
        return
    loose = [s for s in virtual_specs if s.node is None]
    if loose:
        raise ConfigError(f"{loose[0].path}: --placement fixed keeps each virtual object where a "
                          "level puts it, and "
                          "this file is not a level's node; give a glTF/GLB level with --split "
                          "nodes, or use --placement registered")
    import numpy as np

    from ..match.redirect import hand_start, world_pose
    from ..mesh.load import load_mesh

    meshes = []
    for spec in tangible_specs:
        read = spec.with_defaults(units=units, up=up)
        meshes.append(load_mesh(read.path, units=read.units, up=read.up).mesh)
    starts = [hand_start(spec, settings.redirect, mesh.vertices)
              for spec, mesh in zip(tangible_specs, meshes)]
    for spec, mesh, start in zip(tangible_specs, meshes, starts):
        R, p = world_pose(spec)
        far = float(np.linalg.norm(mesh.vertices @ R.T + p - start, axis=1).min())
        if far > MAX_REACH_MM:
            where = ("--hand-start" if settings.hand_start_mm is not None
                     else "the default hand start")
            raise ConfigError(f"{where} {np.round(start, 1).tolist()} mm is {far:.0f} mm from the "
                              "prop "
                              f"{spec.display_name}, beyond an arm's reach ({MAX_REACH_MM:g} mm); "
                              "give a --hand-start "
                              "X,Y,Z where the user's hand rests, within reach of the props (mm, "
                              "the level's frame)")
    for spec, mesh in zip(tangible_specs, meshes):
        R, p = world_pose(spec)
        for start in starts:
            if mesh.contains(((start - p) @ R)[None])[0]:
                where = ("--hand-start" if settings.hand_start_mm is not None
                         else "the default hand start")
                raise ConfigError(f"{where} {np.round(start, 1).tolist()} mm lies inside the prop "
                                  f"{spec.display_name}; give a --hand-start X,Y,Z outside every "
                                  "prop, where the hand rests before it reaches")
    _start_outside_objects(starts, virtual_specs, units,
                           "--hand-start" if settings.hand_start_mm is not None
                           else "the default hand start")


def _start_outside_objects(starts: list, virtual_specs: list, units: str | None,
                           where: str) -> None:
    """Refuse a hand start inside a level's object, in one line: the hand cannot rest there."""
    import numpy as np
    import trimesh

    from ..mesh.frames import UNITS_MM
    from ..mesh.level import node_mesh
    from ..mesh.load import level_scene

    points = np.unique(np.asarray(starts, dtype=np.float64).reshape(-1, 3), axis=0)
    for path in sorted({s.path for s in virtual_specs if s.node is not None}):
        scene = level_scene(Path(path))
        for spec in (s for s in virtual_specs if s.path == path and s.node is not None):
            mesh = node_mesh(scene, spec.node)
            if mesh is None:
                continue
            vertices = np.asarray(mesh.vertices) * UNITS_MM[spec.units or units or "m"]
            low, high = vertices.min(axis=0), vertices.max(axis=0)
            near = points[((points >= low) & (points <= high)).all(axis=1)]
            if len(near) and trimesh.Trimesh(vertices, mesh.faces,
                                             process=False).contains(near).any():
                raise ConfigError(f"{where} {np.round(near[0], 1).tolist()} mm lies inside the "
                                  "level's object "
                                  f"{spec.display_name}; give a --hand-start X,Y,Z outside every "
                                  "object, where the "
                                  "hand rests before it reaches (mm, the level's frame)")


def virtual_level_specs(args, notes: list | None = None) -> list:
    """The virtual objects the command line names (``--virtual``), a level split as ``--split``,
    ``--nodes`` and ``--skip-nodes`` say, its furniture left out (a line each in ``notes``)."""
    from ..mesh.manifest import object_specs

    return object_specs(args.virtual, option="--virtual", split=args.split, nodes=args.nodes or (),
                        skip_nodes=args.skip_nodes or (), notes=notes, units=args.units, up=args.up)


def level_note(specs: list) -> str | None:
    """Before the run: how many objects each split level makes (a level of thousands of nodes is a
    long run)."""
    counts: dict[str, int] = {}
    for spec in specs:
        if spec.node is not None:
            counts[spec.path] = counts.get(spec.path, 0) + 1
    if not counts:
        return None
    return "; ".join(f"{path}: {n} node{'s' if n != 1 else ''}, one object each"
                     for path, n in counts.items())


def standing(specs: list, args, role: str) -> list:
    """The specs with the run's ``--support`` where their manifest says nothing: every prop stands,
    and every node of a level; a virtual object of its own file does not (it is not anywhere)."""
    return ([spec.standing(args.support) if role == "tangible" or spec.node else spec
             for spec in specs])


def given_poses(files, paths, option, grasp: str = "pinch") -> list:
    """Per object, the given poses or None; ``files`` must be one per object. Pinches are (p1_mm,
    p2_mm); tripods (``grasp``) a tuple of their (n, 3, 3) contacts."""
    if not files:
        return [None] * len(paths)
    if len(files) != len(paths):
        raise ConfigError(f"{option}: got {len(files)} files for {len(paths)} objects; give one "
                          "per object, in order")
    if grasp == "tripod":
        return [(load_tripods_file(f),) for f in files]
    return [load_poses_file(f) for f in files]


def out_folder(args) -> Path:
    out = Path(args.output)
    check_writable(out, folder=True)  # before any work
    return out


#: at most this many rows in the printed tables; the result files hold every one
TABLE_ROWS = 40


def table_rows(rows: list, what: str) -> list:
    """The header and at most TABLE_ROWS rows, the rest counted in a last row."""
    if len(rows) <= TABLE_ROWS + 1:
        return rows
    return rows[:TABLE_ROWS + 1] + [(f"... {len(rows) - 1 - TABLE_ROWS} more {what}",) + ("",)
                                    * (len(rows[0]) - 1)]


def match_job(args, settings: PinchSettings, match_settings: MatchSettings, cache) -> Job:
    return Job(units=args.units, up=args.up, config=Config(settings, match_settings),
               cache_folder=None if cache is None else str(Path(cache.folder).resolve()),
               dump_poses=getattr(args, "dump_poses", False), scenes=True, figures=args.figures)


def object_tasks(role: str, specs, given, files) -> list[ObjectTask]:
    return [ObjectTask(role, spec.path, given[k], files[k] if given[k] is not None else None, spec)
            for k, spec in enumerate(specs)]


def check_match_flags(args) -> None:
    if args.cache and args.no_cache:
        raise ConfigError("--cache and --no-cache: give one of them")
    if args.json and getattr(args, "format", "json") == "jsonl":
        raise ConfigError("--json and --format jsonl: give one of them; --json prints the "
                          "matches.json document")
    if args.figures and args.no_figures:
        raise ConfigError("--figures and --no-figures: give one of them")


def write_matches(args, stage: Path, out: Path, ui, ex, tangible_tasks, virtual_tasks, job: Job,
                   run_settings: dict, fmt: str = "json", plan: dict | None = None):
    """``match``'s run and its outputs into the staging folder ``stage`` of ``out``: matches.json,
    the scenes, the figures asked for and the page. Returns (result, document, sink, written)."""
    stems = scene_stems([t.spec.display_name for t in virtual_tasks])

    def on_failure(f) -> None:
        ui.error(f"{f.error}; skipped, going on with the other files")

    sink = MatchesSink(stage, fmt, stems)
    with sink:
        try:
            result = run_match(tangible_tasks, virtual_tasks, job, ex, on_failure=on_failure,
                               on_result=sink.add, step=ui.step, plan=plan,
                               header=lambda tangibles: sink.start(run_settings, tangibles,
                                                                   job.dump_poses))
        except BrokenProcessPool:
            raise RunError("a worker process died (out of memory?); run again with fewer "
                           "--jobs") from None
        doc = sink.finish(result)
    written = [str(out / sink.result_path.name), f"{sink.scenes} glTF scenes in {out / 'scenes'}"]
    if args.figures:
        from ..export.figures import (  # matplotlib: imported when figures are wanted
            cost_matrix_figure,
            png_bytes,
        )

        with ui.step("cost matrix figure"):
            write_atomic(stage / "figures" / "cost_matrix.png",
                         png_bytes(cost_matrix_figure(sink.overview())))
        written.append(f"{sink.scenes + 1} figures in {out / 'figures'}")
    if job.config.match.redirect is not None:
        written += write_levels(stage, out,
                                doc if doc is not None else read_lines(sink.result_path),
                                virtual_tasks, result, run_settings)
    if not args.no_view and doc is not None:
        with ui.step("viewer page"):
            write_page(stage, document=doc)
            written.append(f"the viewer page {out / 'index.html'}")
    elif not args.no_view:
        written.append(f"no viewer page (build it with: pinchmatch view {out})")
    return result, doc, sink, written


def read_lines(path: Path) -> dict:
    """The matches and the virtual objects of a ``matches.jsonl`` just written, as a matches
    document has them."""
    import json

    matches, virtuals = [], []
    with open(path, encoding="utf-8") as lines:
        for line in lines:
            record = json.loads(line)
            if record.get("record") == "match":
                matches.append(record["match"])
                virtuals.append(record["object"])
    return {"matches": matches, "virtuals": virtuals}


def _distinct_stems(paths: list) -> dict:
    """{path: a name for its level.glb}: the file's stem, with as many of its folders before it
    (joined by ``-``) as tell levels of one stem apart (``a/kitchen.glb`` and ``b/kitchen.glb``:
    ``a-kitchen``, ``b-kitchen``)."""
    import os

    parts = {p: Path(os.path.abspath(p)).with_suffix("").parts for p in paths}
    out = {}
    for p, chain in parts.items():
        twins = [c for q, c in parts.items() if q != p and c[-1] == chain[-1]]
        depth = 1
        while any(c[-depth:] == chain[-depth:] for c in twins) and depth < len(chain):
            depth += 1
        out[p] = "-".join(chain[-depth:])
    return out


def write_levels(stage: Path, out: Path, doc: dict, virtual_tasks, result,
                 run_settings: dict) -> list[str]:
    """Under ``--placement fixed``: each level the virtual objects come from, with the props at
    their poses and each node's match in its extras (:mod:`pinchmatch.export.level`): ``level.glb``,
    or ``level-<file stem>.glb`` for each of several levels."""
    from ..export.level import level_glb

    specs = {t.spec.display_name: t.spec for t in virtual_tasks if t.spec is not None
             and t.spec.node is not None}
    props = {c.name: c.obj for c in result.tangibles}
    objects = {v["name"]: v for v in doc.get("virtuals", [])}
    levels = sorted({spec.path for spec in specs.values()})
    level_names = _distinct_stems(levels)
    written = []
    for path in levels:
        entries = {specs[m["virtual"]].node: (m, props[m["tangible"]].spec) for m in doc["matches"]
                   if m.get("tangible") is not None and m["virtual"] in specs
                   and specs[m["virtual"]].path == path}
        virtuals = {specs[name].node: entry for name, entry in objects.items()
                    if name in specs and specs[name].path == path}
        name = "level.glb" if len(levels) == 1 else f"level-{level_names[path]}.glb"
        units = next((s.units for s in specs.values() if s.path == path and s.units),
                     None) or run_settings.get("units")
        data = level_glb(path,
                         [(obj.spec, obj.loaded.mesh, obj.props.com_mm, obj.mass_g)
                          for obj in props.values()], entries, run_settings, virtuals=virtuals,
                          units=units)
        write_atomic(stage / name, data)
        written.append(str(out / name))
    return written


def print_match(ui, sink, result, run_settings) -> None:
    ui.table(table_rows(sink.objects, "objects"), title="objects")
    ui.table(table_rows(sink.rows, "matches"), title="matches", legend=matches_legend(run_settings),
             optional=OPTIONAL_COLUMNS)
    if note := flipped_note(sink.rows, run_settings):
        ui.note(note)
    if note := redirection_note(sink.redirections):
        ui.note(note)
    if note := equivalent_note(sink.equivalents):
        ui.note(note)
    if note := rest_note(sink.rests):
        ui.note(note)
    if note := comfort_note(sink.approaches):
        ui.note(note)
    if note := reference_note(sink.references):
        ui.note(note)
    if note := scan_note([(c.name, None if c.obj.spec is None else c.obj.spec.scale_verified)
                          for c in result.tangibles]):
        ui.note(note)
    if result.failed:
        ui.table(table_rows([("file", "role", "problem")]
                            + [(f.path, f.role, f.error) for f in result.failed],
                             "files"),
                             title=f"failed: {len(result.failed)} files, left out of the run")




def placed_in_level(tangible_specs: list, virtual_specs: list, up: str | None) -> list:
    """The props with the up of the level their poses place them in (``level_up``): the up of the
    levels the virtual objects are nodes of (their manifest entries', else ``up``, else glTF's
    ``y``); levels of two ups are refused in one line. Unchanged where the level is y-up, or no prop
    has a pose."""
    from dataclasses import replace

    from ..mesh.frames import parse_up

    ups = {}
    for spec in virtual_specs:
        if spec.node is not None:
            ups.setdefault(parse_up(spec.up or up or "y")[0], spec.path)
    if len(ups) > 1:
        (a, first), (b, second) = list(ups.items())[:2]
        raise ConfigError(f"{second}: its up is {b} while {first}'s is {a}; a prop's pose places "
                          "it in one level "
                          "frame, so match the levels of each up in a run of their own")
    label = next(iter(ups), "y")
    return [replace(s, level_up=label) if s.pose is not None and label != "y" else s
            for s in tangible_specs]
