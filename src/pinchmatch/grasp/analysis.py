"""One object, analysed once: the context object the pipeline passes along.

:func:`analyze_object` loads a file and builds everything expensive about it
(mass properties, dense surface sample, KD-tree, ray engine);
:func:`find_pinches` and :func:`score_pinch` are the one-shot calls behind
``pinchmatch poses`` and ``pinchmatch features``.
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config import finite_number
from ..errors import ConfigError, ContactError, MeshError, NoFeasiblePinchError, in_manifest
from ..mesh import topology
from ..mesh.support import support_plane
from ..files import read_input
from .features import PinchFeatures, TripodFeatures, pinch_features, tripod_features
from ..mesh.load import LoadedMesh, load_mesh
from ..mesh.described import SHAPES_FOLDER
from ..mesh.manifest import ObjectSpec
from .pinches import PinchSettings, Pinches, check_pinches
from .sampling import sample_pinches
from .tripod_rules import FINGERS, Tripods, check_tripods
from .tripods import sample_tripods
from ..mesh.properties import ObjectProperties, object_properties
from ..mesh.surface import SurfaceContext

#: a poses file holds at most this many poses, and is at most this big (bounded memory)
MAX_GIVEN_POSES = 100_000
MAX_POSES_FILE_BYTES = 32 * 2**20
#: a contact farther than this from the origin (mm, 1 km) is not a contact on a prop
MAX_COORDINATE_MM = 1e6


@dataclass(frozen=True)
class ObjectAnalysis:
    """A loaded object with its properties and surface context, and what its spec says of it
    (its name, mass and regions: :class:`~pinchmatch.mesh.object_spec.ObjectSpec`)."""

    loaded: LoadedMesh
    props: ObjectProperties
    context: SurfaceContext
    spec: ObjectSpec | None = None

    @property
    def name(self) -> str:
        """The spec's name, else the scene node's, else the file's name."""
        return self.spec.name if self.spec is not None and self.spec.name else self.loaded.name

    @property
    def mass_g(self) -> float | None:
        """The real or intended mass (g), where the spec gives it."""
        return self.spec.mass_g if self.spec is not None else None


def analyze_object(
    path: str | os.PathLike,
    *,
    units: str | None = None,
    up: str | None = None,
    com_mm: np.ndarray | None = None,
    axis: np.ndarray | None = None,
    mass_g: float | None = None,
    patch_radius_mm: float = 8.0,
    progress=None,
) -> ObjectAnalysis:
    """Load ``path`` and build its properties and surface context (see :func:`load_mesh`);
    ``mass_g`` is its mass in grams where known (the ``mass`` criterion compares felt torques when
    both objects have one); ``progress``, if given, is called with each stage's name as it starts.

    Parameters
    ----------
    path : path-like
        A mesh file (STL, OBJ, PLY, OFF, glTF or GLB), read by :func:`load_mesh`.
    units, up : str, optional
        The file's units and up (:func:`load_mesh`'s defaults where not given).
    com_mm, axis : (3,) float64, optional
        The centre of mass (mm) and principal axis, where known better than the shape says.
    mass_g : float, optional
        The object's mass in grams.
    patch_radius_mm : float
        The radius of the fingertip patches whose curvatures describe a pinch.
    progress : callable, optional
        Called with each stage's name as it starts.

    Returns
    -------
    ObjectAnalysis
        The loaded mesh, its properties (centre of mass, axis, mass) and its surface context.

    Examples
    --------
    >>> obj = analyze_object(box_stl, mass_g=120)
    >>> extents = obj.loaded.mesh.extents
    >>> obj.name, obj.mass_g, obj.props.com_mm.round(1).tolist(), extents.round(1).tolist()
    ('box.stl', 120.0, [0.0, 0.0, 0.0], [60.0, 40.0, 20.0])
    """
    spec = _file_spec(path, units=units, up=up, com_mm=com_mm, axis=axis, mass_g=mass_g)
    return analyze_spec(spec, patch_radius_mm=patch_radius_mm, progress=progress)


