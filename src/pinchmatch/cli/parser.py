"""The command line's parser: every subcommand and option, with its help and its bounds.

argparse, made to raise :class:`~pinchmatch.errors.ConfigError` (one line, exit 2) instead of
printing usage, to refuse abbreviations and misspellings (naming the closest option), and to take
vectors that start with a minus sign (``--p1 -3,0,1``).
"""

from __future__ import annotations

import argparse
import difflib
import re

from ..errors import ConfigError
from ..version import __version__
from ..mesh.frames import UNITS_MM, UP_VECTORS
from ..cores import default_jobs
from ..config import MatchSettings, PinchSettings
from ..options import field_default, flag_of, offered

#: options whose value is a vector and may start with a minus sign
VECTOR_OPTIONS = ("--p1", "--p2", "--p3", "--com", "--axis")


class _Parser(argparse.ArgumentParser):
    """argparse that raises ConfigError instead of printing usage and exiting, and never takes
    an abbreviation or a misspelling for another option."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message):
        raise ConfigError(f"{self.prog}: {message}; see '{self.prog} --help'")


def check_option_names(parser: argparse.ArgumentParser, argv: list[str]) -> None:
    """Refuse an unknown long option first, naming the closest known one (argparse would
    report a missing required option before it, or take ``--unit`` for ``--units``)."""
    commands = next(a.choices for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    words = [t for t in argv if not t.startswith("-")]
    if not words or words[0] not in commands:
        return
    sub = commands[words[0]]
    known = [o for o in sub._option_string_actions if o.startswith("--")]
    for token in argv[argv.index(words[0]) + 1:]:
        if token == "--":
            break
        name = token.split("=", 1)[0]
        if name.startswith("--") and name not in known:
            close = difflib.get_close_matches(name, known, n=1)
            hint = f"did you mean {close[0]}? " if close else ""
            raise ConfigError(f"{sub.prog}: unknown option {name}; {hint}see '{sub.prog} --help'")


def vector_options(parser: argparse.ArgumentParser) -> set[str]:
    """Every option of ``parser`` and its subcommands whose value is a list of numbers (its metavar
    has a comma: ``X,Y,Z``, ``LOW,HIGH``) or one number, which may start with a minus sign."""
    out = set(VECTOR_OPTIONS)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                out |= vector_options(sub)
        elif action.option_strings and action.nargs is None and (
                "," in str(action.metavar or "") or action.type in (int, float)):
            out |= {o for o in action.option_strings if o.startswith("--")}
    return out


def join_vector_values(argv: list[str], parser: argparse.ArgumentParser | None = None) -> list[str]:
    """Turn ``--hand-start -100,150,300`` into ``--hand-start=-100,150,300`` so that argparse does
    not read a value starting with a minus sign as an option (every option :func:`vector_options`
    finds in ``parser``)."""
    options = vector_options(parser) if parser is not None else set(VECTOR_OPTIONS)
    out: list[str] = []
    i = 0
    while i < len(argv):
        token = argv[i]
        if token in options and i + 1 < len(argv) and re.match(r"^-?[\d.]", argv[i + 1]):
            out.append(f"{token}={argv[i + 1]}")
            i += 2
            continue
        out.append(token)
        i += 1
    return out


def _add_object_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("mesh", nargs="?", help="mesh file (STL, OBJ, PLY, OFF, glTF, GLB)")
    p.add_argument("--example", action="store_true",
                   help="use the built-in example prop instead of MESH")
    _add_pinch_options(p)
    p.add_argument("--com", metavar="X,Y,Z", help="centre of mass override, mm in the file's frame")
    p.add_argument("--axis", metavar="X,Y,Z", help="principal axis override")
    p.add_argument("-o", "--output", metavar="FILE",
                   help="write the result here (default: print it)")
    _add_verbosity(p)


def add_record_options(p: argparse.ArgumentParser, record_type, *groups: str) -> None:
    """The options of a settings record's fields in ``groups``, generated from the fields: flag,
    type, choices, default and help (:mod:`pinchmatch.options`)."""
    for f, opt in offered(record_type):
        if opt.group not in groups:
            continue
        flag, default = flag_of(f, opt), field_default(f)
        shown = f" (default {opt.word(default)})" if opt.kind not in ("flag", "vector",
                                                                      "weights") else ""
        kwargs = {"dest": f.name, "help": opt.help + shown}
        if opt.kind == "flag":
            p.add_argument(flag, action="store_true", **kwargs)
        elif opt.kind in ("vector", "weights"):
            p.add_argument(flag, metavar=opt.metavar, default=None, **kwargs)
        elif opt.kind in ("choice", "onoff"):
            p.add_argument(flag, choices=opt.words(), default=opt.word(default), **kwargs)
        else:
            unit = f.name.rsplit("_", 1)[-1].upper() if f.name.endswith(("_mm", "_deg")) else "X"
            p.add_argument(flag, type=float if opt.kind == "float" else int, default=default,
                           metavar=opt.metavar or ("N" if opt.kind == "int" else unit), **kwargs)


def record_of(record_type, args, **extra):
    """A settings record from the parsed options its fields offer (fields a command does not offer
    keep their defaults), with ``extra`` fields given."""
    values = {}
    for f, opt in offered(record_type):
        if f.name in extra or not hasattr(args, f.name) or opt.kind == "weights":
            continue
        given = getattr(args, f.name)
        if opt.kind == "vector":
            if given is not None:  # not given: the field's default
                values[f.name] = parse_vector(given, flag_of(f, opt), opt.metavar or "X,Y,Z")
            continue
        values[f.name] = opt.value(given)
    return record_type(**values, **extra)


def parse_vector(text: str | None, flag: str, metavar: str = "X,Y,Z") -> tuple | None:
    """The numbers of ``text`` (None for None), as many as ``metavar`` names."""
    if text is None:
        return None
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    count = len(metavar.split(","))
    if len(values) != count:
        example = {"X,Y,Z": "0,150,300", "LOW,HIGH": "0.94,1.14"}.get(metavar,
                                                                      ",".join(["1"] * count))
        words = {2: "two", 3: "three"}.get(count, str(count))
        raise ConfigError(f"{flag} {text}: give {words} numbers {metavar}, as {flag} {example}")
    return values


def _add_pinch_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--units", choices=sorted(UNITS_MM),
                   help="units of the files (default: m for glTF/GLB, mm otherwise)")
    p.add_argument("--up", choices=list(UP_VECTORS),
                   help="the objects' up direction (default: y for glTF/GLB, z otherwise)")
    add_record_options(p, PinchSettings, "pinch")


def _add_support_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--support", choices=("auto", "none"), default="auto",
                   help="auto: each prop stands on the plane through its lowest point (a posed "
                        "prop: the level's "
                        "horizontal under it), and so does each node of a level; no finger, "
                        "fingertip or hand "
                        "reaches below it (default); none: nothing stands, a hand may come from "
                        "anywhere. A "
                        "manifest's support and support_mm come first (docs/manifest.md)")


def _add_sampling_options(p: argparse.ArgumentParser) -> None:
    add_record_options(p, PinchSettings, "sampling")


def _add_cost_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--weights-file", metavar="FILE",
                   help="the weights of a weights.json that 'pinchmatch calibrate' wrote (instead "
                        "of --weights)")
    add_record_options(p, MatchSettings, "cost")


def _add_match_options(p: argparse.ArgumentParser, *, one_to_one: bool = True) -> None:
    add_record_options(p, MatchSettings, "weights")
    _add_cost_options(p)
    add_record_options(p, MatchSettings, "match", *(("assignment",) if one_to_one else ()))
    p.add_argument("--robust", dest="rank", action="store_const", const="worst",
                   help="the same as --rank worst: rank by the worst landing")


def _add_node_options(p: argparse.ArgumentParser) -> None:
    """``--nodes`` and ``--skip-nodes``: which mesh nodes of a level split into its nodes are
    objects."""
    p.add_argument("--nodes", action="append", metavar="GLOB",
                   help="with --split nodes: only the mesh nodes whose name or path matches GLOB "
                        "(repeatable; a manifest entry's nodes come first)")
    p.add_argument("--skip-nodes", action="append", metavar="GLOB",
                   help="with --split nodes: leave out the mesh nodes whose name or path matches "
                        "GLOB (repeatable; with a manifest entry's skip_nodes)")


def _add_placement_options(p: argparse.ArgumentParser) -> None:
    add_record_options(p, MatchSettings, "placement")


def _add_output_options(p: argparse.ArgumentParser, *, figures: bool) -> None:
    """``figures``: the command writes its PNG figures unless told not to (else only when asked)."""
    p.add_argument("--no-view", action="store_true",
                   help="do not write the viewer page OUT/index.html")
    if figures:
        p.add_argument("--no-figures", action="store_true",
                       help="do not write the figures in OUT/figures")
    else:
        p.add_argument("--figures", action="store_true",
                       help="also write PNG figures in OUT/figures: the cost matrix and each "
                            "match's criteria (the page draws the same bars itself)")
        p.add_argument("--no-figures", action="store_true", help="no PNG figures (the default)")
    p.add_argument("--json", action="store_true",
                   help="print the result document to stdout (and nothing else there)")


def _add_worker_options(p: argparse.ArgumentParser, *, work: str = "the per-object work") -> None:
    """The cache and the workers of a command that samples objects: ``work`` is what they run."""
    p.add_argument("--cache", metavar="DIR",
                   help="keep each object's poses and features here (default: the per-user cache, "
                        "$PINCHMATCH_CACHE_DIR or ~/.cache/pinchmatch)")
    p.add_argument("--no-cache", action="store_true",
                   help="compute every object's poses afresh (kept for this run only), store "
                        "nothing")
    p.add_argument("-j", "--jobs", type=int, metavar="N",
                   help=f"objects worked on at once in {work}, in local processes (default: all "
                        f"{default_jobs()} cores)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help=f"run {work} on this Dask scheduler, e.g. tcp://10.0.0.5:8786 "
                        "(needs pinchmatch[dask]; the workers must reach the mesh files)")


def _add_verbosity(p: argparse.ArgumentParser) -> None:
    p.add_argument("-q", "--quiet", action="store_true", help="print only errors")
    p.add_argument("-v", "--verbose", action="store_true",
                   help="log progress; tracebacks on internal errors")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="pinchmatch",
                     description="Match thumb-index pinches between tangible props and virtual "
                                 "objects.")
    parser.add_argument("--version", action="version", version=f"pinchmatch {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    demo = sub.add_parser("demo",
                          help="the method paper's user study, rebuilt in code: 18 rows and the "
                               "scene's matches")
    demo.add_argument("-o", "--output", metavar="OUT", default="pinchmatch-demo",
                      help="folder for study.json, matches.json and the objects (default "
                           "pinchmatch-demo)")
    demo.add_argument("--full", action="store_true",
                      help="candidate virtual poses: every sampled pose as well as the paper's 17")
    demo.add_argument("--design", action="store_true",
                      help="also design a prop for the six virtual objects, starting from the "
                           "study prop's shape, "
                           "and compare it with the study's prop (OUT/props/designed.stl, "
                           "OUT/design.json)")
    demo.add_argument("--budget-s", type=float, default=120.0,
                      help="wall time of --design's search (default 120)")
    _add_cost_options(demo)
    _add_sampling_options(demo)
    _add_output_options(demo, figures=True)
    _add_verbosity(demo)

    match = sub.add_parser("match",
                           help="best tangible, pinch and registration for every virtual object")
    match.add_argument("--tangible", nargs="+", action="extend", required=True, metavar="PATH",
                       help="tangible meshes, folders searched recursively for them, or manifests "
                            "(*.toml: "
                            "per-object units, up, mass, centre of mass and contact regions; "
                            "docs/manifest.md)")
    match.add_argument("--virtual", nargs="+", action="extend", required=True, metavar="PATH",
                       help="virtual meshes, folders or manifests, as for --tangible")
    match.add_argument("--split", choices=("none", "nodes"), default=None,
                       help="nodes: each mesh node of a virtual glTF/GLB scene (a game level) is "
                            "its own object, "
                            "in world coordinates, named by its node (default none; a manifest "
                            "entry's split comes first)")
    _add_node_options(match)
    match.add_argument("--tangible-poses", action="append", metavar="FILE",
                       help="use only these poses on a tangible (JSON, as for poses --poses); once "
                            "per tangible, in order")
    match.add_argument("--virtual-poses", action="append", metavar="FILE",
                       help="use only these poses on a virtual object; once per virtual object, in "
                            "order")
    _add_pinch_options(match)
    _add_support_option(match)
    _add_sampling_options(match)
    _add_match_options(match)
    _add_placement_options(match)
    match.add_argument("-o", "--output", metavar="OUT", default="pinchmatch-out",
                       help="folder for matches.json, the scenes, the page and the figures "
                            "(default pinchmatch-out)")
    _add_worker_options(match)
    match.add_argument("--format", choices=("json", "jsonl"), default="json",
                       help="json: OUT/matches.json (default); jsonl: OUT/matches.jsonl, one line "
                            "per virtual "
                            "object, written as they come (memory stays flat for thousands of "
                            "objects)")
    match.add_argument("--dump-poses", action="store_true",
                       help="list every object's feasible poses in the result (large)")
    _add_output_options(match, figures=False)
    _add_verbosity(match)

    select = sub.add_parser("select",
                            help="the K props of a shelf that together serve a scene best")
    select.add_argument("--tangible", nargs="+", action="extend", required=True, metavar="PATH",
                        help="the shelf: prop meshes, folders searched recursively for them, or "
                             "manifests")
    select.add_argument("--virtual", nargs="+", action="extend", required=True, metavar="PATH",
                        help="the scene: virtual meshes, folders or manifests")
    select.add_argument("-k", type=int, required=True, metavar="K", help="how many props to choose")
    select.add_argument("--objective", choices=("mean", "noticeable", "max"), default="mean",
                        help="mean: the mean best cost (default); noticeable: the count of objects "
                             "with a noticeable "
                             "criterion, ties by the mean; max: the worst object's cost")
    select.add_argument("--max-k", type=int, metavar="M",
                        help="the coverage curve goes up to M props (default: the whole shelf)")
    select.add_argument("--split", choices=("none", "nodes"), default=None,
                        help="nodes: each mesh node of a virtual glTF/GLB scene is its own object "
                             "(default none)")
    _add_node_options(select)
    _add_pinch_options(select)
    _add_support_option(select)
    _add_sampling_options(select)
    _add_match_options(select, one_to_one=False)
    _add_placement_options(select)
    select.add_argument("-o", "--output", metavar="OUT", default="pinchmatch-select",
                        help="folder for selection.json, the coverage figure, and the chosen "
                             "props' matches.json, scenes and page (default pinchmatch-select)")
    _add_worker_options(select)
    select.add_argument("--no-view", action="store_true",
                        help="do not write the viewer page OUT/index.html")
    select.add_argument("--figures", action="store_true",
                        help="also write match's PNG figures (the cost matrix, each match's "
                             "criteria)")
    select.add_argument("--no-figures", action="store_true",
                        help="no PNG figures, not even the coverage curve")
    select.add_argument("--json", action="store_true",
                        help="print selection.json to stdout (and nothing else there)")
    _add_verbosity(select)

    design = sub.add_parser("design",
                            help="new props, ready to print, whose pinches render a scene best")
    design.add_argument("--virtual", nargs="+", action="extend", required=True, metavar="PATH",
                        help="the scene: virtual meshes, folders or manifests")
    design.add_argument("--tangible", nargs="+", action="extend", metavar="PATH",
                        help="a shelf to compare with: the best K of its props, as select finds "
                             "them")
    design.add_argument("-k", type=int, default=1, metavar="K",
                        help="how many props to design together (default 1)")
    design.add_argument("--max-parts", type=int, default=4,
                        help="parts per prop, 1 to 4 (default 4)")
    design.add_argument("--max-height-mm", type=float, default=200.0,
                        help="tallest prop (default 200); its widest part, a box's diagonal "
                             "included, is at most --max-width-mm, the largest pinch width")
    design.add_argument("--no-supports", action="store_true",
                        help="every prop printable standing on its base without supports: no part "
                             "hangs over "
                             "the one below, no downward face flatter than 45 degrees (default: "
                             "overhangs allowed and reported)")
    design.add_argument("--budget-s", type=float, default=120.0,
                        help="wall time of the design's search (default 120); the scene's sampling "
                             "and the final match come on top")
    design.add_argument("--evaluations", type=int, metavar="N",
                        help="judge exactly N candidates, whatever the machine's speed (the budget "
                             "still bounds it)")
    design.add_argument("--split", choices=("none", "nodes"), default=None,
                        help="nodes: each mesh node of a virtual glTF/GLB scene is its own object "
                             "(default none)")
    _add_node_options(design)
    _add_pinch_options(design)
    _add_support_option(design)
    _add_sampling_options(design)
    _add_match_options(design, one_to_one=False)
    design.add_argument("-o", "--output", metavar="OUT", default="pinchmatch-design",
                        help="folder for props/*.stl, design.json, and the scene's matches.json, "
                             "scenes and page on the designed props (default pinchmatch-design)")
    _add_worker_options(design, work="the final match")
    _add_output_options(design, figures=False)
    _add_verbosity(design)

    calibrate = sub.add_parser("calibrate",
                               help="criterion weights fitted to rated pose pairs (a study's CSV)")
    calibrate.add_argument("ratings", metavar="RATINGS.csv",
                           help="one row per rated trial: rating and <criterion>_jnd columns "
                                "(docs/study.md)")
    calibrate.add_argument("--criteria", metavar="NAME,...",
                           help="fit only these criteria (default: the table's <criterion>_jnd "
                                "columns of the default "
                                "criteria whose weights it can determine, said in a note); the "
                                "others keep their defaults (1; com 0)")
    calibrate.add_argument("--seed", type=int, default=0,
                           help="seed of the cross-validation's folds (default 0)")
    calibrate.add_argument("--pooling", choices=("quick", "sum"), default="quick",
                           help="the pooling the weights are for (default quick, as match's "
                                "default)")
    calibrate.add_argument("--hold-out", choices=("placement", "object"), default="placement",
                           help="cross-validate by placement (5 folds, default) or one virtual "
                                "object at a time")
    calibrate.add_argument("--force", action="store_true",
                           help="write the fitted weights even where the defaults rank held-out "
                                "ratings better")
    calibrate.add_argument("-o", "--output", metavar="FILE", default="weights.json",
                           help="the fitted weights, for match --weights-file (default "
                                "weights.json)")
    calibrate.add_argument("--json", action="store_true",
                           help="print weights.json to stdout (and nothing else there)")
    _add_verbosity(calibrate)

    cache = sub.add_parser("cache",
                           help="the cache of poses and features: where, how big; clear it")
    cache.add_argument("action", choices=("info", "clear"),
                       help="info: folder, entries, size; clear: delete them")
    cache.add_argument("--cache", metavar="DIR",
                       help="the cache folder (default: the per-user cache)")
    _add_verbosity(cache)

    prop = sub.add_parser("prop", help="make a prop from a phone scan (pinchmatch prop import)")
    prop.add_argument("action", choices=("import",),
                      help="import: clean a scan and add it to a props folder's manifest")
    prop.add_argument("scan", metavar="SCAN",
                      help="the scan: USDZ/USD, GLB/glTF, OBJ, PLY (mesh or point cloud), STL")
    prop.add_argument("-o", "--out", metavar="PROPS_DIR", required=True,
                      help="the props folder: NAME.stl goes there, its entry into props.toml")
    prop.add_argument("--name", help="the prop's name (default: the scan's file name)")
    prop.add_argument("--units", choices=sorted(UNITS_MM),
                      help="the scan's unit where its file has none (OBJ, PLY, STL; default mm)")
    prop.add_argument("--up", choices=list(UP_VECTORS),
                      help="the scan's up where its file has none (OBJ, PLY, STL; default z)")
    prop.add_argument("--measured-mm", metavar="AXIS=VALUE",
                      help="a ruler or caliper reading of the object, mm: height=, x=, y= or "
                           "diameter=; the scan is scaled to it")
    prop.add_argument("--mass-g", type=float, help="the prop's mass, grams")
    prop.add_argument("--faces", type=int, default=None,
                      help="at most this many faces in the prop's mesh (default 40000)")
    _add_verbosity(prop)

    view = sub.add_parser("view",
                          help="write OUT/index.html, the viewer page of a match or demo run, and "
                               "serve it")
    view.add_argument("folder", metavar="OUT",
                      help="the -o folder of a 'pinchmatch match' or 'pinchmatch demo' run, "
                                                    "or its matches.json (.jsonl)")
    view.add_argument("--serve", action="store_true",
                      help="serve OUT on 127.0.0.1 and print the address")
    view.add_argument("--open", action="store_true",
                      help="open the page in your web browser (where there is a display)")
    view.add_argument("--port", type=int, default=0, help="port for --serve (default: a free one)")
    _add_verbosity(view)

    poses = sub.add_parser("poses", help="feasible pinches of one mesh, with their haptic features")
    _add_object_options(poses)
    _add_sampling_options(poses)
    poses.add_argument("--poses", metavar="FILE",
                       help='check these pinches instead: JSON list of {"p1_mm": [...], '
                                                       '"p2_mm": [...]} (with --grasp tripod: of '
                                                       '{"contacts_mm": '
                                                       '[[...], [...], [...]]}, thumb, index, '
                                                       'middle)')
    poses.add_argument("--format", choices=("json", "csv"), default="json",
                       help="output format (default json)")

    features = sub.add_parser("features",
                              help="the features of one given pinch (or tripod, with --p3), and "
                                   "whether it is feasible")
    _add_object_options(features)
    features.add_argument("--p1", required=True, metavar="X,Y,Z", help="first contact, mm")
    features.add_argument("--p2", required=True, metavar="X,Y,Z", help="second contact, mm")
    features.add_argument("--p3", metavar="X,Y,Z",
                          help="a third contact, mm: the grasp is then a tripod, --p1 the thumb's "
                               "contact, --p2 the index's and --p3 the middle finger's")
    return parser
