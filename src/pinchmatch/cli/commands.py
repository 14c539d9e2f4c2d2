"""The commands: ``pinchmatch demo``, ``match``, ``select``, ``design``, ``calibrate``, ``view``,
``cache``, ``poses`` and ``features``.

Each takes the parsed options and returns its exit code (:mod:`pinchmatch.cli.main` lists them
and turns errors into one line; callers that run a command line use
:func:`pinchmatch.cli.main.main`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import time
from importlib import resources
from pathlib import Path

import numpy as np

from ..grasp.analysis import (analyze_object, find_pinches, load_poses_file, load_tripods_file,
                              score_pinches, score_tripods)
from ..runner.cache import FeatureCache
from ..errors import ConfigError
from ..config import Config
from ..files import check_writable, read_input, write_atomic
from ..mesh.manifest import object_specs
from ..grasp.pinches import PinchSettings
from ..export.folder import OutputFolder, exclusive
from ..mesh.properties import parse_vector
from .console import Presenter
from .runs import (EXIT_SOME_FAILED, check_match_flags, check_placement, given_poses, level_note,
                   match_job, placed_in_level, standing, match_settings_of, object_tasks,
                   out_folder, pinch_settings_of, print_match, table_rows, virtual_level_specs,
                   write_matches)
from .universal import cmd_design, cmd_select, demo_design
from ..export.notes import flipped_note
from ..export.documents import (features_document, matches_rows, poses_csv, poses_document,
                                scene_stems, matches_legend, study_document, study_legend,
                                study_rows, to_json)
from ..runner.tasks import Job, virtual_result
from ..export.sink import MatchesSink
from ..export.study_plan import study_plan
from ..export.study_ratings import static_ratings_table
from ..runner.matching import RunResult
from ..runner.executors import executor
from ..runner.study import ORDERS, run_study, study_mesh_names
from ..export.view import make_server, write_page

log = logging.getLogger("pinchmatch")

def example_mesh_path() -> Path:
    """The built-in example: the method's study prop (cylinder, cube and cone stacked, 120 mm
    tall)."""
    return Path(str(resources.files("pinchmatch") / "data" / "example_prop.stl"))


def _object(args, progress=None):
    if args.example and args.mesh:
        raise ConfigError(f"{args.mesh}: give either a MESH or --example, not both")
    if not args.example and not args.mesh:
        raise ConfigError("no mesh given; name a mesh file, or use --example for the built-in one")
    com = parse_vector(args.com, option="--com") if args.com else None
    axis = parse_vector(args.axis, option="--axis") if args.axis else None
    path = example_mesh_path() if args.example else Path(args.mesh)
    return analyze_object(path, units=args.units, up=args.up, com_mm=com, axis=axis,
                          patch_radius_mm=args.patch_radius_mm, progress=progress)


def _settings_dict(args, settings: PinchSettings, obj) -> dict:
    out = settings.as_dict()
    out.update(units=obj.loaded.units_in, up=obj.loaded.up_label)
    return out


def _emit(args, text: str, summary: str) -> None:
    if args.output:
        write_atomic(args.output, text)
        if not args.quiet:
            print(summary)
    else:
        sys.stdout.write(text)


def _cmd_poses(args) -> int:
    settings = pinch_settings_of(args)  # validate options before any work
    if args.output:
        check_writable(args.output, folder=False)
    tripods = settings.grasp == "tripod"
    given = (None if not args.poses else load_tripods_file(args.poses) if tripods
             else load_poses_file(args.poses))
    ui = Presenter(quiet=args.quiet)
    t0 = time.perf_counter()
    with ui.step("loading") as stage:  # a large mesh shows which stage its load is in
        obj = _object(args, progress=lambda name: stage(name, done=False))
    t1 = time.perf_counter()
    with ui.step("poses and features"):
        if given is not None and tripods:
            pinches, features = score_tripods(obj, given, settings=settings, source=args.poses)
        elif given is not None:
            pinches, features = score_pinches(obj, *given, settings=settings, source=args.poses)
        else:
            pinches, features = find_pinches(obj, settings=settings)
    t2 = time.perf_counter()
    doc = poses_document(obj.loaded, obj.props, _settings_dict(args, settings, obj), pinches,
                         features, ray_engine=obj.context.ray_engine_name)
    text = to_json(doc) if args.format == "json" else poses_csv(doc)
    n_ok = int(pinches.feasible.sum())
    lines = [
        f"{obj.name}: {len(obj.loaded.mesh.faces)} faces, {doc['object']['extent_mm']} mm, "
        f"watertight={obj.loaded.watertight}, axis from {obj.props.axis_source}",
        f"{n_ok} feasible of {len(pinches)} {'tripods' if tripods else 'pinches'}; load "
        f"{t1 - t0:.2f} s, poses and features {t2 - t1:.2f} s",
    ]
    if given is not None:
        for i in np.flatnonzero(~pinches.feasible):
            lines.append(f"  pose {i}: infeasible, breaks {', '.join(pinches.broken_rules(i))}")
    lines += [f"  repaired: {r}" for r in obj.loaded.repairs] + [f"  warning: {w}"
                                                                 for w in obj.loaded.warnings]
    if args.output:
        lines.append(f"wrote {args.output}")
    _emit(args, text, "\n".join(lines))
    return 0


def _cmd_features(args) -> int:
    settings = pinch_settings_of(args)
    if args.output:
        check_writable(args.output, folder=False)
    given = [parse_vector(args.p1, option="--p1"), parse_vector(args.p2, option="--p2")]
    if args.p3:
        given.append(parse_vector(args.p3, option="--p3"))
    for i in range(len(given)):
        for j in range(i):
            if np.allclose(given[i], given[j], rtol=0, atol=1e-9):
                raise ConfigError(f"--p{j + 1} and --p{i + 1} are the same point; a grasp needs "
                                  "distinct contacts")
    kind = "tripod" if args.p3 else "pinch"
    with Presenter(quiet=args.quiet).step(f"loading and scoring the {kind}") as stage:
        obj = _object(args, progress=lambda name: stage(name, done=False))
        if args.p3:
            pinches, features = score_tripods(obj, np.array(given), settings=settings)
        else:
            pinches, features = score_pinches(obj, *given, settings=settings)
    recorded = {**_settings_dict(args, settings, obj), "grasp": kind}
    doc = features_document(obj.loaded, obj.props, recorded, pinches, features,
                            given=given, ray_engine=obj.context.ray_engine_name)
    pose = doc["pose"]
    verdict = ("feasible" if pose["feasible"]
               else f"NOT feasible: breaks {', '.join(pose['broken_rules'])}")
    size = (f"aperture {pose['aperture_mm']} mm, spacing {pose['spacing_mm']} mm" if args.p3
            else f"width {pose['width_mm']} mm")
    lines = [
        f"{obj.name}: {kind} {verdict}",
        f"  {size}, com distance {pose['com_distance_mm']} mm, tilt {pose['tilt_deg']} deg",
        "  approach " + (f"{pose['approach']} (fingers clear by {pose['approach_clearance_mm']} mm)"
                         if pose["approach_clearance_mm"] is not None
                         else "none: no hand gets to both contacts"),
    ]
    for k, patch in enumerate(pose["patches"], start=1):
        lines.append(
            f"  patch {k}: normal angle {patch['normal_angle_deg']} deg, curvature axis angle "
            f"{patch['curvature_axis_angle_deg']} deg, kappa {patch['kappa_max_per_m']} / "
            f"{patch['kappa_min_per_m']} 1/m"
        )
    if args.output:
        _emit(args, to_json(doc), "\n".join(lines + [f"wrote {args.output}"]))
    elif args.quiet:
        sys.stdout.write(to_json(doc))
    else:
        print("\n".join(lines))
        sys.stdout.write(to_json(doc))
    return 0


def _cmd_match(args) -> int:
    settings = pinch_settings_of(args)
    match_settings = match_settings_of(args)
    out = out_folder(args)
    tangible_specs = standing(object_specs(args.tangible, option="--tangible"), args, "tangible")
    left_out: list[str] = []
    virtual_specs = standing(virtual_level_specs(args, left_out), args, "virtual")
    tangible_specs = placed_in_level(tangible_specs, virtual_specs, args.up)
    given_t = given_poses(args.tangible_poses, tangible_specs, "--tangible-poses", settings.grasp)
    given_v = given_poses(args.virtual_poses, virtual_specs, "--virtual-poses", settings.grasp)
    check_match_flags(args)
    cache = None if args.no_cache else FeatureCache(args.cache)
    job = match_job(args, settings, match_settings, cache)
    ui = Presenter(quiet=args.quiet, json_mode=args.json)
    for note in left_out:
        ui.note(note)
    if note := level_note(virtual_specs):
        ui.note(note)
    check_placement(match_settings, tangible_specs, virtual_specs, ui, units=args.units, up=args.up)
    run_settings = {**settings.as_dict(), **match_settings.as_dict(), "units": args.units,
                    "up": args.up, "split": args.split or "none", "support": args.support}
    t0 = time.perf_counter()
    with OutputFolder(out) as stage:  # published into OUT as a whole at the end, or not at all
        with executor(args.jobs, args.scheduler) as ex:
            result, doc, sink, written = write_matches(
                args, stage, out, ui, ex,
                object_tasks("tangible", tangible_specs, given_t, args.tangible_poses),
                object_tasks("virtual", virtual_specs, given_v, args.virtual_poses), job,
                run_settings, args.format)
        t1 = time.perf_counter()
    print_match(ui, sink, result, run_settings)
    who = "Dask workers" if args.scheduler else "processes" if ex.workers > 1 else "process"
    where = f"{ex.workers} {who}"
    cached = (f"; {result.cached} from the cache, {result.computed} computed; cache {cache.folder}"
              if cache is not None else "")
    ui.note(f"{t1 - t0:.2f} s on {where}{cached}; wrote " + ", ".join(written))
    if doc is not None:
        ui.document(to_json(doc))
    return EXIT_SOME_FAILED if result.failed else 0


def _cmd_calibrate(args) -> int:
    from ..match.calibrate import calibrate, fittable_criteria, read_ratings
    from ..match.cost import CRITERIA

    criteria = None
    if args.criteria:
        criteria = tuple(c.strip() for c in args.criteria.split(",") if c.strip())
        unknown = [c for c in criteria if c not in CRITERIA]
        if unknown or not criteria:
            raise ConfigError(f"--criteria {args.criteria}: unknown "
                              f"{', '.join(unknown) or 'nothing given'}; "
                              f"valid: {', '.join(CRITERIA)}")
    check_writable(args.output, folder=False)
    ui = Presenter(quiet=args.quiet, json_mode=args.json)
    text = read_input(args.ratings, "ratings table (CSV)", limit_bytes=64 * 2**20)
    try:
        decoded = text.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ConfigError(f"{args.ratings}: not UTF-8 text; save the table as a UTF-8 "
                          "CSV") from None
    ratings = read_ratings(decoded, args.ratings, criteria=criteria)
    left_out: dict = {}
    if criteria is None:
        fittable, left_out = fittable_criteria(ratings, pooling=args.pooling)
        if fittable and left_out:
            # read again as if named: placements are grouped on the fitted columns
            ratings = read_ratings(decoded, args.ratings, criteria=fittable)
        else:  # all fittable, or none (the fit's check then says why, in one line)
            left_out = {}
    fit = calibrate(ratings, pooling=args.pooling, seed=args.seed, hold_out=args.hold_out,
                    force=args.force)
    document = fit.as_dict(str(args.ratings))
    if left_out:
        document["fit"]["not_fitted"] = left_out
    write_atomic(args.output, to_json(document))
    intervals = fit.intervals or {}
    rows = [("criterion", "fitted", "90 % interval", "written")] + [
        (c, f"{fit.fitted_weights[c]:.3f}",
         f"{intervals[c][0]:.3f}-{intervals[c][1]:.3f}" if c in intervals else "-",
         f"{fit.weights[c]:.3f}")
        for c in ratings.criteria]
    ui.table(table_rows(rows, "criteria"),
             title=f"weights fitted to {fit.rows} ratings of {fit.pairs} placements ({fit.pooling} "
                   "pooling)")
    if left_out:
        ui.note("not fitted, kept at their defaults: "
                + "; ".join(f"{c} {why}" for c, why in left_out.items()))
    if fit.undetermined:
        ui.warn("the table does not determine " + ", ".join(
            f"{c} (90 % interval {intervals[c][0]:.2f}-{intervals[c][1]:.2f})"
            for c in fit.undetermined)
            + f"; {'it keeps its' if len(fit.undetermined) == 1 else 'they keep their'} default in "
              f"{args.output} (rate placements that differ in it; --force writes the fit)")
    by = "by placement" if fit.hold_out == "placement" else "one virtual object out at a time"
    ui.note(f"held-out rank correlation of cost and rating ({fit.folds} folds, {by}; -1 is "
            "perfect): "
            f"fitted {fit.held_out_spearman:+.3f}, default weights {fit.default_spearman:+.3f}; "
            f"wrote {args.output}")
    if fit.kept == "defaults":
        ui.warn("the fitted weights rank held-out ratings no better than the default weights, so "
                f"{args.output} keeps "
                "the defaults (the fitted ones are under fit.fitted_weights); --force writes the "
                "fitted weights")
    ui.document(to_json(document))
    return 0


def _cmd_cache(args) -> int:
    cache, ui = FeatureCache(args.cache), Presenter(quiet=args.quiet)
    if args.action == "clear":
        ui.note(f"deleted {cache.clear()} entries from {cache.folder}")
    else:
        info = cache.info()
        ui.note(f"{info.folder}: {info.entries} entries, {info.size_bytes / 2**20:.1f} MiB")
    return 0


def _cmd_prop(args) -> int:
    from ..scan.prop_import import import_prop
    from ..scan.surface import MAX_FACES

    ui = Presenter(quiet=args.quiet)
    if args.faces is not None and args.faces < 1000:
        raise ConfigError(f"--faces {args.faces}: give at least 1000 faces (default {MAX_FACES})")
    prop = import_prop(args.scan, args.out, name=args.name, units=args.units, up=args.up,
                       measured=args.measured_mm, mass_g=args.mass_g,
                       faces=args.faces or MAX_FACES)
    for line in prop.lines:
        ui.note(line)
    return 0


def _cmd_demo(args) -> int:
    settings = pinch_settings_of(args)
    match = match_settings_of(args)
    out = out_folder(args)
    ui = Presenter(quiet=args.quiet, json_mode=args.json)
    t0 = time.perf_counter()
    publisher = OutputFolder(out)
    with publisher as stage:  # published into OUT as a whole at the end, or not at all
        with ui.step("user study", total=len(ORDERS) + 1) as advance:
            started = []

            def starting(note: str) -> None:
                # run_study names each part as it starts: the one before is done
                advance(note, done=bool(started))
                started.append(note)

            # the study's objects are its inputs, the same bytes every run: written in place, so the
            # documents can name where they stay; a run that does not finish takes back those it
            # added (recorded before they are written: a killed run's are taken back too)
            for name in study_mesh_names():
                publisher.direct(out / "objects" / name, new=not (out / "objects" / name).exists())
            study = run_study(out / "objects", full=args.full, settings=settings,
                              match_settings=match, progress=starting)
        t1 = time.perf_counter()
        common = {**settings.as_dict(),
                  "candidate_virtual_poses": "17 heights and all sampled" if args.full
                  else "17 heights",
                  **match.as_dict()}
        study_doc = study_document(study, common)
        write_atomic(stage / "study.json", to_json(study_doc))
        plan = study_plan(study.rows, [v.name for v in study.virtuals], seed=args.seed)
        write_atomic(stage / "study_plan.json", to_json(plan))
        write_atomic(stage / "ratings_static.csv",
                     static_ratings_table(study.rows,
                                          [v.name for v in study.virtuals]).encode("utf-8"))
        scene = study.scene
        job = Job(units="mm", up="z", config=Config(settings, match), figures=not args.no_figures)
        with MatchesSink(stage, "json", scene_stems([v.name for v in scene.virtuals])) as sink:
            sink.start(common, scene.tangibles, dump_poses=False)
            with ui.step("glTF scenes", total=len(scene.virtuals)) as advance:
                for k in range(len(scene.virtuals)):
                    sink.add(k, virtual_result(scene, k, job))
                    advance(scene.virtuals[k].name)
            matches_doc = sink.finish(RunResult(scene.tangibles, {}, [], 0, len(scene.virtuals)))
        written = [f"{out / 'study.json'}",
                   f"{out / 'study_plan.json'} ({len(plan['trials'])} trials for the headset)",
                   f"{out / 'ratings_static.csv'} (the method's static ratings with this run's "
                   "differences, for calibrate)",
                   f"{out / 'matches.json'}", f"{sink.scenes} glTF scenes in {out / 'scenes'}"]
        if not args.no_figures:
            # matplotlib: imported when figures are wanted
            from ..export.figures import figure_count, write_figures

            total = figure_count(matches_doc, study=study, criteria=False)
            with ui.step("figures", total=total) as advance:
                write_figures(stage, matches_doc, study=study, criteria=False,
                              progress=lambda p: advance(p.name))
            written.append(f"{total + sink.scenes} figures in {out / 'figures'}")
        if not args.no_view:
            with ui.step("viewer page"):
                write_page(stage, document=matches_doc)
            written.append(f"the viewer page {out / 'index.html'}")
        written.append(f"the objects in {out / 'objects'}")
        if args.design:
            designed = demo_design(publisher, stage, out / "objects", settings,
                                   budget_s=args.budget_s, seed=args.seed, ui=ui)
            written.append(f"{out / 'props' / 'designed.stl'} and {out / 'design.json'}")
    ui.table(study_rows(study.rows), title="user study", legend=study_legend(study.rows))
    rows = matches_rows(matches_doc)
    ui.table(rows, title="matches", legend=matches_legend(common))
    if note := flipped_note(rows, common):
        ui.note(note)
    if args.design:
        c = designed["comparison"]
        ui.table([("prop", "mean_cost", "noticeable")]
                 + [(name, f"{v['mean_cost']:.4f}", v["noticeable_count"])
                                                          for name, v in c.items()],
                 title="a prop designed for the six virtual objects, from the study prop's shape "
                       f"({designed['evaluations']} judged)")
    ui.note(f"study {t1 - t0:.2f} s; wrote " + ", ".join(written))
    ui.document(to_json(study_doc))
    return 0


def _cmd_view(args) -> int:
    if not 0 <= args.port <= 65535:
        raise ConfigError(f"--port {args.port}: not a port; give 0 (any free port) to 65535")
    ui = Presenter(quiet=args.quiet)
    folder = Path(args.folder)
    if folder.is_file():
        if folder.name not in RESULT_DOCUMENTS:
            raise ConfigError(f"{folder}: not a result document of pinchmatch; give the -o folder "
                              f"of a match or demo run, or its {' or '.join(RESULT_DOCUMENTS)}")
        folder = folder.parent
    if folder.is_dir():
        check_writable(folder / "index.html", folder=False)
    with exclusive(folder) if folder.is_dir() else contextlib.nullcontext():
        # after a run that died while publishing is finished: its result, whole
        path = write_page(folder)
    ui.note(f"wrote {path}")
    if not args.serve:
        if args.open:
            _open_in_browser(path.resolve().as_uri(), ui)
        return 0
    try:
        server = make_server(folder, port=args.port)
    except OSError as exc:
        raise ConfigError(f"--port {args.port}: cannot serve there ({exc.strerror}); try --port "
                          "0") from None
    host, port = server.server_address[:2]
    # the address is printed even with --quiet: it is what --serve is for
    print(f"serving {folder} at http://{host}:{port}/index.html (Ctrl-C stops)", flush=True)
    if args.open:
        _open_in_browser(f"http://{host}:{port}/index.html", ui)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()
    return 0


#: the documents of a result folder that ``view`` also accepts in its place
RESULT_DOCUMENTS = ("matches.json", "matches.jsonl", "study.json")


def has_display() -> bool:
    """Whether a browser window can open here: macOS and Windows, or an X11 or Wayland display."""
    return sys.platform in ("darwin", "win32") or bool(os.environ.get("DISPLAY")
                                                       or os.environ.get("WAYLAND_DISPLAY"))


def _open_in_browser(url: str, ui) -> None:
    import webbrowser

    if not has_display() or not webbrowser.open(url):
        ui.note(f"no display to open a browser on; open {url} in one")


COMMANDS = {"calibrate": _cmd_calibrate, "demo": _cmd_demo, "match": _cmd_match,
            "select": cmd_select, "design": cmd_design, "view": _cmd_view, "cache": _cmd_cache,
            "poses": _cmd_poses, "features": _cmd_features, "prop": _cmd_prop}
