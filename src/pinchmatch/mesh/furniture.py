"""What in a level is not an object to pinch: tables, counters, shelves, walls and floors.

A level split into its nodes (``--split nodes``) holds the objects a user may pick up and what they
stand on or stand in front of. Matching a 1.4 m table to a prop, or failing on a wall, helps no one,
so such a node is left out of the match, with one line that names it and how to bring it back
(``--nodes NAME``). A node is such *furniture* when

- **other nodes stand on it** and it is a surface, not a stack: the lowest points of another node
  (its vertices within ``BASE_BAND_MM`` of its lowest) lie within ``STANDS_ON_MM`` of its surface,
  on a face that looks up (within ``UP_FACE_DEG`` of the level's up), and it spans more than
  ``SURFACE_SPAN_MM`` in two directions: a table, a counter, a shelf, a floor (a saucer under a cup,
  a book on a book stay objects); or
- **it spans more than ``FURNITURE_SPAN_MM`` in two directions** (along its principal axes): a wall,
  a floor, a large table. No thumb and finger hold such a thing, and a prop standing in for it would
  have to be as large; an arm's reach (about 1 m, :data:`pinchmatch.config.MAX_REACH_MM`) is the
  measure. A long thin object (a broom, a rod) spans that in one direction only and stays an object.

Where a node stands on furniture, the furniture's top is its support
(:mod:`pinchmatch.mesh.support`): the height, along the level's up, of the points of the furniture's
upward faces nearest its lowest points (their median; the highest such top where it stands on two).
A scanned mug 3 mm into the table stands on the table's top, not on its own lowest point, and one
hovering 2 mm over it on the top too.

Everything is measured in the level's world frame (every node's transforms applied), in mm.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from .level import level_nodes, node_mesh

#: another node stands on this one when its lowest points are within this distance of its upward
#: faces (mm): scans sink into or float over the table by a few mm
STANDS_ON_MM = 10.0
#: a node's lowest points: its vertices within this height of its lowest (mm), at most
#: ``BASE_POINTS`` of them
BASE_BAND_MM = 2.0
BASE_POINTS = 64
#: a face looks up when its normal is within this angle of the level's up (deg)
UP_FACE_DEG = 30.0
#: a node that spans more than this in two directions is furniture (mm): an arm's reach
FURNITURE_SPAN_MM = 1000.0
#: a node others stand on is furniture when it spans more than this in two directions (mm): a
#: surface to put things on, wider than a tray a hand carries
SURFACE_SPAN_MM = 300.0


def _base_points(vertices: np.ndarray, up: np.ndarray) -> np.ndarray:
    height = vertices @ up
    low = np.flatnonzero(height <= height.min() + BASE_BAND_MM)
    if len(low) > BASE_POINTS:
        # evenly through the band, in vertex order: the same points every run
        low = low[np.linspace(0, len(low) - 1, BASE_POINTS).astype(np.int64)]
    return vertices[low]


def principal_spans(vertices: np.ndarray) -> np.ndarray:
    """(3,) the extents of ``vertices`` (mm) along their principal axes, largest first."""
    centred = vertices - vertices.mean(axis=0)
    _, axes = np.linalg.eigh(centred.T @ centred)
    spans = np.ptp(centred @ axes, axis=0)
    return np.sort(spans)[::-1]


@dataclass(frozen=True)
class Furniture:
    """What of a level is furniture: ``why`` {node name: why it is furniture}, ``tops_mm`` {name of
    a node that stands on furniture: the height of the furniture's top under it along the level's
    up, mm}."""

    why: dict = field(default_factory=dict)
    tops_mm: dict = field(default_factory=dict)


def furniture(scene: trimesh.Scene, *, mm_per_unit: float, up: np.ndarray) -> Furniture:
    """The furniture among the mesh nodes of ``scene`` (a level whose coordinates are in units of
    ``mm_per_unit`` mm, ``up`` its up direction): the nodes that are not objects to pinch, and the
    tops the others stand on (module notes)."""
    up = np.asarray(up, dtype=np.float64)
    nodes = level_nodes(scene)
    meshes = {}
    for n in nodes:
        mesh = node_mesh(scene, n.name)
        meshes[n.name] = trimesh.Trimesh(mesh.vertices * mm_per_unit, mesh.faces, process=False)
    out: dict[str, str] = {}
    spans_of = {name: principal_spans(np.asarray(m.vertices)) for name, m in meshes.items()}
    for name, spans in spans_of.items():
        if spans[1] > FURNITURE_SPAN_MM:
            out[name] = (f"it spans {spans[0]:.0f} x {spans[1]:.0f} mm, more than "
                         f"{FURNITURE_SPAN_MM:.0f} mm in two directions")
    bases = {name: _base_points(np.asarray(m.vertices), up) for name, m in meshes.items()}
    bounds = {name: m.bounds for name, m in meshes.items()}
    cos_up = np.cos(np.radians(UP_FACE_DEG))
    tops: dict[str, float] = {}
    for name, mesh in meshes.items():
        if spans_of[name][1] <= SURFACE_SPAN_MM:
            continue
        low, high = bounds[name][0] - STANDS_ON_MM, bounds[name][1] + STANDS_ON_MM
        standing = []
        for other, base in bases.items():
            if other == name or not ((base >= low) & (base <= high)).all(axis=1).any():
                continue
            closest, distance, face = trimesh.proximity.closest_point(mesh, base)
            on = (distance <= STANDS_ON_MM) & (mesh.face_normals[face] @ up >= cos_up)
            if on.any():
                standing.append(other)
                tops[other] = max(tops.get(other, -np.inf), float(np.median(closest[on] @ up)))
        if standing:
            shown = ", ".join(standing[:3]) + (f" and {len(standing) - 3} more" if len(standing)
                                               > 3 else "")
            out[name] = f"{shown} stand{'s' if len(standing) == 1 else ''} on it" + (
                f"; {out[name]}" if name in out else "")
    return Furniture(out, {name: top for name, top in tops.items() if name not in out})


def level_furniture(path, *, units: str | None, up: str | None) -> Furniture:
    """:func:`furniture` of the level file ``path``, read in ``units`` and ``up`` (glTF's metres and
    +Y where not given)."""
    from .frames import UNITS_MM, parse_up
    from .load import level_scene
    from pathlib import Path

    return furniture(level_scene(Path(path)), mm_per_unit=UNITS_MM[units or "m"],
                     up=parse_up(up or "y")[1])
