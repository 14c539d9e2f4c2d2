"""The commands: ``pinchmatch demo``, ``match``, ``select``, ``view``, ``cache``, ``poses`` and ``features``.

Each takes the parsed options and returns its exit code (:mod:`pinchmatch.cli.main` lists them
and turns errors into one line). ``main`` is re-exported here for callers that run a command line.
"""

from __future__ import annotations

import logging
import os
import sys
import time
from concurrent.futures.process import BrokenProcessPool
from importlib import resources
from pathlib import Path

import numpy as np

from ..grasp.analysis import analyze_object, find_pinches, load_poses_file, score_pinches
from ..runner.cache import FeatureCache
from ..errors import ConfigError, RunError
from ..files import check_writable, write_atomic
from ..mesh.manifest import object_specs
from ..grasp.pinches import PinchSettings
from ..export.folder import OutputFolder, recover
from ..match.cost import parse_criteria, parse_weights
from ..match.search import MatchSettings
from ..mesh.properties import parse_vector
from .console import Presenter
from .main import main  # noqa: F401 (the entry point, re-exported)
from ..export.documents import (features_document, matches_rows, poses_csv, poses_document, scene_stems,
                                matches_legend, study_document, study_legend, study_rows, to_json)
from ..runner.tasks import Job, ObjectTask, virtual_result
from ..export.sink import MatchesSink
from ..runner.matching import RunResult, run_match
from ..runner.executors import executor
from ..runner.study import ORDERS, run_study
from ..export.view import make_server, write_page

log = logging.getLogger("pinchmatch")

EXIT_SOME_FAILED = 3

def example_mesh_path() -> Path:
    """The built-in example: the method's study prop (cylinder, cube and cone stacked, 120 mm tall)."""
    return Path(str(resources.files("pinchmatch") / "data" / "example_prop.stl"))


def _settings(args, **extra) -> PinchSettings:
    return PinchSettings(
        friction_cone_deg=args.friction_cone_deg,
        min_width_mm=args.min_width_mm,
        max_width_mm=args.max_width_mm,
        fingertip_radius_mm=args.fingertip_radius_mm,
        patch_radius_mm=args.patch_radius_mm,
        snap_tolerance_mm=args.snap_tolerance_mm,
        finger_radius_mm=args.finger_radius_mm,
        finger_length_mm=args.finger_length_mm,
        approach_tilt_deg=args.approach_tilt_deg,
        **extra,
    )


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
    settings = _settings(args, count=args.count, seed=args.seed)  # validate options before any work
    if args.output:
        check_writable(args.output, folder=False)
    given = load_poses_file(args.poses) if args.poses else None
    ui = Presenter(quiet=args.quiet)
    t0 = time.perf_counter()
    with ui.step("loading") as stage:  # a large mesh shows which stage its load is in
        obj = _object(args, progress=lambda name: stage(name, done=False))
    t1 = time.perf_counter()
    with ui.step("poses and features"):
        if given is not None:
            pinches, features = score_pinches(obj, *given, settings=settings, source=args.poses)
        else:
            pinches, features = find_pinches(obj, settings=settings)
    t2 = time.perf_counter()
    doc = poses_document(obj.loaded, obj.props, _settings_dict(args, settings, obj), pinches, features,
                         ray_engine=obj.context.ray_engine_name)
    text = to_json(doc) if args.format == "json" else poses_csv(doc)
    n_ok = int(pinches.feasible.sum())
    lines = [
        f"{obj.name}: {len(obj.loaded.mesh.faces)} faces, {doc['object']['extent_mm']} mm, "
        f"watertight={obj.loaded.watertight}, axis from {obj.props.axis_source}",
        f"{n_ok} feasible of {len(pinches)} pinches; load {t1 - t0:.2f} s, poses and features {t2 - t1:.2f} s",
    ]
    if given is not None:
        for i in np.flatnonzero(~pinches.feasible):
            lines.append(f"  pose {i}: infeasible, breaks {', '.join(pinches.broken_rules(i))}")
    lines += [f"  repaired: {r}" for r in obj.loaded.repairs] + [f"  warning: {w}" for w in obj.loaded.warnings]
    if args.output:
        lines.append(f"wrote {args.output}")
    _emit(args, text, "\n".join(lines))
    return 0


