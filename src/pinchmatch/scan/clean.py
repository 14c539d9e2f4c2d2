"""What a scan never saw, found, closed and marked: the bottom where the object stood, the holes,
the floaters.

- **Floaters:** the scan's connected pieces of less than ``FLOATER_SHARE`` of its surface (a bit of
  the table, a stray blob) are removed and counted; an object made of several sizable pieces keeps
  them all.
- **The bottom:** the object stood on a plane, so its underside was never seen: a phone scan leaves
  it open, or closes it with a guess. An open bottom is a wide boundary loop low on the object
  (``OPEN_BOTTOM_SHARE``): the object is cut flat just above the loop's highest point and closed
  there. A closed
  scan is not cut (where its guess ends cannot be told from the scan; cutting would take away what
  was seen): its lowest ``CLOSED_BOTTOM_MM`` (or three times the noise, if more) are marked unseen.
- **Closing:** the cut and every other hole are closed by a fan from a new vertex at the loop's
  centroid (:func:`_capped`), and the windings are made consistent and outward (trimesh), so that
  the volume and centre of mass are the solid's.
- **Marks:** every closed surface is returned as a region where no contact may land: the cap as a
  box 1 mm thick around its plane, each filled hole as a sphere around it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from ..errors import MeshError
from ..mesh.regions import Region

#: a connected piece of less than this share of the surface is a floater
FLOATER_SHARE = 0.05
#: a boundary loop is the open bottom when it lies wholly within this share of the height above the
#: lowest point, reaches down to within the second share of it, and spans at least the third share
#: of the footprint (a hole in a mug's inner floor is none of these)
OPEN_BOTTOM_SHARE, OPEN_BOTTOM_REACH, OPEN_BOTTOM_SPAN = 0.25, 0.08, 0.3
#: a closed scan's lowest this many mm are marked unseen (or three times its noise, if more)
CLOSED_BOTTOM_MM = 2.0
#: the cut is this far above an open bottom's highest point (mm)
CUT_ABOVE_MM = 0.1
#: the mark around a cap reaches this far above and below its plane (mm)
CAP_MARK_MM = 1.0
#: around a filled hole, the mark's radius exceeds the hole's by this much (mm)
HOLE_MARK_MM = 2.0


@dataclass
class Closed:
    """A closed scan: its mesh, the regions never seen (``exclude``), and what was done."""

    mesh: trimesh.Trimesh
    exclude: list = field(default_factory=list)
    holes: int = 0
    lines: list = field(default_factory=list)
    #: an open bottom cut flat: how far above the scan's lowest point (mm); None: it was closed
    cut_above_mm: float | None = None


def without_floaters(mesh: trimesh.Trimesh, path) -> tuple[trimesh.Trimesh, str | None]:
    """The mesh without its floaters (module notes), and a line naming what went (None:
    nothing)."""
    labels = trimesh.graph.connected_component_labels(mesh.face_adjacency, len(mesh.faces))
    area = np.bincount(labels, weights=mesh.area_faces)
    keep = np.flatnonzero(area >= FLOATER_SHARE * area.sum())
    if not len(keep):
        raise MeshError(f"{path}: the scan is all floaters ({len(area)} pieces, none with "
                        f"{100 * FLOATER_SHARE:.0f} % of its surface); scan the object again, "
                        f"or crop the scan to it")
    if len(keep) == len(area):
        return mesh, None
    out = mesh.submesh([np.flatnonzero(np.isin(labels, keep))], append=True)
    gone = len(area) - len(keep)
    return out, (f"removed {gone} floating piece{'s' if gone > 1 else ''} "
                 f"({100 * (1 - area[keep].sum() / area.sum()):.1f} % of the surface)")


def boundary_loops(mesh: trimesh.Trimesh) -> list[np.ndarray]:
    """The open boundary as simple loops of vertex indices, each in order along its edges (a
    vertex two loops touch, as a trimmed or decimated scan has, starts a loop of its own)."""
    edges = mesh.edges[trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)]
    following: dict = {}
    for a, b in edges.tolist():
        following.setdefault(a, []).append(b)
    loops = []
    for start in sorted(following):
        while following[start]:
            path, at = [start], {start: 0}
            while following.get(path[-1]):
                v = following[path[-1]].pop()
                if v in at:  # a cycle closed: split it off, keep walking from v
                    cycle = path[at[v]:]
                    if len(cycle) >= 3:
                        loops.append(np.array(cycle))
                    for u in cycle[1:]:
                        del at[u]
                    del path[at[v] + 1:]
                else:
                    at[v] = len(path)
                    path.append(v)
    return loops


def bottom_cut(mesh: trimesh.Trimesh, loops: list) -> float | None:
    """Where an open bottom is cut (mm), or None for a closed one (module notes)."""
    z = mesh.vertices[:, 2]
    low, height = float(z.min()), float(np.ptp(z))
    footprint = float(np.ptp(mesh.vertices[:, :2], axis=0).max())
    bottom = [loop for loop in loops
              if z[loop].max() <= low + OPEN_BOTTOM_SHARE * height
              and z[loop].min() <= low + OPEN_BOTTOM_REACH * height
              and np.ptp(mesh.vertices[loop, :2], axis=0).max() >= OPEN_BOTTOM_SPAN * footprint]
    if not bottom:
        return None
    return max(float(z[loop].max()) for loop in bottom) + CUT_ABOVE_MM


def _capped(mesh: trimesh.Trimesh, loops: list) -> trimesh.Trimesh:
    """The mesh with each loop closed by a fan from a new vertex at its centroid. The fan adds no
    edge between two of the loop's vertices (a diagonal could repeat an edge of the mesh and leave
    it non-manifold), and for a planar loop its signed areas sum to the polygon's, concave or
    holed (an outline's fan and its hole's, wound the other way), so the solid's volume and centre
    of mass are right."""
    vertices, faces = [mesh.vertices], [mesh.faces]
    at = len(mesh.vertices)
    for loop in loops:
        vertices.append(mesh.vertices[loop].mean(axis=0)[None])
        faces.append(np.stack([loop, np.roll(loop, -1), np.full(len(loop), at)], axis=1))
        at += 1
    return trimesh.Trimesh(np.concatenate(vertices), np.concatenate(faces), process=False)


def _manifold(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """The mesh without the faces on an edge that three or more faces share (a scan's, or its
    decimation's, knots): the hole they leave is closed and marked as any other."""
    shared = trimesh.grouping.group_rows(mesh.edges_sorted, require_count=None)
    crowded = [g for g in shared if len(g) > 2]
    if not crowded:
        return mesh
    drop = np.zeros(len(mesh.faces), dtype=bool)
    drop[mesh.edges_face[np.concatenate(crowded)]] = True
    out = mesh.copy()
    out.update_faces(~drop)
    out.remove_unreferenced_vertices()
    return out


def close(mesh: trimesh.Trimesh, path, noise_mm: float = 0.0) -> Closed:
    """The scan closed (module notes), its unseen parts returned as regions to exclude."""
    mesh = _manifold(mesh)
    loops = boundary_loops(mesh)
    cut = bottom_cut(mesh, loops)
    out = Closed(mesh)
    if cut is not None:
        kept = trimesh.intersections.slice_faces_plane(
            mesh.vertices, mesh.faces, np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, cut]))
        mesh = trimesh.Trimesh(kept[0], kept[1], process=False)
        mesh.merge_vertices(digits_vertex=6)
        mesh.vertices[np.abs(mesh.vertices[:, 2] - cut) < 1e-6, 2] = cut
        mesh = _manifold(mesh)
        mesh = _capped(mesh, [loop for loop in boundary_loops(mesh)
                              if np.abs(mesh.vertices[loop, 2] - cut).max() < 1e-6])
        lo, hi = mesh.bounds
        out.exclude.append(Region.box([lo[0] - 1, lo[1] - 1, cut - CAP_MARK_MM],
                                      [hi[0] + 1, hi[1] + 1, cut + CAP_MARK_MM]))
        above = cut - float(out.mesh.vertices[:, 2].min())
        out.cut_above_mm = above
        out.lines.append(f"cut the open bottom flat {above:.1f} mm above the scan's lowest point, "
                         f"and closed it")
    else:
        lo, hi = mesh.bounds
        band = max(CLOSED_BOTTOM_MM, 3.0 * noise_mm)
        out.exclude.append(Region.box([lo[0] - 1, lo[1] - 1, lo[2] - 1],
                                      [hi[0] + 1, hi[1] + 1, lo[2] + band]))
        out.lines.append(f"the bottom is closed: its lowest {band:.1f} mm, where it stood, are "
                         f"marked unseen")
    holes = boundary_loops(mesh)
    for loop in holes:
        points = mesh.vertices[loop]
        centre = points.mean(axis=0)
        radius = float(np.linalg.norm(points - centre, axis=1).max())
        out.exclude.append(Region.sphere(centre, radius + HOLE_MARK_MM))
    mesh = _capped(mesh, holes)
    out.holes = len(holes)
    if out.holes:
        out.lines.append(f"filled {out.holes} hole{'s' if out.holes > 1 else ''} and marked "
                         f"{'them' if out.holes > 1 else 'it'} unseen")
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    trimesh.repair.fix_normals(mesh)
    if not mesh.is_watertight or not mesh.volume > 0:
        raise MeshError(f"{path}: the scan could not be closed into a solid (its open edges "
                        f"do not form loops a face can close); repair it in the scanning app or "
                        f"MeshLab")
    out.mesh = mesh
    return out
