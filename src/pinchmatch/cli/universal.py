"""The universal-prop commands: ``pinchmatch select`` (the best props of a shelf for a scene) and
``pinchmatch design`` (new props, ready to print, for a scene)."""

from __future__ import annotations

import dataclasses

import tempfile
import time
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..export.documents import to_json
from ..export.folder import OutputFolder
from ..files import write_atomic
from ..mesh.manifest import object_specs
from ..runner.cache import FeatureCache
from ..runner.executors import executor
from ..runner.matching import run_match
from .console import Presenter
from .runs import (
    EXIT_SOME_FAILED,
    check_match_flags,
    check_placement,
    match_job,
    match_settings_of,
    object_tasks,
    out_folder,
    pinch_settings_of,
    placed_in_level,
    standing,
    table_rows,
    virtual_level_specs,
    write_matches,
)


def _jnd_settings(args, why: str):
    """The pinch settings, the match settings and the run's settings record of a command that
    compares costs across sets of props, which needs the scale of the noticeable differences
    (``why`` says so)."""
    settings = pinch_settings_of(args)
    matching = match_settings_of(args)
    if matching.normalize != "jnd":
        raise ConfigError(f"--normalize range: {why}, which needs a scale that does not change "
                          "with the props; use --normalize jnd (the default)")
    run_settings = {**settings.as_dict(), **matching.as_dict(), "units": args.units, "up": args.up,
                    "split": args.split or "none", "support": args.support}
    return settings, matching, run_settings


def cmd_select(args) -> int:
    """``pinchmatch select``: see docs/matching.md."""
    from ..export.selection import coverage_rows, selection_document, selection_rows
    from ..match.select import (
        EXACT_SUBSETS,
        best_addition,
        coverage_curve,
        helpful_props,
    )
    from ..runner.tasks import served_task

    settings, match_settings, run_settings = _jnd_settings(args,
                                                           "select compares the costs of different "
                                                           "sets of props")
    shelf_specs = standing(object_specs(args.tangible, option="--tangible"), args, "tangible")
    if not 1 <= args.k <= len(shelf_specs):
        raise ConfigError(f"-k {args.k}: choose between 1 and the {len(shelf_specs)} props of the "
                          "shelf")
    if args.max_k is not None and args.max_k < 1:
        raise ConfigError(f"--max-k {args.max_k}: give 1 or more")
    if args.max_k is not None and args.max_k < args.k:
        raise ConfigError(f"--max-k {args.max_k}: the coverage curve must reach -k {args.k}; give "
                          f"--max-k {args.k} or more")
    out = out_folder(args)
    left_out: list[str] = []
    scene_specs = standing(virtual_level_specs(args, left_out), args, "virtual")
    shelf_specs = placed_in_level(shelf_specs, scene_specs, args.up)
    check_match_flags(args)
    ui = Presenter(quiet=args.quiet, json_mode=args.json)
    for note in left_out:
        ui.note(note)
    check_placement(match_settings, shelf_specs, scene_specs, ui, units=args.units, up=args.up)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="pinchmatch-select-") as scratch:
        # both passes read the same candidates: with --no-cache, from a cache that lives for this
        # run only
        cache = FeatureCache(scratch if args.no_cache else args.cache)
        job = match_job(args, settings, match_settings, cache)
        shelf_tasks = object_tasks("tangible", shelf_specs, [None] * len(shelf_specs),
                                   [None] * len(shelf_specs))
        scene_tasks = object_tasks("virtual", scene_specs, [None] * len(scene_specs),
                                   [None] * len(scene_specs))
        rows: dict[int, object] = {}
        with executor(args.jobs, args.scheduler) as ex:
            shelf = run_match(shelf_tasks, scene_tasks, job, ex, step=ui.step,
                              virtual_fn=served_task,
                              on_failure=lambda f: ui.error(f"{f.error}; skipped, going on with "
                                                            "the other files"),
                                                            on_result=rows.__setitem__)
            n = len(shelf.tangibles)
            if args.k > n:
                raise ConfigError(f"-k {args.k}: only {n} props of the shelf could be used; choose "
                                  f"at most {n}")
            order = sorted(rows)
            cost = np.array([rows[j].row for j in order]).reshape(len(order), n)
            loud = np.array([rows[j].noticeable for j in order]).reshape(len(order), n)
            if not np.isfinite(cost).any():
                raise ConfigError("no object of the scene can be placed on any prop of the shelf "
                                  "(every "
                                  "registration is refused); check --keep-upright and the objects' "
                                  "up directions")
            with ui.step("choosing the props"):
                curve = coverage_curve(cost, loud, objective=args.objective,
                                       max_k=max(args.max_k or n, args.k))
                chosen = curve[args.k - 1]
                addition = best_addition(cost, loud, chosen, args.objective)
                helpful = helpful_props(cost, chosen)
            names = [t.name for t in shelf.tangibles]
            shelf_doc = [{"name": t.name, "path": str(t.obj.loaded.path)} for t in shelf.tangibles]
            selection = selection_document(run_settings | {"k": args.k, "objective": args.objective,
                                                           "max_k": args.max_k},
                                           shelf_doc, [rows[j].name for j in order], cost, loud,
                                           chosen, curve[:args.max_k or n], addition, helpful,
                                           EXACT_SUBSETS)
            failed = {f.path for f in shelf.failed if f.role == "tangible"}
            # shelf.tangibles, task by task
            usable = [t for t in shelf_tasks if t.label not in failed]
            chosen_tasks = [usable[t] for t in chosen.props]
            served = [scene_tasks[j] for j in order]
            with OutputFolder(out) as stage:
                # published into OUT as a whole at the end, or not at all
                write_atomic(stage / "selection.json", to_json(selection))
                written = [str(out / "selection.json")]
                if not args.no_figures:
                    from ..export.figures import coverage_figure, png_bytes

                    write_atomic(stage / "figures" / "coverage.png",
                                 png_bytes(coverage_figure(selection)))
                    written.append(str(out / "figures" / "coverage.png"))
                plan = None
                if args.objective == "noticeable":
                    # each object on the prop the selection gives it (quiet first)
                    position = {int(t): i for i, t in enumerate(chosen.props)}
                    plan = {i: ([position[int(chosen.assigned[i])]], None) if chosen.assigned[i]
                            >= 0
                            else ([], "no registration is allowed on any chosen prop")
                            for i in range(len(order))}
                result, _doc, _sink, more = write_matches(args, stage, out, ui, ex, chosen_tasks,
                                                          served, job,
                                                         run_settings, plan=plan)
                written += more
        t1 = time.perf_counter()
    ui.table(table_rows(coverage_rows(selection), "sizes"),
             title="coverage: the best set of each size")
    ui.table(table_rows(selection_rows(selection), "objects"),
             title=f"the {args.k} chosen props: {', '.join(names[t] for t in chosen.props)}")
    if shelf.failed:
        ui.table(table_rows([("file", "role", "problem")]
                            + [(f.path, f.role, f.error) for f in shelf.failed],
                             "files"),
                             title=f"failed: {len(shelf.failed)} files, left out of the run")
    how = ("the best of every subset" if chosen.exact
           else "greedy and swaps (too many subsets to try every one)")
    ui.note(f"{args.objective} objective {selection['selection']['value']} ({how}); {t1 - t0:.2f} "
            "s; wrote "
            + ", ".join(written))
    ui.document(to_json(selection))
    return EXIT_SOME_FAILED if shelf.failed or result.failed else 0