def _cmd_features(args) -> int:
    settings = _settings(args)
    if args.output:
        check_writable(args.output, folder=False)
    p1 = parse_vector(args.p1, option="--p1")
    p2 = parse_vector(args.p2, option="--p2")
    if np.allclose(p1, p2, rtol=0, atol=1e-9):
        raise ConfigError(f"--p1 and --p2 are the same point ({args.p1}); a pinch needs two contacts")
    with Presenter(quiet=args.quiet).step("loading and scoring the pinch") as stage:
        obj = _object(args, progress=lambda name: stage(name, done=False))
        pinches, features = score_pinches(obj, p1, p2, settings=settings)
    doc = features_document(obj.loaded, obj.props, _settings_dict(args, settings, obj), pinches, features,
                            given=(p1, p2), ray_engine=obj.context.ray_engine_name)
    pose = doc["pose"]
    verdict = "feasible" if pose["feasible"] else f"NOT feasible: breaks {', '.join(pose['broken_rules'])}"
    lines = [
        f"{obj.name}: pinch {verdict}",
        f"  width {pose['width_mm']} mm, com distance {pose['com_distance_mm']} mm, tilt {pose['tilt_deg']} deg",
        "  approach " + (f"{pose['approach']} (fingers clear by {pose['approach_clearance_mm']} mm)"
                         if pose["approach_clearance_mm"] is not None else "none: no hand gets to both contacts"),
    ]
    for k, patch in enumerate(pose["patches"], start=1):
        lines.append(
            f"  patch {k}: normal angle {patch['normal_angle_deg']} deg, curvature axis angle "
            f"{patch['curvature_axis_angle_deg']} deg, kappa {patch['kappa_max_per_m']} / {patch['kappa_min_per_m']} 1/m"
        )
    if args.output:
        _emit(args, to_json(doc), "\n".join(lines + [f"wrote {args.output}"]))
    elif args.quiet:
        sys.stdout.write(to_json(doc))
    else:
        print("\n".join(lines))
        sys.stdout.write(to_json(doc))
    return 0


def _match_settings(args) -> MatchSettings:
    criteria = parse_criteria(args.criteria)
    return MatchSettings(weights=parse_weights(args.weights, criteria=criteria), criteria=criteria,
                         normalize=args.normalize, top_k=args.top_k, one_to_one=getattr(args, "one_to_one", False),
                         keep_upright=args.keep_upright, distinct_mm=args.distinct_mm)


def _given_poses(files, paths, option) -> list:
    """Per object, the given poses or None; ``files`` must be one per object."""
    if not files:
        return [None] * len(paths)
    if len(files) != len(paths):
        raise ConfigError(f"{option}: got {len(files)} files for {len(paths)} objects; give one per object, in order")
    return [load_poses_file(f) for f in files]


def _out_folder(args) -> Path:
    out = Path(args.output)
    check_writable(out, folder=True)  # before any work
    return out


#: at most this many rows in the printed tables; the result files hold every one
TABLE_ROWS = 40


def _table_rows(rows: list, what: str) -> list:
    """The header and at most TABLE_ROWS rows, the rest counted in a last row."""
    if len(rows) <= TABLE_ROWS + 1:
        return rows
    return rows[:TABLE_ROWS + 1] + [(f"... {len(rows) - 1 - TABLE_ROWS} more {what}",) + ("",) * (len(rows[0]) - 1)]


def _match_job(args, settings: PinchSettings, match_settings: MatchSettings, cache) -> Job:
    return Job(units=args.units, up=args.up, settings=settings, match=match_settings,
               cache_folder=None if cache is None else str(Path(cache.folder).resolve()),
               dump_poses=getattr(args, "dump_poses", False), scenes=True, figures=args.figures)


def _object_tasks(role: str, specs, given, files) -> list[ObjectTask]:
    return [ObjectTask(role, spec.path, given[k], files[k] if given[k] is not None else None, spec)
            for k, spec in enumerate(specs)]


def _check_match_flags(args) -> None:
    if args.cache and args.no_cache:
        raise ConfigError("--cache and --no-cache: give one of them")
    if args.json and getattr(args, "format", "json") == "jsonl":
        raise ConfigError("--json and --format jsonl: give one of them; --json prints the matches.json document")
    if args.figures and args.no_figures:
        raise ConfigError("--figures and --no-figures: give one of them")


