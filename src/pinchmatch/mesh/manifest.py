"""Object manifests: per-object loading options, mass and contact regions, in a TOML file.

A manifest lists objects (``[[object]]`` tables) with the file each comes from and what one
``--units`` and ``--up`` per run cannot say: props in millimetres beside assets in metres, a
prop with a lead weight inside, a scan with an artefact. Every key but ``file`` is optional; the
manifest's ``[defaults]`` table, then the command line's options, fill in what an object leaves
out. The format is in ``docs/manifest.md`` with a JSON Schema in ``docs/manifest.schema.json``::

    [defaults]
    units = "m"

    [[object]]
    file = "props/can.stl"           # relative to the manifest's folder
    name = "can"
    units = "mm"
    up = "z"
    com_mm = [0, 0, 38]              # in the file's frame, mm
    axis = [0, 0, 1]
    mass_g = 350
    exclude = [{ center_mm = [0, 0, 76], radius_mm = 12 }]
    only = [{ min_mm = [-40, -40, 10], max_mm = [40, 40, 60] }]

    [[object]]
    file = "level.glb"
    split = "nodes"                  # every mesh node its own object

The whole manifest is checked before any work: :func:`read_manifest` raises one
:class:`~pinchmatch.errors.ConfigError` listing every problem, one line each, naming the file,
the object and the key.
"""

from __future__ import annotations

import fnmatch

import difflib
import math
import os
import stat
import tomllib
from dataclasses import replace
from pathlib import Path

from ..config import finite_number
from ..errors import ConfigError, InternalError
from .described import read_shape, shape_file
from .frames import UNITS_MM, UP_VECTORS
from .furniture import Furniture, level_furniture
from .load import GLTF_TYPES, MESH_EXTENSIONS, mesh_files, read_level
from .object_spec import ObjectSpec, spec_from_dict, spec_to_dict  # noqa: F401 (re-exported)
from .regions import ContactRegions, Region

MANIFEST_SUFFIX = ".toml"
#: a centre of mass farther than this from the file's origin (mm, 1 km) is not an object's
MAX_COORDINATE_MM = 1e6
#: the keys of an object; ``[defaults]`` takes all but ``file`` and ``name``
OBJECT_KEYS = ("file", "shape", "name", "units", "up", "com_mm", "axis", "mass_g", "split",
               "exclude", "only", "pose", "support", "support_mm", "nodes", "skip_nodes", "scan")
DEFAULT_KEYS = tuple(k for k in OBJECT_KEYS if k not in ("file", "shape", "name", "pose", "scan"))
#: the keys of an object's ``scan`` table (written by ``pinchmatch prop import``)
SCAN_KEYS = ("noise_mm", "residual_mm", "scale_verified")
#: a scan noisier than this (mm RMS along the normal) is no surface to pinch
MAX_SCAN_NOISE_MM = 10.0
#: a pose's quaternion may be this far from length 1 (then it is normalised); farther, it is no
#: rotation
QUATERNION_TOLERANCE = 1e-3
SPLITS = ("none", "nodes")
#: a manifest is a hand-written list: at most this big
MAX_MANIFEST_BYTES = 4 * 2**20
#: the heaviest object a pinch lifts (g), with margin
MAX_MASS_G = 20_000.0


class _Problems:
    """Problems found in one manifest, each one line: 'FILE: object K (NAME): KEY: what; fix'."""

    def __init__(self, path: Path):
        self.path, self.lines = path, []

    def add(self, where: str, key: str | None, text: str) -> None:
        self.lines.append(f"{self.path}: {where}{f': {key}' if key else ''}: {text}")

    def raise_any(self) -> None:
        if self.lines:
            raise ConfigError("\n".join(self.lines))


def _number(value) -> bool:
    return finite_number(value)


def _vector(value) -> tuple | None:
    if isinstance(value, list) and len(value) == 3 and all(_number(v) for v in value):
        return tuple(float(v) for v in value)
    return None