def cmd_design(args) -> int:
    """``pinchmatch design``: see docs/matching.md."""
    from ..errors import PinchmatchError
    from ..export.design import design_document
    from ..mesh.stacks import stack_mesh
    from ..runner.cache import cached_candidates
    from ..runner.design import DesignSettings, design_props

    settings, matching, run_settings = _jnd_settings(args,
                                                     "a designed prop is judged against the scene "
                                                     "alone")
    design = DesignSettings(k=args.k, max_parts=args.max_parts, max_height_mm=args.max_height_mm,
                            stand=args.support == "auto",
                            max_width_mm=settings.max_width_mm,
                            budget_s=args.budget_s, seed=args.seed, evaluations=args.evaluations,
                            supports=not args.no_supports)
    design.check()
    left_out: list[str] = []
    scene_specs = standing(virtual_level_specs(args, left_out), args, "virtual")
    shelf_specs = standing(object_specs(args.tangible, option="--tangible"), args,
                           "tangible") if args.tangible else []
    shelf_specs = placed_in_level(shelf_specs, scene_specs, args.up)
    if shelf_specs and not 1 <= args.k <= len(shelf_specs):
        raise ConfigError(f"-k {args.k}: the shelf to compare with has {len(shelf_specs)} props; "
                          "give at most that")
    out = out_folder(args)
    check_match_flags(args)
    ui = Presenter(quiet=args.quiet, json_mode=args.json)
    for note in left_out:
        ui.note(note)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="pinchmatch-design-") as scratch:
        cache = FeatureCache(scratch if args.no_cache else args.cache)
        virtuals, failures, used = [], [], []
        with ui.step("scene: poses and features", len(scene_specs)) as advance:
            for spec in scene_specs:
                try:
                    # at the full count, in the run's cache: the final match reads them back
                    virtuals.append(cached_candidates(spec.with_defaults(units=args.units,
                                                                         up=args.up), cache=cache,
                                                      settings=settings))
                    used.append(spec)
                except PinchmatchError as exc:
                    failures.append(exc.cli_message())
                    if len(scene_specs) > 1:
                        ui.error(f"{exc.cli_message()}; skipped, going on with the other files")
                advance(spec.display_name)
        if not virtuals:
            raise ConfigError(failures[0] if len(failures) == 1 else
                              f"none of the {len(failures)} scene files could be used (first: "
                              f"{failures[0]}); fix or remove them")
        job = match_job(args, settings, matching, cache)
        scene_tasks = object_tasks("virtual", used, [None] * len(used), [None] * len(used))
        shelf, seeds = None, ()
        if shelf_specs:  # the shelf's best props first: the search starts from their shapes
            with executor(args.jobs, args.scheduler) as ex:
                shelf, seeds = _best_shelf_subset(args, ui, ex, job, shelf_specs, scene_tasks,
                                                  design.k)
        with ui.step("designing", None) as advance:
            found = design_props(virtuals, design, match=matching, pinch=settings, seeds=seeds,
                                 progress=lambda done, total,
                                 note: advance(f"{done} judged: {note}", done=False))
        t1 = time.perf_counter()
        publisher = OutputFolder(out)
        with publisher as stage:
            props = []
            for i, stack in enumerate(found.best.stacks, start=1):
                path = out / "props" / f"prop_{i}.stl"
                publisher.write_direct(path, stack_mesh(stack).export(file_type="stl"))
                props.append(path)
            # the props are read as they were written, in mm and standing on +Z, whatever the
            # scene's --units and --up
            prop_specs = [dataclasses.replace(s, units="mm", up="z")
                          for s in standing(object_specs([str(p) for p in props],
                                                         option="--tangible"), args,
                                            "tangible")]
            prop_tasks = object_tasks("tangible", prop_specs, [None] * len(props),
                                      [None] * len(props))
            with executor(args.jobs, args.scheduler) as ex:
                result, doc, _sink, written = write_matches(args, stage, out, ui, ex, prop_tasks,
                                                            scene_tasks, job,
                                                           run_settings)
            document = design_document(run_settings | {"k": design.k, "max_parts": design.max_parts,
                                                       "max_height_mm": design.max_height_mm,
                                                       "max_width_mm": design.max_width_mm,
                                                       "budget_s": design.budget_s,
                                                       "evaluations": design.evaluations,
                                                       "supports": design.supports,
                                                       "search_count": design.search_count},
                                       found, props, out, doc, shelf,
                                       seconds=time.perf_counter() - t0)
            write_atomic(stage / "design.json", to_json(document))
            written = [f"{len(props)} props in {out / 'props'}", str(out / "design.json")] + written
        t2 = time.perf_counter()
    rows = [("virtual", "prop", "cost", "noticeable")] + [
        (o["virtual"], o["prop"] or "-", "-" if o["cost"] is None else o["cost"],
         ", ".join(o["noticeable"]) or "-")
        for o in document["objects"]]
    ui.table(table_rows(rows, "objects"),
             title=f"the scene on the designed prop{'s' if design.k > 1 else ''}")
    if shelf is not None:
        c = document["shelf_comparison"]
        ui.note(f"designed: mean cost {document['mean_cost']}, {document['noticeable_count']} "
                f"noticeable; best {design.k} "
                f"of the shelf ({', '.join(c['props'])}): mean cost {c['mean_cost']}, "
                f"{c['noticeable_count']} noticeable")
    ui.note(f"{found.evaluations} candidates judged in {t1 - t0:.1f} s; {t2 - t0:.1f} s in all "
            f"(budget {design.budget_s:g} s); wrote " + ", ".join(written))
    ui.document(to_json(document))
    return EXIT_SOME_FAILED if failures or result.failed else 0