def _write_matches(args, stage: Path, out: Path, ui, ex, tangible_tasks, virtual_tasks, job: Job,
                   run_settings: dict, fmt: str = "json", plan: dict | None = None):
    """``match``'s run and its outputs into the staging folder ``stage`` of ``out``: matches.json,
    the scenes, the figures asked for and the page. Returns (result, document, sink, written)."""
    stems = scene_stems([t.spec.display_name for t in virtual_tasks])

    def on_failure(f) -> None:
        ui.error(f"{f.error}; skipped, going on with the other files")

    sink = MatchesSink(stage, fmt, stems)
    with sink:
        try:
            result = run_match(tangible_tasks, virtual_tasks, job, ex, on_failure=on_failure, on_result=sink.add,
                               step=ui.step, plan=plan,
                               header=lambda tangibles: sink.start(run_settings, tangibles, job.dump_poses))
        except BrokenProcessPool:
            raise RunError("a worker process died (out of memory?); run again with fewer --jobs") from None
        doc = sink.finish(result)
    written = [str(out / sink.result_path.name), f"{sink.scenes} glTF scenes in {out / 'scenes'}"]
    if args.figures:
        from ..export.figures import png_bytes, cost_matrix_figure  # matplotlib: imported when figures are wanted

        with ui.step("cost matrix figure"):
            write_atomic(stage / "figures" / "cost_matrix.png", png_bytes(cost_matrix_figure(sink.overview())))
        written.append(f"{sink.scenes + 1} figures in {out / 'figures'}")
    if not args.no_view and doc is not None:
        with ui.step("viewer page"):
            write_page(stage, document=doc)
            written.append(f"the viewer page {out / 'index.html'}")
    elif not args.no_view:
        written.append(f"no viewer page (build it with: pinchmatch view {out})")
    return result, doc, sink, written


def _print_match(ui, sink, result, run_settings) -> None:
    ui.table(_table_rows(sink.objects, "objects"), title="objects")
    ui.table(_table_rows(sink.rows, "matches"), title="matches", legend=matches_legend(run_settings))
    if result.failed:
        ui.table(_table_rows([("file", "role", "problem")] + [(f.path, f.role, f.error) for f in result.failed],
                             "files"), title=f"failed: {len(result.failed)} files, left out of the run")


def _cmd_match(args) -> int:
    settings = _settings(args, count=args.count, seed=args.seed)
    match_settings = _match_settings(args)
    out = _out_folder(args)
    tangible_specs = object_specs(args.tangible, option="--tangible")
    virtual_specs = object_specs(args.virtual, option="--virtual", split=args.split)
    given_t = _given_poses(args.tangible_poses, tangible_specs, "--tangible-poses")
    given_v = _given_poses(args.virtual_poses, virtual_specs, "--virtual-poses")
    _check_match_flags(args)
    cache = None if args.no_cache else FeatureCache(args.cache)
    job = _match_job(args, settings, match_settings, cache)
    ui = Presenter(quiet=args.quiet, json_mode=args.json)
    run_settings = {**settings.as_dict(), **match_settings.as_dict(), "units": args.units, "up": args.up,
                    "split": args.split or "none"}
    t0 = time.perf_counter()
    with OutputFolder(out) as stage:  # published into OUT as a whole at the end, or not at all
        with executor(args.jobs, args.scheduler) as ex:
            result, doc, sink, written = _write_matches(
                args, stage, out, ui, ex, _object_tasks("tangible", tangible_specs, given_t, args.tangible_poses),
                _object_tasks("virtual", virtual_specs, given_v, args.virtual_poses), job, run_settings, args.format)
        t1 = time.perf_counter()
    _print_match(ui, sink, result, run_settings)
    where = f"{ex.workers} {'Dask workers' if args.scheduler else 'processes' if ex.workers > 1 else 'process'}"
    cached = (f"; {result.cached} from the cache, {result.computed} computed; cache {cache.folder}"
              if cache is not None else "")
    ui.note(f"{t1 - t0:.2f} s on {where}{cached}; wrote " + ", ".join(written))
    if doc is not None:
        ui.document(to_json(doc))
    return EXIT_SOME_FAILED if result.failed else 0