def _regions(entries, where: str, key: str, problems: _Problems) -> tuple:
    if not isinstance(entries, list):
        problems.add(where, key,
                     "must be a list of regions, e.g. [{ center_mm = [0, 0, 10], radius_mm = 5 }]")
        return ()
    out = []
    for k, item in enumerate(entries):
        at = f"{key}[{k}]"
        keys = set(item) if isinstance(item, dict) else set()
        if keys == {"center_mm", "radius_mm"}:
            centre, radius = _vector(item["center_mm"]), item["radius_mm"]
            if centre is None or not _number(radius) or radius <= 0:
                problems.add(where, at,
                             "a sphere needs center_mm = [x, y, z] and radius_mm > 0, in mm")
            else:
                out.append(Region.sphere(centre, radius))
        elif keys == {"min_mm", "max_mm"}:
            lo, hi = _vector(item["min_mm"]), _vector(item["max_mm"])
            if lo is None or hi is None or not all(a < b for a, b in zip(lo, hi)):
                problems.add(where, at,
                             "a box needs min_mm = [x, y, z] below max_mm = [x, y, z] on every "
                             "axis, in mm")
            else:
                out.append(Region.box(lo, hi))
        else:
            problems.add(where, at,
                         "a region is a sphere { center_mm, radius_mm } or a box { min_mm, max_mm "
                         "}")
    return tuple(out)


def _unknown(table: dict, allowed: tuple, where: str, problems: _Problems) -> None:
    for key in table:
        if key not in allowed:
            close = difflib.get_close_matches(str(key), allowed, n=1)
            hint = f"did you mean {close[0]!r}?" if close else f"the keys are {', '.join(allowed)}"
            problems.add(where, str(key), f"unknown key; {hint}")


def _options(table: dict, where: str, problems: _Problems) -> dict:
    """The checked values of the optional keys of an object or of ``[defaults]``."""
    out = {}
    if "name" in table:
        if isinstance(table["name"], str) and table["name"].strip():
            out["name"] = table["name"].strip()
        else:
            problems.add(where, "name", "must be a non-empty string")
    if "units" in table:
        if table["units"] in UNITS_MM:
            out["units"] = table["units"]
        else:
            problems.add(where, "units",
                         f"unknown unit {table['units']!r}; use one of {', '.join(UNITS_MM)}")
    if "up" in table:
        up = str(table["up"]).strip().lower() if isinstance(table["up"], str) else None
        if up in UP_VECTORS:
            out["up"] = up
        else:
            problems.add(where, "up",
                         f"unknown up direction {table['up']!r}; use one of "
                         f"{', '.join(UP_VECTORS)}")
    for key in ("com_mm", "axis"):
        if key in table:
            v = _vector(table[key])
            if v is not None and key == "com_mm" and max(abs(c) for c in v) > MAX_COORDINATE_MM:
                problems.add(where, key,
                             f"must be three numbers [x, y, z] within {MAX_COORDINATE_MM:g} mm of "
                             "the file's origin")
                continue
            if v is None or (key == "axis" and not any(v)):
                problems.add(where, key, "must be three numbers [x, y, z]"
                             + (", not all zero" if key == "axis" else
                                                                             ", in mm in the "
                                                                             "file's frame"))
            else:
                out[key] = v
    if "mass_g" in table:
        m = table["mass_g"]
        if _number(m) and 0 < m <= MAX_MASS_G:
            out["mass_g"] = float(m)
        else:
            problems.add(where, "mass_g",
                         f"must be a number of grams above 0 and at most {MAX_MASS_G:g}")
    if "split" in table:
        if table["split"] in SPLITS:
            out["split"] = table["split"]
        else:
            problems.add(where, "split",
                         f"unknown split {table['split']!r}; use one of {', '.join(SPLITS)}")
    for key in ("exclude", "only"):
        if key in table:
            out[key] = _regions(table[key], where, key, problems)
    for key in ("nodes", "skip_nodes"):
        if key in table:
            globs = [table[key]] if isinstance(table[key], str) else table[key]
            if isinstance(globs, list) and globs and all(isinstance(g, str) and g.strip()
                                                         for g in globs):
                out[key] = tuple(globs)
            else:
                problems.add(where, key,
                             "must be a glob of node names or paths, or a list of them, as "
                                         f'{key} = ["counter*", "Kitchen/Wall_?"]')
    if "scan" in table:
        out |= _scan(table["scan"], where, problems)
    if "pose" in table:
        pose = _pose(table["pose"], where, problems)
        if pose is not None:
            out["pose"] = pose
    if "support" in table and "support_mm" in table:
        problems.add(where, "support",
                     "give support = \"none\" (held in the hand) or support_mm (the height of "
                                       "what it stands on), not both")
    elif "support" in table:
        if table["support"] in ("none", "auto"):
            out["support"] = table["support"]
        else:
            problems.add(where, "support",
                         "must be \"none\" (a prop held in the hand) or \"auto\" (standing on "
                                           "the plane through its lowest point); give a height as "
                                           "support_mm")
    elif "support_mm" in table:
        height = table["support_mm"]
        if _number(height) and abs(height) <= MAX_COORDINATE_MM:
            out["support"] = float(height)
        else:
            problems.add(where, "support_mm", f"must be a height in mm along the prop's up, within "
                                              f"{MAX_COORDINATE_MM:g} mm of its origin")
    return out


