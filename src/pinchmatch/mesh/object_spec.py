"""One object as the pipeline reads it: its file and what a manifest or the command line says of it.

:class:`ObjectSpec` is the record every stage passes along (the loader reads by it, the caches key
by its :meth:`ObjectSpec.shape_key`, the documents write it with :func:`spec_to_dict`); the manifest
reader (:mod:`pinchmatch.mesh.manifest`) and the command line make it.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from .regions import ContactRegions, Region


#: the fields of an :class:`ObjectSpec` that do not shape its candidates
NOT_SHAPE = frozenset({"path", "name", "mass_g", "split", "node_path", "manifest", "nodes",
                       "skip_nodes", "scan_noise_mm", "scan_residual_mm",
                       "scale_verified"})


@dataclass(frozen=True)
class ObjectSpec:
    """How to read and describe one object: its file and what the manifest or command line says.

    ``None`` means "not given": the loader's default (units, up), the computed value (centre of
    mass, axis), unknown (mass), the file's or node's name (name).
    """

    path: str
    name: str | None = None
    units: str | None = None
    up: str | None = None
    com_mm: tuple | None = None
    axis: tuple | None = None
    mass_g: float | None = None
    regions: ContactRegions = ContactRegions()
    split: str | None = None  # "nodes": one object per mesh node of a glTF/GLB scene
    node: str | None = None  # one mesh node of a level
    node_path: str | None = None
    manifest: str | None = None  # the manifest it was listed in
    # ((x, y, z) mm, (qx, qy, qz, qw)): file coordinates (mm) -> the level's world
    pose: tuple | None = None
    # what it stands on (:mod:`pinchmatch.mesh.support`): "auto", "none", mm
    support: str | float | None = None
    # a level's node on furniture: the furniture's top under it (mm, along up)
    rests_on_mm: float | None = None
    # a posed prop: the up of the level its pose places it in (None: glTF's "y")
    level_up: str | None = None
    # a level split into nodes: only the nodes whose name or path matches one of these globs and
    # none that matches one of these
    nodes: tuple = ()
    skip_nodes: tuple = ()
    # a prop imported from a scan (``pinchmatch prop import``): the noise its smoothing took out
    # and the error it left (mm RMS along the normal), and whether its scale was checked against a
    # measurement
    scan_noise_mm: float | None = None
    scan_residual_mm: float | None = None
    scale_verified: bool | None = None

    @property
    def display_name(self) -> str:
        """Its name: the given one, else the scene node's, else the file's."""
        return self.name or self.node or Path(self.path).name

    def with_defaults(self, *, units: str | None, up: str | None) -> "ObjectSpec":
        """The spec with the command line's units and up where it gives none."""
        return replace(self, units=self.units or units, up=self.up or up)

    def shape_key(self) -> dict:
        """What shapes the object's candidates (a cache key): every field but those in ``NOT_SHAPE``
        (its name, mass, where it was listed, which file; the file is keyed by its contents), and of
        the pose its turn, only for an object that stands (where it stands in the level moves
        nothing in its frame)."""
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in NOT_SHAPE}
        out["regions"] = self.regions.as_dict()
        out["pose"] = None if self.support in (None, "none") or self.pose is None else self.pose[1]
        return out

    def standing(self, default: str | None) -> "ObjectSpec":
        """The spec with ``default`` support (``"auto"`` or ``"none"``) where it says none
        itself."""
        return self if self.support is not None or default is None else replace(self,
                                                                                support=default)


def spec_to_dict(spec: ObjectSpec) -> dict:
    """A spec as plain JSON values, every field by its name (:func:`spec_from_dict` makes it
    again): tuples as lists, the regions as their record."""
    return {f.name: _plain(getattr(spec, f.name)) for f in fields(spec)}


def _plain(value):
    if isinstance(value, ContactRegions):
        return value.as_dict()
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value.item() if isinstance(value, np.generic) else value


def spec_from_dict(d: dict) -> ObjectSpec:
    """The spec :func:`spec_to_dict` wrote (a field it does not hold takes its default)."""
    def region(r: dict) -> Region:
        return Region.sphere(r["center_mm"],
                             r["radius_mm"]) if "center_mm" in r else Region.box(r["min_mm"],
                                                                                 r["max_mm"])

    def tupled(value):
        return tuple(tupled(v) for v in value) if isinstance(value, list) else value

    given = {f.name: tupled(d[f.name]) for f in fields(ObjectSpec) if f.name in d}
    if "regions" in given:
        given["regions"] = ContactRegions(tuple(region(r) for r in d["regions"]["exclude"]),
                                          tuple(region(r) for r in d["regions"]["only"]))
    return ObjectSpec(**given)