def _cmd_select(args) -> int:
    import tempfile

    from ..export.selection import coverage_rows, selection_document, selection_rows
    from ..match.select import EXACT_SUBSETS, best_addition, coverage_curve, helpful_props
    from ..runner.tasks import served_task

    settings = _settings(args, count=args.count, seed=args.seed)
    match_settings = _match_settings(args)
    if match_settings.normalize != "jnd":
        raise ConfigError("--normalize range: select compares the costs of different sets of props, which needs "
                          "a scale that does not change with the set; use --normalize jnd (the default)")
    shelf_specs = object_specs(args.tangible, option="--tangible")
    if not 1 <= args.k <= len(shelf_specs):
        raise ConfigError(f"-k {args.k}: choose between 1 and the {len(shelf_specs)} props of the shelf")
    if args.max_k is not None and args.max_k < 1:
        raise ConfigError(f"--max-k {args.max_k}: give 1 or more")
    out = _out_folder(args)
    scene_specs = object_specs(args.virtual, option="--virtual", split=args.split)
    _check_match_flags(args)
    ui = Presenter(quiet=args.quiet, json_mode=args.json)
    run_settings = {**settings.as_dict(), **match_settings.as_dict(), "units": args.units, "up": args.up,
                    "split": args.split or "none"}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="pinchmatch-select-") as scratch:
        # both passes read the same candidates: with --no-cache, from a cache that lives for this run only
        cache = FeatureCache(scratch if args.no_cache else args.cache)
        job = _match_job(args, settings, match_settings, cache)
        shelf_tasks = _object_tasks("tangible", shelf_specs, [None] * len(shelf_specs), [None] * len(shelf_specs))
        scene_tasks = _object_tasks("virtual", scene_specs, [None] * len(scene_specs), [None] * len(scene_specs))
        rows: dict[int, object] = {}
        with executor(args.jobs, args.scheduler) as ex:
            shelf = run_match(shelf_tasks, scene_tasks, job, ex, step=ui.step, virtual_fn=served_task,
                              on_failure=lambda f: ui.error(f"{f.error}; skipped, going on with the other files"),
                              on_result=rows.__setitem__)
            n = len(shelf.tangibles)
            if args.k > n:
                raise ConfigError(f"-k {args.k}: only {n} props of the shelf could be used; choose at most {n}")
            order = sorted(rows)
            cost = np.array([rows[j].row for j in order]).reshape(len(order), n)
            loud = np.array([rows[j].noticeable for j in order]).reshape(len(order), n)
            if not np.isfinite(cost).any():
                raise ConfigError("no object of the scene can be placed on any prop of the shelf (every "
                                  "registration is refused); check --keep-upright and the objects' up directions")
            with ui.step("choosing the props"):
                curve = coverage_curve(cost, loud, args.objective, max(args.max_k or n, args.k))
                chosen = curve[args.k - 1]
                addition = best_addition(cost, loud, chosen, args.objective)
                helpful = helpful_props(cost, chosen)
            names = [t.name for t in shelf.tangibles]
            shelf_doc = [{"name": t.name, "path": str(t.obj.loaded.path)} for t in shelf.tangibles]
            selection = selection_document(run_settings | {"k": args.k, "objective": args.objective,
                                                           "max_k": args.max_k},
                                           shelf_doc, [rows[j].name for j in order], cost, loud, chosen,
                                           curve[:args.max_k or n], addition, helpful, EXACT_SUBSETS)
            failed = {f.path for f in shelf.failed if f.role == "tangible"}
            usable = [t for t in shelf_tasks if t.label not in failed]  # shelf.tangibles, task by task
            chosen_tasks = [usable[t] for t in chosen.props]
            served = [scene_tasks[j] for j in order]
            with OutputFolder(out) as stage:  # published into OUT as a whole at the end, or not at all
                write_atomic(stage / "selection.json", to_json(selection))
                written = [str(out / "selection.json")]
                if not args.no_figures:
                    from ..export.figures import coverage_figure, png_bytes

                    write_atomic(stage / "figures" / "coverage.png", png_bytes(coverage_figure(selection)))
                    written.append(str(out / "figures" / "coverage.png"))
                plan = None
                if args.objective == "noticeable":  # each object on the prop the selection gives it (quiet first)
                    position = {int(t): i for i, t in enumerate(chosen.props)}
                    plan = {i: ([position[int(chosen.assigned[i])]], None) if chosen.assigned[i] >= 0
                            else ([], "no registration is allowed on any chosen prop") for i in range(len(order))}
                result, doc, sink, more = _write_matches(args, stage, out, ui, ex, chosen_tasks, served, job,
                                                         run_settings, plan=plan)
                written += more
        t1 = time.perf_counter()
    ui.table(_table_rows(coverage_rows(selection), "sizes"), title="coverage: the best set of each size")
    ui.table(_table_rows(selection_rows(selection), "objects"),
             title=f"the {args.k} chosen props: {', '.join(names[t] for t in chosen.props)}")
    if shelf.failed:
        ui.table(_table_rows([("file", "role", "problem")] + [(f.path, f.role, f.error) for f in shelf.failed],
                             "files"), title=f"failed: {len(shelf.failed)} files, left out of the run")
    how = "the best of every subset" if chosen.exact else "greedy and swaps (too many subsets to try every one)"
    ui.note(f"{args.objective} objective {selection['selection']['value']} ({how}); {t1 - t0:.2f} s; wrote "
            + ", ".join(written))
    ui.document(to_json(selection))
    return EXIT_SOME_FAILED if shelf.failed or result.failed else 0