def _scan(value, where: str, problems: _Problems) -> dict:
    """The spec's fields of a ``scan`` table: ``{ noise_mm = 0.6, residual_mm = 0.1,
    scale_verified = false }``."""
    fix = ("must be a table as { noise_mm = 0.6, residual_mm = 0.1, scale_verified = false }: the "
           f"noise its smoothing took out and the error it left, in mm RMS (0 to "
           f"{MAX_SCAN_NOISE_MM:g}), and whether its scale was measured")
    if not isinstance(value, dict) or set(value) - set(SCAN_KEYS):
        problems.add(where, "scan", fix)
        return {}
    noise, left = value.get("noise_mm"), value.get("residual_mm")
    verified = value.get("scale_verified")
    if any(n is not None and not (_number(n) and 0 <= n <= MAX_SCAN_NOISE_MM) for n in (noise, left)
           ) or (verified is not None and not isinstance(verified, bool)):
        problems.add(where, "scan", fix)
        return {}
    return {"scan_noise_mm": None if noise is None else float(noise),
            "scan_residual_mm": None if left is None else float(left), "scale_verified": verified}


def _pose(value, where: str, problems: _Problems) -> tuple | None:
    """A prop's pose in the room: ((x, y, z) mm, unit quaternion (x, y, z, w)), or None with its
    problem."""
    example = "e.g. pose = { position_mm = [0, 0, 0], quaternion_xyzw = [0, 0, 0, 1] }"
    if (not isinstance(value, dict) or "position_mm" not in value
            or set(value) - {"position_mm", "quaternion_xyzw"}):
        problems.add(where, "pose",
                     f"must be a table of position_mm and, optionally, quaternion_xyzw; {example}")
        return None
    position = _vector(value["position_mm"])
    if position is None or max(abs(c) for c in position) > MAX_COORDINATE_MM:
        problems.add(where, "pose",
                     "position_mm must be three numbers [x, y, z] in mm within "
                     f"{MAX_COORDINATE_MM:g} mm of the level's origin")
        return None
    q = value.get("quaternion_xyzw", [0.0, 0.0, 0.0, 1.0])
    if not (isinstance(q, list) and len(q) == 4 and all(_number(c) for c in q)):
        problems.add(where, "pose", f"quaternion_xyzw must be four numbers [x, y, z, w]; {example}")
        return None
    length = math.sqrt(sum(c * c for c in q))
    if abs(length - 1.0) > QUATERNION_TOLERANCE:
        problems.add(where, "pose",
                     f"quaternion_xyzw {q} has length {length:.4g}, so it is not a rotation (a "
                     "rigid pose turns by a unit quaternion); give one of length 1, [0, "
                                    "0, 0, 1] for none")
        return None
    return position, tuple(float(c) / length for c in q)


