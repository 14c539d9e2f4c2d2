"""The family of printable props that ``pinchmatch design`` searches: coaxial stacks of simple
parts.

A stack is up to ``MAX_PARTS`` parts, bottom to top along +Z, each centred on the Z axis and resting
on the one below; the first stands on z = 0 with a flat face. A part is one of

- ``cylinder``: diameter ``width_mm``;
- ``box``: a square prism of side ``width_mm`` (``depth_mm`` along Y makes it oblong), turned
  ``turn_deg`` about Z;
- ``frustum``: a cone frustum from diameter ``width_mm`` at its bottom to ``top_width_mm`` at its
  top;
- ``barrel``: the middle zone of an ellipsoid of revolution (a sphere's when the numbers make it
  one): diameter ``width_mm`` at mid-height and ``top_width_mm`` at both cut faces;

each ``height_mm`` tall. This is the method's own study prop (a cylinder, a cube and a frustum) made
general: every part offers its own widths, wall orientations and curvatures, one above the other, so
different heights give different sensations. Round parts are surfaces of revolution (trimesh's
``revolve``); the stack is their union by manifold3d, so it is watertight and manifold by
construction (and checked).

**Printing.** The base is flat. A part wider at its bottom than the part below is at its top, and a
barrel's lower half, hang over: :func:`overhang_area_mm2` measures the area of every downward face
steeper than ``OVERHANG_DEG`` from vertical (the usual limit of printing without supports), which
``design.json`` reports; zero means printable without supports, standing on its base.
:func:`supported` reshapes a stack so that it has none (``design --no-supports``).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np
import trimesh

from ..errors import ConfigError, InternalError

PART_KINDS = ("cylinder", "box", "frustum", "barrel")
#: most parts in a stack
MAX_PARTS = 4
#: a part narrower or lower than this cannot be pinched on its own (mm)
MIN_PART_WIDTH_MM = 10.0
MIN_PART_HEIGHT_MM = 12.0
#: downward faces steeper than this from vertical need support when printed standing on the base
OVERHANG_DEG = 45.0
#: segments around the axis of a round part
SECTIONS = 96


@dataclass(frozen=True)
class Part:
    """One part of a stack (mm, degrees); see the module notes."""

    kind: str
    height_mm: float
    width_mm: float
    top_width_mm: float | None = None  # frustum: top diameter; barrel: diameter at the cut faces
    turn_deg: float = 0.0  # box: turned about Z
    depth_mm: float | None = None  # box: its side along Y before the turn (default: width_mm)

    def __post_init__(self):
        if self.kind not in PART_KINDS:
            raise ConfigError(f"unknown part {self.kind!r}; use one of {', '.join(PART_KINDS)}")
        if self.kind in ("frustum", "barrel") and self.top_width_mm is None:
            raise ConfigError(f"a {self.kind} needs top_width_mm")

    @property
    def widest_mm(self) -> float:
        """The part's largest extent across the axis (a box's diagonal)."""
        if self.kind == "box":
            return math.hypot(self.width_mm, self.depth_mm or self.width_mm)
        return max(self.width_mm, self.top_width_mm or 0.0)

    def radius_at(self, where: str) -> float:
        """Radius (mm) of the part's round outline at its ``bottom`` or ``top`` face (a box's
        inscribed)."""
        if self.kind == "box":
            return min(self.width_mm, self.depth_mm or self.width_mm) / 2.0
        if self.kind == "cylinder":
            return self.width_mm / 2.0
        if self.kind == "frustum":
            return (self.width_mm if where == "bottom" else self.top_width_mm) / 2.0
        return self.top_width_mm / 2.0  # barrel: both cut faces

    def as_dict(self) -> dict:
        return {k: v for k, v in asdict(self).items()
                if v is not None and not (k == "turn_deg" and self.kind != "box")}


@dataclass(frozen=True)
class Stack:
    parts: tuple

    @property
    def height_mm(self) -> float:
        return float(sum(p.height_mm for p in self.parts))

    @property
    def widest_mm(self) -> float:
        return float(max(p.widest_mm for p in self.parts))

    def as_dict(self) -> dict:
        z, parts = 0.0, []
        for p in self.parts:
            parts.append(p.as_dict() | {"bottom_z_mm": round(z, 3)})
            z += p.height_mm
        return {"parts": parts, "height_mm": round(self.height_mm, 3),
                "widest_mm": round(self.widest_mm, 3)}


def stack_problems(stack: Stack, *, max_height_mm: float, max_width_mm: float) -> list[str]:
    """What keeps a stack out of the family's limits (empty: none)."""
    out = []
    if not 1 <= len(stack.parts) <= MAX_PARTS:
        out.append(f"{len(stack.parts)} parts (1 to {MAX_PARTS})")
    if stack.height_mm > max_height_mm + 1e-9:
        out.append(f"{stack.height_mm:.1f} mm tall (at most {max_height_mm:g})")
    for k, p in enumerate(stack.parts):
        widths = [p.width_mm] + ([p.top_width_mm] if p.top_width_mm is not None else [])
        if p.widest_mm > max_width_mm + 1e-9:
            out.append(f"part {k + 1} is {p.widest_mm:.1f} mm wide (at most {max_width_mm:g})")
        if min(widths) < MIN_PART_WIDTH_MM - 1e-9 or p.height_mm < MIN_PART_HEIGHT_MM - 1e-9:
            out.append(f"part {k + 1} is under {MIN_PART_WIDTH_MM:g} mm wide or "
                       f"{MIN_PART_HEIGHT_MM:g} mm tall")
        if p.kind == "barrel" and p.top_width_mm >= p.width_mm:
            out.append(f"part {k + 1}: a barrel's cut faces are narrower than its middle")
    return out