def _cmd_cache(args) -> int:
    cache, ui = FeatureCache(args.cache), Presenter(quiet=args.quiet)
    if args.action == "clear":
        ui.note(f"deleted {cache.clear()} entries from {cache.folder}")
    else:
        info = cache.info()
        ui.note(f"{info.folder}: {info.entries} entries, {info.size_bytes / 2**20:.1f} MiB")
    return 0


def _cmd_demo(args) -> int:
    settings = PinchSettings(count=args.count, seed=args.seed)
    out = _out_folder(args)
    ui = Presenter(quiet=args.quiet, json_mode=args.json)
    t0 = time.perf_counter()
    publisher = OutputFolder(out)
    with publisher as stage:  # published into OUT as a whole at the end, or not at all
        with ui.step("user study", total=len(ORDERS) + 1) as advance:
            started = []

            def starting(note: str) -> None:  # run_study names each part as it starts: the one before is done
                advance(note, done=bool(started))
                started.append(note)

            # the study's objects are its inputs, the same bytes every run: written in place, so the
            # documents can name where they stay
            study = run_study(out / "objects", full=args.full, settings=settings, progress=starting)
        for path in sorted((out / "objects").glob("*.stl")):
            publisher.direct(path)
        t1 = time.perf_counter()
        common = {**settings.as_dict(),
                  "candidate_virtual_poses": "17 heights and all sampled" if args.full else "17 heights",
                  **MatchSettings().as_dict()}
        study_doc = study_document(study, common)
        write_atomic(stage / "study.json", to_json(study_doc))
        scene = study.scene
        job = Job(units="mm", up="z", settings=settings, match=MatchSettings(), figures=not args.no_figures)
        with MatchesSink(stage, "json", scene_stems([v.name for v in scene.virtuals])) as sink:
            sink.start(common, scene.tangibles, dump_poses=False)
            with ui.step("glTF scenes", total=len(scene.virtuals)) as advance:
                for k in range(len(scene.virtuals)):
                    sink.add(k, virtual_result(scene, k, job))
                    advance(scene.virtuals[k].name)
            matches_doc = sink.finish(RunResult(scene.tangibles, {}, [], 0, len(scene.virtuals)))
        written = [f"{out / 'study.json'}", f"{out / 'matches.json'}", f"{sink.scenes} glTF scenes in {out / 'scenes'}"]
        if not args.no_figures:
            from ..export.figures import figure_count, write_figures  # matplotlib: imported when figures are wanted

            total = figure_count(matches_doc, study=study, criteria=False)
            with ui.step("figures", total=total) as advance:
                write_figures(stage, matches_doc, study=study, criteria=False, progress=lambda p: advance(p.name))
            written.append(f"{total + sink.scenes} figures in {out / 'figures'}")
        if not args.no_view:
            with ui.step("viewer page"):
                write_page(stage, document=matches_doc)
            written.append(f"the viewer page {out / 'index.html'}")
        written.append(f"the objects in {out / 'objects'}")
    ui.table(study_rows(study.rows), title="user study", legend=study_legend(study.rows))
    ui.table(matches_rows(matches_doc), title="matches", legend=matches_legend(common))
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
            raise ConfigError(f"{folder}: not a result document of pinchmatch; give the -o folder of a match or "
                              f"demo run, or its {' or '.join(RESULT_DOCUMENTS)}")
        folder = folder.parent
    if folder.is_dir():
        check_writable(folder / "index.html", folder=False)
        recover(folder)  # a run that died while publishing: its result, whole
    path = write_page(folder)
    ui.note(f"wrote {path}")
    if not args.serve:
        if args.open:
            _open_in_browser(path.resolve().as_uri(), ui)
        return 0
    try:
        server = make_server(folder, port=args.port)
    except OSError as exc:
        raise ConfigError(f"--port {args.port}: cannot serve there ({exc.strerror}); try --port 0") from None
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
    return sys.platform in ("darwin", "win32") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _open_in_browser(url: str, ui) -> None:
    import webbrowser

    if not has_display() or not webbrowser.open(url):
        ui.note(f"no display to open a browser on; open {url} in one")


COMMANDS = {"demo": _cmd_demo, "match": _cmd_match, "select": _cmd_select, "view": _cmd_view, "cache": _cmd_cache,
            "poses": _cmd_poses, "features": _cmd_features}