def read_manifest(path: str | os.PathLike) -> list[ObjectSpec]:
    """The objects a manifest lists, checked; every problem in one ConfigError, one line each.

    Parameters
    ----------
    path : path-like
        A TOML manifest.

    Returns
    -------
    list of ObjectSpec
        The objects it lists, with their options.

    Examples
    --------
    >>> [(spec.name, spec.units, spec.mass_g) for spec in read_manifest(props_toml)]
    [('box', None, 120.0), ('can', 'm', None)]
    """
    path = Path(path)
    try:
        if not stat.S_ISREG(path.stat().st_mode):
            raise ConfigError(f"{path}: not a regular file (a folder, a device or a pipe); give a "
                              "manifest file")
        if path.stat().st_size > MAX_MANIFEST_BYTES:
            raise ConfigError(f"{path}: a manifest of more than {MAX_MANIFEST_BYTES // 2**20} MiB; "
                              "split the list into several manifests")
        document = tomllib.loads(path.read_bytes().decode("utf-8-sig"))
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such manifest; check the path") from None
    except OSError as exc:
        raise ConfigError(f"{path}: the manifest cannot be read ({exc.strerror or exc}); check its "
                          "permissions") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{path}: the manifest is not UTF-8 text; save it as UTF-8 "
                          "TOML") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML ({exc}); fix the manifest (see "
                          "docs/manifest.md)") from None
    except ValueError as exc:  # an integer of thousands of digits
        raise ConfigError(f"{path}: a value the manifest cannot hold ({str(exc)[:60]}); fix the "
                          "manifest (see docs/manifest.md)") from None
    except RecursionError:
        raise ConfigError(f"{path}: nested too deep to be a manifest; fix the manifest (see "
                          "docs/manifest.md)") from None
    problems = _Problems(path)
    _unknown(document, ("defaults", "object", "user_mm"), "top level", problems)
    if "user_mm" in document and _user(document["user_mm"]) is None:
        problems.add("top level", "user_mm",
                     "must be where the user stands: three numbers [x, y, z] in mm in the "
                                             "level's frame (y up), within 100 km of its origin")
    defaults = document.get("defaults", {})
    if not isinstance(defaults, dict):
        problems.add("top level", "defaults", "must be a table: [defaults]")
        defaults = {}
    _unknown(defaults, DEFAULT_KEYS, "[defaults]", problems)
    base = _options(defaults, "[defaults]", problems)
    objects = document.get("object", [])
    if not isinstance(objects, list) or not objects:
        problems.add("top level", "object",
                     "the manifest lists no object; add [[object]] tables with file = \"...\"")
        objects = []
    specs = []
    for k, table in enumerate(objects):
        where = f"object {k + 1}"
        if not isinstance(table, dict):
            problems.add(where, None, "must be a table: [[object]]")
            continue
        if isinstance(table.get("name"), str):
            where += f" ({table['name']})"
        _unknown(table, OBJECT_KEYS, where, problems)
        given = table.get("file")
        if "shape" in table:
            spec = _described(table, where, base, path, problems)
            if spec is not None:
                specs.append(spec)
            continue
        if given is None or given == "":
            problems.add(where, "file",
                         "missing; give the mesh file, relative to the manifest's folder, or the "
                                        "prop's sizes as shape = { kind = \"cylinder\", "
                                        "diameter_mm = 54, height_mm = 66 }")
            continue
        if not isinstance(given, str):
            problems.add(where, "file",
                         f"{given!r} is not a path; give the mesh file as text in quotes, relative "
                                        "to the manifest's folder")
            continue
        file = path.parent / given
        options = base | _options(table, where, problems)
        if file.is_dir():
            problems.add(where, "file",
                         f"{file}: a folder, not a mesh file; give the mesh file's path (relative "
                         "to the manifest's folder)")
        elif not file.is_file():
            problems.add(where, "file",
                         f"{file}: no such file; check the path (relative to the manifest's "
                         "folder)")
        elif file.suffix.lower() not in MESH_EXTENSIONS:
            problems.add(where, "file",
                         f"{file}: not a mesh file; use one of {', '.join(MESH_EXTENSIONS)}")
        elif (options.get("split") == "nodes"
              and MESH_EXTENSIONS[file.suffix.lower()] not in GLTF_TYPES):
            problems.add(where, "split", "only a glTF or GLB scene can be split into its nodes")
        regions = ContactRegions(options.pop("exclude", ()), options.pop("only", ()))
        specs.append(ObjectSpec(str(file), regions=regions, manifest=str(path), **options))
    problems.raise_any()
    return specs


def _described(table: dict, where: str, base: dict, manifest: Path,
               problems: _Problems) -> ObjectSpec | None:
    """The spec of an object known by its sizes (:mod:`pinchmatch.mesh.described`): mm, +Z up."""
    clash = [k for k in ("file", "units", "up", "split") if k in table]
    if clash:
        problems.add(where, "shape",
                     f"a shape has no file: its sizes are in mm and its axis is +Z; drop "
                                     f"{', '.join(clash)}")
    if not isinstance(table.get("name"), str):
        problems.add(where, "name", "a shape needs a name (it has no file to be named after)")
    stack, lines = read_shape(table["shape"], where)
    for line in lines:
        problems.add(line.split(": ", 1)[0], None, line.split(": ", 1)[1])
    options = {k: v for k, v in (base | _options(table, where, problems)).items()
               if k not in ("units", "up", "split")}
    if stack is None or clash or "name" not in options:
        return None
    try:
        file = shape_file(stack)
    except InternalError as exc:
        problems.add(where, "shape", f"{exc}; check that each part rests on the one below")
        return None
    except OSError as exc:
        problems.add(where, "shape", f"the prop's solid cannot be written to the temporary folder "
                                     f"({exc.strerror or exc}); free some space or set TMPDIR")
        return None
    regions = ContactRegions(options.pop("exclude", ()), options.pop("only", ()))
    return ObjectSpec(str(file), regions=regions, manifest=str(manifest), units="mm", up="z",
                      **options)