#: a footprint fits inside the one below when it is this much smaller (the round parts are 96-gons)
FIT_MARGIN = math.cos(math.pi / SECTIONS) * 0.999


def _top_reach(part: Part, rel_turn_deg: float, box_above: bool) -> float:
    """How far from the axis the part above may reach and stand on ``part``'s top face: its radius
    (a box's inscribed half-side; for a box above a box, turned ``rel_turn_deg``, the half-side that
    its corners may span, measured along the upper box's own axes)."""
    if part.kind == "box":
        half = part.width_mm / 2.0
        if box_above:
            phi = math.radians(rel_turn_deg)
            return half / (abs(math.cos(phi)) + abs(math.sin(phi)))
        return half
    return part.radius_at("top")


def supported(stack: Stack) -> Stack:
    """The stack changed as little as needed to print standing on its base without supports: every
    part's bottom footprint inside the top face below it (a box's corners included), a frustum that
    widens upward at most 45° from vertical, and a barrel's lower half no flatter than 45° at its
    cut (a² - e² <= e·h/2, a and e its middle and cut radii, h its height: the surface is
    flattest at the cut). Widths only shrink, so the limits still hold; a box that cannot stand on
    what is below becomes a cylinder of the largest width that can, and a part that would be
    narrower than ``MIN_PART_WIDTH_MM`` ends the stack below it."""
    parts = []
    for k, p in enumerate(stack.parts):
        if k > 0:
            below = parts[-1]
            rel = (p.turn_deg - below.turn_deg) if (p.kind == "box" and below.kind
                                                    == "box") else 0.0
            reach = _top_reach(below, rel, p.kind == "box") * FIT_MARGIN
            if p.kind == "box":
                allowed = 2.0 * reach if below.kind == "box" else math.sqrt(2.0) * reach
                if allowed < MIN_PART_WIDTH_MM:  # corners would hang over: a cylinder instead
                    round_reach = _top_reach(below, 0.0, False) * FIT_MARGIN
                    p = Part("cylinder", p.height_mm,
                             math.floor(min(p.width_mm, 2.0 * round_reach) * 10) / 10)
                else:
                    p = replace(p, width_mm=min(p.width_mm, math.floor(allowed * 10) / 10))
            elif p.kind == "barrel":
                p = replace(p, top_width_mm=min(p.top_width_mm, math.floor(2.0 * reach * 10) / 10))
            else:
                p = replace(p, width_mm=min(p.width_mm, math.floor(2.0 * reach * 10) / 10))
        if p.kind == "frustum" and p.top_width_mm > p.width_mm + 2.0 * p.height_mm:
            p = replace(p, top_width_mm=math.floor((p.width_mm + 2.0 * p.height_mm) * 10) / 10)
        if p.kind == "barrel":
            a, e, h = p.width_mm / 2.0, p.top_width_mm / 2.0, p.height_mm
            if a * a - e * e > e * h / 2.0:
                # too flat at the cut: the middle narrows to what the cut carries
                a = math.sqrt(e * e + e * h / 2.0) * 0.999
                p = replace(p, width_mm=math.floor(2.0 * a * 10) / 10)
            if p.top_width_mm >= p.width_mm:  # no bulge left: a cylinder
                p = Part("cylinder", p.height_mm, p.top_width_mm)
        if min(p.width_mm, p.top_width_mm or p.width_mm) < MIN_PART_WIDTH_MM - 1e-9:
            break  # too narrow to pinch on what carries it: the stack ends below
        parts.append(p)
    return Stack(tuple(parts))