def _file_spec(path, *, units=None, up=None, com_mm=None, axis=None, mass_g=None) -> ObjectSpec:
    if mass_g is not None and not (isinstance(mass_g, (int, float, np.number))
                                   and not isinstance(mass_g, bool)
                                   and 0 < float(mass_g) < 1e9):
        raise ConfigError(f"{path}: mass_g={mass_g!r} must be a mass in grams above 0 (or None, "
                          "unknown)")
    return ObjectSpec(str(path), units=units, up=up, com_mm=None if com_mm is None
                      else tuple(np.ravel(com_mm)),
                      axis=None if axis is None else tuple(np.ravel(axis)),
                      mass_g=None if mass_g is None else float(mass_g))


def analyze_prop(prop: str | os.PathLike | ObjectSpec, **options) -> ObjectAnalysis:
    """A prop as ``pinchmatch match`` reads one: standing on its table (its support, ``"auto"``: the
    plane through its lowest point, or through its pose's in a level) unless its manifest entry says
    otherwise (``support = "none"``, held in the hand). ``prop`` is a file (``options`` as
    :func:`analyze_object`'s) or a spec (``options``: ``patch_radius_mm``, ``progress``). A virtual
    object of its own file stands nowhere: read it with :func:`analyze_object`, as the command line
    does.

    Parameters
    ----------
    prop : path-like or ObjectSpec
        A prop's mesh file or its spec (a manifest entry, a level node).
    **options
        For a file, :func:`analyze_object`'s options; for a spec, ``patch_radius_mm`` and
        ``progress``.

    Returns
    -------
    ObjectAnalysis
        The prop, standing on its support unless its spec says ``support = "none"``.

    Examples
    --------
    >>> prop = analyze_prop(box_stl)
    >>> prop.context.support.source, prop.context.support.height_mm
    ('lowest point', -10.0)
    """
    reading = {k: options.pop(k) for k in ("patch_radius_mm", "progress") if k in options}
    spec = prop if isinstance(prop, ObjectSpec) else _file_spec(prop, **options)
    return analyze_spec(spec.standing("auto"), **reading)


def analyze_spec(spec: ObjectSpec, *, patch_radius_mm: float = 8.0,
                 progress=None) -> ObjectAnalysis:
    """:func:`analyze_object` for an object described by a spec (a manifest entry, a level node):
    its units, up, centre of mass, axis, node and contact regions.

    Parameters
    ----------
    spec : ObjectSpec
        The object's file and what its manifest entry or the command line says of it.
    patch_radius_mm : float
        The radius of the fingertip patches.
    progress : callable, optional
        Called with each stage's name as it starts.

    Returns
    -------
    ObjectAnalysis
        The object as its spec describes it.

    Examples
    --------
    >>> from pinchmatch import read_manifest
    >>> box, can = [analyze_spec(spec) for spec in read_manifest(props_toml)]
    >>> can.name, can.loaded.mesh.extents.round(1).tolist()  # the manifest says it is in metres
    ('can', [54.0, 54.0, 66.0])
    """
    say = progress or (lambda stage: None)
    try:
        loaded = load_mesh(spec.path, units=spec.units, up=spec.up, progress=progress,
                           node=spec.node)
    except MeshError as exc:
        if spec.manifest and spec.node is None:  # its units and up are its manifest entry's
            raise in_manifest(exc, spec.manifest) from None
        raise
    say("mass properties")
    props = object_properties(loaded.mesh, up=loaded.up, watertight=loaded.watertight,
                              com_mm=None if spec.com_mm is None else np.array(spec.com_mm),
                              axis=None if spec.axis is None else np.array(spec.axis))
    say("surface sample and index")
    context = SurfaceContext(loaded.mesh, patch_radius_mm=patch_radius_mm, regions=spec.regions,
                             support=support_plane(spec, loaded.mesh.vertices, loaded.up))
    return ObjectAnalysis(loaded, props, context, spec)


def source_of(obj: ObjectAnalysis) -> str:
    """How a message names the object: its file, with its node in a level; for a prop a manifest
    describes by its shape, the manifest and the object (its solid's file is pinchmatch's own)."""
    spec = obj.spec
    if (spec is not None and spec.manifest
        and Path(obj.loaded.path).parent.name.startswith(SHAPES_FOLDER)):
        return f"{spec.manifest}: object {spec.display_name} (its shape)"
    node = spec.node if spec is not None else None
    return f"{obj.loaded.path} (node {node})" if node else str(obj.loaded.path)