def node_specs(spec: ObjectSpec, nodes, *, only: tuple = (), skip: tuple = (),
               furniture: Furniture | None = None, notes: list | None = None) -> list[ObjectSpec]:
    """One spec per mesh node of a level (``nodes`` from :func:`pinchmatch.mesh.load.read_level`),
    named by the node (after the level's own name, where the manifest gives one): the nodes whose
    name or path matches a glob of the spec's ``nodes`` (else of ``only``; every node where neither
    gives one), none that matches one of the spec's ``skip_nodes`` or of ``skip``. A glob of
    ``nodes`` or ``only`` that matches no node is refused, naming the level's nodes. A node of
    ``furniture`` (:func:`pinchmatch.mesh.furniture.furniture`) is left out unless a glob of
    ``nodes`` or ``only`` names it, with one line in ``notes`` saying so; a node that stands on
    furniture has its top as ``rests_on_mm``."""
    furniture = furniture or Furniture()
    include = spec.nodes or tuple(only)
    exclude = tuple(spec.skip_nodes) + tuple(skip)

    def matches(n, globs) -> bool:
        return any(fnmatch.fnmatchcase(n.name, g) or fnmatch.fnmatchcase(n.path, g) for g in globs)

    for g in include:
        if not any(matches(n, (g,)) for n in nodes):
            names = ", ".join(n.name for n in nodes[:12]) + (", ..." if len(nodes) > 12 else "")
            raise ConfigError(f"{spec.path}: the node glob {g!r} (--nodes, or a manifest's nodes) "
                              f"matches no mesh node of the level; its nodes are {names}")
    kept = [n for n in nodes if (not include or matches(n, include)) and not matches(n, exclude)]
    left = [n for n in kept if n.name in furniture.why and not (include and matches(n, include))]
    for n in left:
        if notes is not None:
            notes.append(f"{spec.path}: node {n.name} left out of the match, as a table, a "
                         "counter, a shelf, a wall "
                         f"or a floor is: {furniture.why[n.name]}; to match it, name it with "
                         f"--nodes '{n.name}'")
    kept = [n for n in kept if n not in left]
    if not kept:
        raise ConfigError(f"{spec.path}: --nodes and --skip-nodes leave no mesh node of the level; "
                          "name at least one node to match")
    return [replace(spec, split="none", node=n.name, node_path=n.path,
                    rests_on_mm=furniture.tops_mm.get(n.name),
                    name=f"{spec.name}/{n.name}" if spec.name else None) for n in kept]


def _user(value) -> tuple | None:
    """``value`` as a point (x, y, z) in mm, or None where it is not one."""
    if not isinstance(value, list) or len(value) != 3 or not all(finite_number(c) and abs(c) <= 1e8
                                                                 for c in value):
        return None
    return tuple(float(c) for c in value)


def manifest_user(paths) -> tuple | None:
    """Where the user stands (mm, the level's frame), as the manifests among ``paths`` say with a
    level-wide ``user_mm`` (each manifest checked as :func:`read_manifest` checks it); None where
    none says. Two manifests that put the user in two places are refused in one line."""
    found: dict[tuple, str] = {}
    for given in paths:
        if is_manifest(given):
            read_manifest(given)
            document = tomllib.loads(Path(given).read_bytes().decode("utf-8-sig"))
            if "user_mm" in document:
                found.setdefault(_user(document["user_mm"]), str(given))
    if len(found) > 1:
        (a, first), (b, second) = list(found.items())[:2]
        raise ConfigError(f"{second}: user_mm = {list(b)} puts the user elsewhere than {first} "
                          f"does ({list(a)}); give one place, in one manifest or with --user-at")
    return next(iter(found), None)


def is_manifest(path: str | os.PathLike) -> bool:
    return Path(path).suffix.lower() == MANIFEST_SUFFIX