def _profile(part: Part, z0: float) -> np.ndarray:
    """(r, z) outline of a round part, from the axis at its bottom to the axis at its top."""
    h = part.height_mm
    if part.kind == "cylinder":
        r = part.width_mm / 2.0
        rim = [(r, z0), (r, z0 + h)]
    elif part.kind == "frustum":
        rim = [(part.width_mm / 2.0, z0), (part.top_width_mm / 2.0, z0 + h)]
    else:  # barrel: x²/a² + z²/c² = 1 through (e/2, ±h/2)
        a, e = part.width_mm / 2.0, part.top_width_mm / 2.0
        c = (h / 2.0) / math.sqrt(1.0 - (e / a) ** 2)
        t = np.linspace(-h / 2.0, h / 2.0, 33)
        rim = list(zip(a * np.sqrt(np.clip(1.0 - (t / c) ** 2, 0.0, 1.0)), z0 + h / 2.0 + t))
    outline = np.array([(0.0, z0)] + rim + [(0.0, z0 + h)], dtype=np.float64)
    # a cone's apex or a sphere's poles lie on the axis already: each point once
    return outline[np.r_[True, np.any(np.diff(outline, axis=0) != 0.0, axis=1)]]


def part_mesh(part: Part, z0: float) -> trimesh.Trimesh:
    """One part as a closed surface, its bottom at ``z0``."""
    if part.kind == "box":
        mesh = trimesh.creation.box(extents=(part.width_mm, part.depth_mm or part.width_mm,
                                             part.height_mm))
        mesh.apply_transform(trimesh.transformations.rotation_matrix(math.radians(part.turn_deg),
                                                                     [0, 0, 1]))
        mesh.apply_translation((0.0, 0.0, z0 + part.height_mm / 2.0))
        return mesh
    return trimesh.creation.revolve(_profile(part, z0), sections=SECTIONS)


def stack_mesh(stack: Stack) -> trimesh.Trimesh:
    """The stack as one watertight, manifold solid, its base on z = 0 (mm)."""
    meshes, z = [], 0.0
    for part in stack.parts:
        meshes.append(part_mesh(part, z))
        z += part.height_mm
    mesh = meshes[0] if len(meshes) == 1 else trimesh.boolean.union(meshes, engine="manifold")
    if not (mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0):
        raise InternalError("the stack's union is not a closed solid")
    return mesh


def overhang_area_mm2(mesh: trimesh.Trimesh) -> float:
    """Area of the faces that face down more steeply than ``OVERHANG_DEG`` from vertical, the base
    (faces on z = min z) left out: what would need support when printed standing on its base."""
    normals, area = mesh.face_normals, mesh.area_faces
    steep = normals[:, 2] < -math.sin(math.radians(OVERHANG_DEG))
    on_base = np.abs(mesh.triangles[:, :, 2] - mesh.bounds[0, 2]).max(axis=1) < 1e-6
    return float(area[steep & ~on_base].sum())


def base_area_mm2(mesh: trimesh.Trimesh) -> float:
    """Area of the flat base: downward faces lying on z = min z."""
    on_base = np.abs(mesh.triangles[:, :, 2] - mesh.bounds[0, 2]).max(axis=1) < 1e-6
    return float(mesh.area_faces[on_base & (mesh.face_normals[:, 2] < -0.999)].sum())