def find_pinches(obj: ObjectAnalysis, *,
                 settings: PinchSettings = PinchSettings()) -> tuple[Pinches, PinchFeatures]:
    """Feasible pinches spread over ``obj`` and their features.

    Parameters
    ----------
    obj : ObjectAnalysis
        The object.
    settings : PinchSettings
        The sampling (``grasp``: pinches or tripods) and the rules a pinch must pass.

    Returns
    -------
    (Pinches, PinchFeatures)
        The feasible pinches (or tripods) and their features.

    Examples
    --------
    >>> obj = analyze_object(box_stl)
    >>> pinches, features = find_pinches(obj, settings=PinchSettings(count=50, seed=0))
    >>> len(pinches), features.width_mm.shape, features.kappa_max_per_m.shape
    (50, (50,), (50, 2))
    """
    node = obj.spec.node if obj.spec is not None else None
    source = source_of(obj)
    too_wide(obj.loaded.mesh, settings, source, node)
    if settings.grasp == "tripod":
        tripods = sample_tripods(obj.context, settings=settings, source=source)
        return tripods, tripod_features(tripods, obj.props)
    pinches = sample_pinches(obj.context, settings=settings, source=source)
    return pinches, pinch_features(pinches, obj.props)


#: a closed object whose volume is at least this share of its convex hull's is taken as convex
CONVEX_SHARE = 0.97


def too_wide(mesh, settings: PinchSettings, source: str, node: str | None = None) -> None:
    """Refuse a convex object wider than the largest pinch in every direction (its oriented bounding
    box's least extent, trimesh's): no hand could pinch it, and sampling it would only say so
    slowly. An object that is not convex (a pot with handles, a bowl's rim) may have thin parts:
    sampling decides.

    The box is asked last: trimesh finds it by trying every face of the hull, which takes longer
    than the hull itself on a large scan (1.4 s on a 100k-face torus), and it only matters for a
    closed convex object. And the hull of a few thousand of the vertices, inside the whole hull,
    shows most objects that are not convex at once (its volume is at most the whole hull's)."""
    # trimesh's is_watertight, faster
    watertight, _ = topology.watertight_and_wound(topology.edges(mesh.faces))
    if not watertight:
        return
    volume = abs(mesh.volume)
    if (volume < CONVEX_SHARE * _inner_hull_volume(mesh.vertices) or volume < CONVEX_SHARE
        * mesh.convex_hull.volume):
        return
    extents = np.sort(np.asarray(mesh.bounding_box_oriented.primitive.extents, dtype=np.float64))
    if extents[0] > settings.max_width_mm:
        leave = f"--skip-nodes '{node}'" if node else "leave it out"
        raise NoFeasiblePinchError(
            f"{source}: no feasible pinch: {' x '.join(f'{e:.0f}' for e in extents)} mm, wider "
            "than the largest pinch "
            f"(--max-width-mm {settings.max_width_mm:g}) in every direction: no hand can pinch it; "
            f"{leave}")


#: vertices of the inner hull of :func:`too_wide`: a hull of this many points takes milliseconds
INNER_HULL_POINTS = 4096