def object_specs(paths, *, option: str, split: str | None = None, nodes=(), skip_nodes=(),
                 notes: list | None = None, units: str | None = None,
                 up: str | None = None) -> list[ObjectSpec]:
    """The objects that command-line paths name: mesh files, folders of them (searched as
    :func:`~pinchmatch.mesh.load.mesh_files` does) and manifests, in the order given. A glTF/GLB
    scene whose split is ``"nodes"`` (its manifest entry's, else ``split``) becomes one object per
    mesh node (those ``nodes`` and ``skip_nodes`` keep, as :func:`node_specs` says; its furniture
    left out, with a line in ``notes``: :mod:`pinchmatch.mesh.furniture`, the level read in its
    spec's units and up, else ``units`` and ``up``, the run's); other files are not split.

    Parameters
    ----------
    paths : list of path-like
        Mesh files, folders of them and manifests.
    option : str
        The command-line option the paths came from (for messages).
    split : {"none", "nodes"}, optional
        Split glTF/GLB scenes into one object per mesh node.
    nodes, skip_nodes : tuple of str
        Globs of the node names or paths to keep and to leave out.
    notes : list, optional
        Collects a line for each level's furniture left out.
    units, up : str, optional
        The run's units and up, for files that give none.

    Returns
    -------
    list of ObjectSpec
        One spec per object, in the order given.

    Examples
    --------
    >>> [spec.display_name for spec in object_specs([props_toml, box_stl], option="--tangible")]
    ['box', 'can', 'box.stl']
    """
    if split is not None and split not in SPLITS:
        raise ConfigError(f"--split: unknown split {split!r}; use one of {', '.join(SPLITS)}")
    if isinstance(paths, (str, os.PathLike)):  # one path, not its characters
        paths = [paths]
    out: list[ObjectSpec] = []
    for given in paths:
        if is_manifest(given):
            specs = read_manifest(given)
        else:
            specs = [ObjectSpec(str(p)) for p in mesh_files([given], option=option)]
        for spec in specs:
            how = spec.split or split or "none"
            level = Path(spec.path).suffix.lower() in MESH_EXTENSIONS and \
                MESH_EXTENSIONS[Path(spec.path).suffix.lower()] in GLTF_TYPES
            globs = [g for g in (*nodes, *skip_nodes, *spec.nodes, *spec.skip_nodes)]
            if globs and how != "nodes" and level:
                where = (f"{spec.manifest}: {Path(spec.path).name}'s nodes"
                         if spec.nodes or spec.skip_nodes else "--nodes and --skip-nodes")
                raise ConfigError(f"{where}: choose nodes of a level split into its nodes, but "
                                  f"{spec.path} is not "
                                  "split; add --split nodes (or split = \"nodes\" in its manifest "
                                  "entry)")
            if how == "nodes" and level:
                out.extend(node_specs(spec, read_level(spec.path), only=tuple(nodes),
                                      skip=tuple(skip_nodes),
                                      furniture=level_furniture(spec.path,
                                                                units=spec.units or units,
                                                                up=spec.up or up),
                                      notes=notes))
            else:
                out.append(spec)
    return distinct_names(out, option)


def distinct_names(specs: list, option: str) -> list:
    """``specs`` with names that tell them apart: a result names each object, so two files called
    ``prop.stl`` in two folders, or two levels' nodes called ``mug``, are named by as much of their
    paths as tells them apart (``a/prop.stl``, ``b/prop.stl``; ``kitchen_a.glb/mug``). Two objects a
    manifest gives the same name are refused in one line: the names are the user's to choose."""
    groups: dict[str, list[int]] = {}
    for k, spec in enumerate(specs):
        groups.setdefault(spec.display_name, []).append(k)
    out = list(specs)
    for name, members in groups.items():
        if len(members) < 2:
            continue
        given = [specs[k] for k in members if specs[k].name is not None and specs[k].node is None]
        if len(given) > 1:
            raise ConfigError(f"{option}: {len(given)} objects are named {name!r} "
                              f"({given[0].manifest or given[0].path}, "
                              f"{given[1].manifest or given[1].path}); give each its own name")
        parts = [Path(os.path.abspath(specs[k].path)).parts for k in members]
        for depth in range(1, max(len(p) for p in parts) + 1):
            labels = ["/".join(p[-depth:]) for p in parts]
            if len(set(labels)) == len(labels) or depth == max(len(p) for p in parts):
                break
        for k, label in zip(members, labels):
            spec = specs[k]
            node = spec.node if spec.node is not None else None
            unique = f"{label}/{node}" if node is not None else label
            if spec.name is not None and spec.node is not None:
                # a manifest's level: its name, then the path
                unique = f"{label}/{spec.name}"
            out[k] = replace(spec, name=unique)
    return out