def _best_shelf_subset(args, ui, ex, job, shelf_specs, scene_tasks, k: int) -> tuple[dict, tuple]:
    """The best ``k`` props of a shelf for the scene, as ``select`` finds them, for the comparison;
    and the stacks fitted to them, standing on their up
    (:func:`pinchmatch.mesh.stack_fit.fitted_stack`), where the design's search starts."""
    import trimesh

    from ..mesh.stack_fit import fitted_stack

    from ..match.select import select_props
    from ..runner.tasks import served_task

    rows: dict[int, object] = {}
    shelf_tasks = object_tasks("tangible", shelf_specs, [None] * len(shelf_specs),
                               [None] * len(shelf_specs))
    run = run_match(shelf_tasks, scene_tasks, job, ex, step=ui.step, virtual_fn=served_task,
                    on_failure=lambda f: ui.error(f"{f.error}; skipped, going on with the other "
                                                  "files"),
                    on_result=rows.__setitem__)
    n = len(run.tangibles)
    cost = np.array([rows[j].row for j in sorted(rows)]).reshape(len(rows), n)
    loud = np.array([rows[j].noticeable for j in sorted(rows)]).reshape(len(rows), n)
    chosen = select_props(cost, loud, min(k, n), objective="mean")
    seeds = []
    for t in chosen.props:
        loaded = run.tangibles[t].obj.loaded
        mesh = loaded.mesh.copy()
        mesh.apply_transform(trimesh.geometry.align_vectors(np.asarray(loaded.up, dtype=np.float64),
                                                            [0.0, 0.0, 1.0]))
        seeds.append(fitted_stack(mesh, parts=args.max_parts))
    return {"props": [run.tangibles[t].name for t in chosen.props], "mean_cost": chosen.mean_cost,
            "noticeable_count": int(chosen.noticeable[chosen.assigned >= 0].sum()),
            "exact": chosen.exact,
            "objects": {rows[j].name: float(chosen.cost[i])
                        for i, j in enumerate(sorted(rows))}}, tuple(seeds)