def _inner_hull_volume(vertices: np.ndarray) -> float:
    """The volume of the hull of every k-th vertex (about ``INNER_HULL_POINTS`` of them) and of the
    extreme vertex along each axis both ways: a lower bound on the convex hull's volume (0 where it
    is flat)."""
    from scipy.spatial import ConvexHull, QhullError

    step = max(1, len(vertices) // INNER_HULL_POINTS)
    chosen = np.r_[np.arange(0, len(vertices),
                             step), vertices.argmin(axis=0), vertices.argmax(axis=0)]
    try:
        return float(ConvexHull(vertices[chosen]).volume)
    except (QhullError, ValueError):  # flat or too few points: no bound
        return 0.0


def score_pinches(
    obj: ObjectAnalysis,
    p1_mm: np.ndarray,
    p2_mm: np.ndarray,
    *,
    settings: PinchSettings = PinchSettings(),
    source: str | None = None,
) -> tuple[Pinches, PinchFeatures]:
    """Snap user-given pinches to the surface, check them and compute their features.

    Returns the pinches (all of them, feasible or not; ``snap_distance_mm``
    says how far each contact moved) and their features.

    Parameters
    ----------
    obj : ObjectAnalysis
        The object.
    p1_mm, p2_mm : (n, 3) float64
        The given contacts (mm).
    settings : PinchSettings
        The rules a pinch must pass and how far a contact may be snapped.
    source : str, optional
        What messages call the given pinches (their file).

    Returns
    -------
    (Pinches, PinchFeatures)
        The pinches (all of them, feasible or not; ``snap_distance_mm`` says how far each contact
        moved) and their features.

    Raises
    ------
    ContactError
        A contact is farther than ``settings.snap_tolerance_mm`` from the surface.

    Examples
    --------
    >>> obj = analyze_object(box_stl)  # 20 mm tall: a pinch from the top face to the bottom one
    >>> top, bottom = np.array([[0.0, 0.0, 10.0]]), np.array([[0.0, 0.0, -10.0]])
    >>> pinches, f = score_pinches(obj, top, bottom)
    >>> pinches.feasible.tolist(), f.width_mm.tolist(), f.com_distance_mm.round(6).tolist()
    ([True], [20.0], [0.0])
    """
    p1_mm = np.asarray(p1_mm, dtype=np.float64).reshape(-1, 3)
    p2_mm = np.asarray(p2_mm, dtype=np.float64).reshape(-1, 3)
    pinches = check_pinches(obj.context, p1_mm, p2_mm, settings=settings)
    distance = pinches.snap_distance_mm
    far = np.argwhere(distance > settings.snap_tolerance_mm)
    if len(far):
        i, k = far[0]
        point = (p1_mm, p2_mm)[k][i]
        label = f"p{k + 1}" if len(p1_mm) == 1 else f"pose {i} p{k + 1}"
        raise ContactError(
            f"{source or obj.loaded.path}: {label} ({', '.join(f'{c:g}' for c in point)}) mm is "
            f"{distance[i, k]:.2f} mm from the surface (tolerance {settings.snap_tolerance_mm:g} "
            "mm); give a point on the surface, in the file's frame and in mm (check --units)"
        )
    return pinches, pinch_features(pinches, obj.props)


def score_tripods(obj: ObjectAnalysis, points_mm: np.ndarray, *,
                  settings: PinchSettings = PinchSettings(),
                  source: str | None = None) -> tuple[Tripods, TripodFeatures]:
    """Snap user-given tripods (n, 3, 3): thumb, index, middle) to the surface, check them and
    compute their features, as :func:`score_pinches` does for pinches.

    Raises
    ------
    ContactError
        A contact is farther than ``settings.snap_tolerance_mm`` from the surface.
    """
    points = np.asarray(points_mm, dtype=np.float64).reshape(-1, 3, 3)
    n = len(points)
    closest, distance, face = obj.context.closest_points(points.reshape(-1, 3))
    distance = distance.reshape(n, 3)
    far = np.argwhere(distance > settings.snap_tolerance_mm)
    if len(far):
        i, k = far[0]
        label = FINGERS[k] if n == 1 else f"pose {i} {FINGERS[k]}"
        raise ContactError(
            f"{source or obj.loaded.path}: the {label} contact "
            f"({', '.join(f'{c:g}' for c in points[i, k])}) mm is "
            f"{distance[i, k]:.2f} mm from the surface (tolerance {settings.snap_tolerance_mm:g} "
            "mm); give a point on the surface, in the file's frame and in mm (check --units)")
    tripods = check_tripods(obj.context, closest.reshape(n, 3, 3), face.reshape(n, 3),
                            settings=settings)
    tripods = dataclasses.replace(tripods, snap_distance_mm=distance)
    return tripods, tripod_features(tripods, obj.props)


def _poses_list(path: str):
    """The JSON of a poses file, its ``poses`` list where it is a poses document; ConfigError where
    it cannot be read or is no JSON."""
    raw = read_input(path, "JSON poses file", limit_bytes=MAX_POSES_FILE_BYTES,
                     too_big=f"more than a poses file of {MAX_GIVEN_POSES:,} poses needs; split it "
                             "or give fewer poses")
    try:
        data = json.loads(raw.decode("utf-8-sig"))
    except (ValueError, RecursionError) as exc:
        # not JSON, not UTF-8, or an integer of thousands of digits
        raise ConfigError(f"{path}: not valid JSON ({type(exc).__name__}: {str(exc)[:80]}); fix "
                          "the file") from None
    if isinstance(data, dict) and isinstance(data.get("poses"), list):
        data = data["poses"]
    return data


def load_tripods_file(path: str | os.PathLike) -> np.ndarray:
    """Read user-given tripods: a JSON list of ``{"contacts_mm": [[x, y, z], [x, y, z], [x, y,
    z]]}`` (thumb, index, middle), or a ``pinchmatch poses --grasp tripod`` document; (n, 3, 3)
    float64.

    Raises
    ------
    ConfigError
        Missing file, invalid JSON, or an entry without three finite 3-vectors.
    """
    path = os.fspath(path)
    data = _poses_list(path)
    if not isinstance(data, list) or not data or len(data) > MAX_GIVEN_POSES:
        raise ConfigError(f'{path}: expected a JSON list of 1 to {MAX_GIVEN_POSES:,} tripods, each '
                          '{"contacts_mm": [[x, y, z], [x, y, z], [x, y, z]]} (thumb, index, '
                          'middle)')
    out = []
    for i, entry in enumerate(data):
        try:
            contacts = np.stack([_three_numbers(c) for c in entry["contacts_mm"]])
        except (KeyError, TypeError, ValueError):
            contacts = np.zeros(0)
        if contacts.shape != (3, 3) or not (np.abs(contacts) < MAX_COORDINATE_MM).all():
            raise ConfigError(f'{path}: tripod {i} needs "contacts_mm", three points of three '
                              'finite numbers each '
                              f"(mm, below {MAX_COORDINATE_MM:g} in size; thumb, index, middle); "
                              "fix that entry")
        out.append(contacts)
    return np.array(out)


def _three_numbers(value) -> np.ndarray:
    """A JSON list of three numbers as an array; text ("20") and booleans are not numbers."""
    if not isinstance(value, list) or not all(finite_number(v) for v in value):
        raise ValueError(value)
    return np.asarray(value, dtype=np.float64)


def load_poses_file(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read user-given pinches: a JSON list of ``{"p1_mm": [x, y, z], "p2_mm": [x, y, z]}``.

    A ``pinchmatch poses`` document (an object with a ``poses`` list) is read too.

    Returns
    -------
    p1_mm, p2_mm : (n, 3) float64

    Raises
    ------
    ConfigError
        Missing file, invalid JSON, or an entry without two finite 3-vectors.
    """
    path = os.fspath(path)
    data = _poses_list(path)
    if not isinstance(data, list) or not data:
        raise ConfigError(
            f'{path}: expected a non-empty JSON list of {{"p1_mm": [x, y, z], "p2_mm": [x, y, z]}}'
        )
    if len(data) > MAX_GIVEN_POSES:
        raise ConfigError(f"{path}: {len(data):,} poses, more than the {MAX_GIVEN_POSES:,} a file "
                          "may give; split it")
    p1, p2 = [], []
    for i, entry in enumerate(data):
        try:
            a, b = (_three_numbers(entry[key]) for key in ("p1_mm", "p2_mm"))
        except (KeyError, TypeError, ValueError):
            a = b = np.zeros(0)
        if a.shape != (3,) or b.shape != (3,) or not (np.abs(a) < MAX_COORDINATE_MM).all() \
                or not (np.abs(b) < MAX_COORDINATE_MM).all():
            raise ConfigError(
                f"{path}: pose {i} needs \"p1_mm\" and \"p2_mm\", each three finite numbers (mm, "
                f"below {MAX_COORDINATE_MM:g} in size); fix that entry"
            )
        p1.append(a)
        p2.append(b)
    return np.array(p1), np.array(p2)
