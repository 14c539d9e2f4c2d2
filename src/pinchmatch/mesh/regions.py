"""Contact regions: where on an object the fingers may not, or must, touch.

Regions are spheres and axis-aligned boxes in the object file's frame, in mm (the frame the mesh
is loaded in). A contact is *allowed* when it lies in no ``exclude`` region and, if any ``only``
region is given, in at least one of them. Each contact of a pinch is tested at its point on the
surface (the centre of the fingertip pad); draw regions around what they protect with the pad's
radius to spare, as the pad covers a disc around that point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Region:
    """A sphere (``center_mm``, ``radius_mm``) or an axis-aligned box (``min_mm``, ``max_mm``),
    mm."""

    kind: str  # "sphere" or "box"
    a: tuple  # sphere: centre; box: least corner
    b: tuple | float  # sphere: radius; box: greatest corner

    @staticmethod
    def sphere(center_mm, radius_mm: float) -> "Region":
        return Region("sphere", tuple(float(c) for c in center_mm), float(radius_mm))

    @staticmethod
    def box(min_mm, max_mm) -> "Region":
        return Region("box", tuple(float(c) for c in min_mm), tuple(float(c) for c in max_mm))

    def contains(self, points: np.ndarray) -> np.ndarray:
        """(...,) bool: which points (..., 3) lie in the region (its boundary included)."""
        p = np.asarray(points, dtype=np.float64)
        if self.kind == "sphere":
            return np.einsum("...d,...d->...", p - self.a, p - self.a) <= self.b ** 2
        return ((p >= self.a) & (p <= self.b)).all(axis=-1)

    def overlaps_boxes(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """(n,) bool: which axis-aligned boxes [lo, hi] (n, 3) the region meets."""
        if self.kind == "sphere":
            nearest = np.clip(self.a, lo, hi)
            return np.einsum("nd,nd->n", nearest - self.a, nearest - self.a) <= self.b ** 2
        return ((lo <= self.b) & (hi >= self.a)).all(axis=1)

    def as_dict(self) -> dict:
        if self.kind == "sphere":
            return {"center_mm": list(self.a), "radius_mm": self.b}
        return {"min_mm": list(self.a), "max_mm": list(self.b)}


@dataclass(frozen=True)
class ContactRegions:
    """The ``exclude`` and ``only`` regions of one object (none: every contact is allowed)."""

    exclude: tuple = ()
    only: tuple = ()

    def __bool__(self) -> bool:
        return bool(self.exclude or self.only)

    def allows(self, points: np.ndarray) -> np.ndarray:
        """(...,) bool: which contact points (..., 3) are allowed."""
        p = np.asarray(points, dtype=np.float64)
        ok = np.ones(p.shape[:-1], dtype=bool)
        for region in self.exclude:
            ok &= ~region.contains(p)
        if self.only:
            inside = np.zeros_like(ok)
            for region in self.only:
                inside |= region.contains(p)
            ok &= inside
        return ok

    def faces_that_may_hold_contacts(self, triangles: np.ndarray) -> np.ndarray:
        """(n,) bool for triangles (n, 3, 3): False only where no point of the triangle can be
        allowed (it lies wholly in one ``exclude`` region, or meets no ``only`` region)."""
        ok = np.ones(len(triangles), dtype=bool)
        for region in self.exclude:  # regions are convex: all three corners inside = all inside
            ok &= ~region.contains(triangles).all(axis=1)
        if self.only:
            lo, hi = triangles.min(axis=1), triangles.max(axis=1)
            meets = np.zeros_like(ok)
            for region in self.only:
                meets |= region.overlaps_boxes(lo, hi)
            ok &= meets
        return ok

    def as_dict(self) -> dict:
        return {"exclude": [r.as_dict() for r in self.exclude],
                "only": [r.as_dict() for r in self.only]}