def demo_design(publisher, stage: Path, objects: Path, settings, *, budget_s: float, seed: int,
                ui) -> dict:
    """``pinchmatch demo --design``: a prop designed for the study's six virtual objects, its search
    starting from the study prop's shape (its fitted stack, as ``design`` starts from a shelf's
    best), judged against the study's own prop the same way (both sampled with the demo's settings,
    every feasible pinch, the exact search against the six objects' sampled poses). Writes
    OUT/props/designed.stl and OUT/design.json; returns the comparison."""
    import trimesh

    from ..mesh.stack_fit import fitted_stack
    from ..export.design import prop_record
    from ..config import Config
    from ..match.scene import match_one
    from ..match.search import MatchSettings, cost_model
    from ..mesh.stacks import stack_mesh
    from ..runner.cache import cached_candidates
    from ..runner.design import DesignSettings, design_props

    virtual_paths = sorted(objects.glob("vo*.stl"))
    study_prop = next(objects.glob("tangible_*.stl"))
    matching = MatchSettings()
    with ui.step("design: the scene's poses", len(virtual_paths)) as advance:
        virtuals = []
        for p in virtual_paths:
            virtuals.append(cached_candidates(str(p), cache=None, settings=settings))
            advance(p.name)
    design = DesignSettings(k=1, max_width_mm=settings.max_width_mm, budget_s=budget_s, seed=seed)
    with ui.step("designing", None) as advance:
        found = design_props(virtuals, design, match=matching, pinch=settings,
                             seeds=(fitted_stack(trimesh.load(study_prop, force="mesh")),),
                             progress=lambda done, total,
                             note: advance(f"{done} judged: {note}", done=False))
    designed_path = publisher.out / "props" / "designed.stl"
    publisher.write_direct(designed_path, stack_mesh(found.best.stacks[0]).export(file_type="stl"))
    model = cost_model(matching, virtuals)
    judged = {}
    for name, path in (("study prop", study_prop), ("designed prop", designed_path)):
        prop = cached_candidates(str(path), cache=None, settings=settings)
        # judged as match judges (refined unless --refine off); the design's own search ranks its
        # many candidate props on the sampled poses
        rows = [match_one([prop], v, Config(settings, matching), model=model, details=False)
                for v in virtuals]
        judged[name] = {"file": path.relative_to(publisher.out).as_posix(),
                        "costs": {v.name: float(vm.row[0]) for v, vm in zip(virtuals, rows)},
                        "mean_cost": float(np.mean([vm.row[0] for vm in rows])),
                        "noticeable_count": int(sum(bool(vm.row_noticed[0]) for vm in rows))}
    document = {"schema": "pinchmatch.design/1", "settings": settings.as_dict()
                | {"budget_s": budget_s, "seed": seed},
                "props": [prop_record(found.best.stacks[0], designed_path, publisher.out)],
                "comparison": judged, "evaluations": found.evaluations,
                "search_seconds": round(found.seconds, 2),
                "no_worse_than_the_study_prop": judged["designed prop"]["mean_cost"]
                <= judged["study prop"]["mean_cost"] + 1e-12}
    write_atomic(stage / "design.json", to_json(document))
    return document
