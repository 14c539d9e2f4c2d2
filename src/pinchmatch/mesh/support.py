"""The support an object stands on: the plane the hand cannot reach below.

A prop on a table, a can on a level's counter: no fingertip, finger or hand gets under them. An
object's support is a plane in its own frame (mm), ``normal · x = height_mm``, with ``normal``
pointing up, away from the table:

- a prop with a ``pose`` in a level stands on the level's horizontal plane (the level's up: +Y of a
  glTF level, or the up ``--up`` or the level's manifest entry gives it) through its lowest point as
  posed;
- a prop without one stands on the plane through its lowest point along its own up;
- ``support_mm`` (a manifest key) puts the plane at that height along the up instead (a prop
  standing on a block, a bottle on a shelf's lip), ``support = "none"`` declares a hand-held prop;
- a node of a level (``--split nodes``) stands on the level's horizontal plane through the top of
  the furniture it stands on (:mod:`pinchmatch.mesh.furniture`), else through its own lowest point.

The hand model (:mod:`pinchmatch.grasp.hand`) treats the half-space below the plane as part of the
object: a finger's test spheres measure their distance to it as to the surface, the fingertip
spheres must stay above it (:mod:`pinchmatch.grasp.pinches`'s ``clearance``), and no finger's axis
(nor so the hand behind it) points below the horizontal of the support. What an object stands on is
its spec's ``support``: ``"auto"`` (as above), ``"none"`` or a height in mm; ``None`` means the run
did not say (no support).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: the up direction of a glTF level's world (+Y), in which a prop's ``pose`` places it
LEVEL_UP = np.array([0.0, 1.0, 0.0])


def level_up(spec) -> np.ndarray:
    """(3,) the up of the level a posed prop's ``pose`` places it in: its spec's ``level_up`` (the
    level's own, as ``--up`` or the level's manifest entry says), else glTF's +Y."""
    from .frames import parse_up

    label = getattr(spec, "level_up", None) if spec is not None else None
    return LEVEL_UP if label is None else np.asarray(parse_up(label)[1], dtype=np.float64)
#: what a spec's ``support`` may say besides a height in mm
SUPPORT_WORDS = ("auto", "none")


@dataclass(frozen=True)
class SupportPlane:
    """The plane ``normal · x = height_mm`` in the object's frame (mm); ``normal`` (3,) unit,
    pointing up; ``source`` says where it came from (``pose``, ``lowest point``, ``support_mm``)."""

    normal: np.ndarray
    height_mm: float
    source: str

    def heights(self, points: np.ndarray) -> np.ndarray:
        """(...) the signed height of points (..., 3) above the plane, mm (negative below)."""
        return np.asarray(points, dtype=np.float64) @ self.normal - self.height_mm

    def as_dict(self) -> dict:
        return {"normal": [round(float(c), 6) for c in self.normal],
                "height_mm": round(float(self.height_mm), 3), "source": self.source}


def support_plane(spec, vertices: np.ndarray, up: np.ndarray) -> SupportPlane | None:
    """The support of the object of ``spec`` whose vertices (mm, its frame) and up are given; None
    when it stands on nothing (``support`` None or ``"none"``)."""
    support = getattr(spec, "support", None) if spec is not None else None
    if support is None or support == "none":
        return None
    pose = getattr(spec, "pose", None)
    if pose is not None:
        from scipy.spatial.transform import Rotation

        normal = Rotation.from_quat(np.asarray(pose[1],
                                               dtype=np.float64)).as_matrix().T @ level_up(spec)
        source = "pose"
    else:
        normal = np.asarray(up, dtype=np.float64)
        source = "lowest point"
    normal = normal / np.linalg.norm(normal)
    rests_on = getattr(spec, "rests_on_mm", None)
    if support == "auto" and rests_on is not None and pose is None:
        return SupportPlane(normal, float(rests_on), "furniture top")
    if support == "auto":
        return SupportPlane(normal, float(np.min(np.asarray(vertices, dtype=np.float64) @ normal)),
                            source)
    return SupportPlane(normal, float(support), "support_mm")
