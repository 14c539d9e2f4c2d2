"""Which way an open part faces: its outside is where rays leave it for nothing.

A closed part's volume says which way its faces point (:mod:`pinchmatch.mesh.topology`); an open
one's says nothing, and trimesh's repair makes its winding consistent, not outward. An open part
wound towards the inside (a book's cover of three sheets whose faces point at its pages, a scan's
shell turned inside out) sends every pinch the wrong way: the fingertips are put inside it and the
pinch line is cast out of it. So the loader asks each large open part which side is outside: from
just off its largest faces, a ray along the face's normal and one against it. Where the normal's ray
meets the object (the cover's other sheet, the pages) and the other escapes, the face points inward;
where the other way round, outward. A part most of whose sampled faces point inward is turned over;
a lone sheet, both of whose rays escape, is left as it is.
"""

from __future__ import annotations

import numpy as np
import trimesh

#: the largest faces of an open part that are asked, and how many more of them must point in than
#: out
FACING_SAMPLES = 16
#: the open parts asked: those holding at least this share of the surface, the largest this many
FACING_AREA_FRACTION, FACING_PARTS = 0.05, 8


def inward_open_parts(mesh: trimesh.Trimesh, labels: np.ndarray) -> np.ndarray:
    """(parts,) bool: the open parts (bodies of ``labels``) of ``mesh`` (consistently wound) that
    face inward (module notes)."""
    from .surface import ray_engine
    from .topology import edges, watertight_and_wound

    parts = int(labels.max()) + 1 if len(labels) else 0
    out = np.zeros(parts, dtype=bool)
    area = np.asarray(mesh.area_faces, dtype=np.float64)
    part_area = np.bincount(labels, weights=area, minlength=parts)
    large = np.flatnonzero(part_area >= FACING_AREA_FRACTION * part_area.sum())
    large = large[np.argsort(-part_area[large], kind="stable")][:FACING_PARTS]
    faces = np.asarray(mesh.faces)
    asked = np.array([p for p in large if not watertight_and_wound(edges(faces[labels == p]))[0]],
                     dtype=np.int64)
    if not len(asked):
        return out
    rows = [r[np.argsort(-area[r], kind="stable")[:FACING_SAMPLES]]
            for r in (np.flatnonzero(labels == p) for p in asked)]
    owner = np.repeat(asked, [len(r) for r in rows])
    rows = np.concatenate(rows)
    rows, owner = rows[area[rows] > 0], owner[area[rows] > 0]
    centre = mesh.triangles_center[rows]
    normal = np.asarray(mesh.face_normals[rows], dtype=np.float64)
    lift = 1e-4 * float(np.linalg.norm(mesh.extents))
    rays = ray_engine(mesh)[0]
    ahead = rays.intersects_any(centre + lift * normal, normal)
    behind = rays.intersects_any(centre - lift * normal, -normal)
    votes = np.bincount(owner, weights=(ahead & ~behind).astype(float) - (behind & ~ahead),
                        minlength=parts)
    counts = np.bincount(owner, minlength=parts)
    out[asked] = votes[asked] > 0.5 * counts[asked]
    return out


def turned_outward(mesh: trimesh.Trimesh) -> str | None:
    """Turn ``mesh``'s open parts that face inward (:func:`inward_open_parts`) over, in place; the
    repair's line, or None when none did."""
    from .topology import component_labels, edges, face_adjacency

    labels = component_labels(face_adjacency(edges(mesh.faces)), len(mesh.faces))
    inward = inward_open_parts(mesh, labels)
    if not inward.any():
        return None
    faces = mesh.faces.copy()
    faces[inward[labels]] = faces[inward[labels]][:, ::-1]
    mesh.faces = faces
    return (f"turned {int(inward.sum())} open part(s) to face outward (rays from their faces met "
            "the object on the side they faced)")
