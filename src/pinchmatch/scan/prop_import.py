"""``pinchmatch prop import``: a phone scan made into a prop that ``match``, ``select`` and
``design`` read as they are.

The scan is read (:mod:`.read`), a point cloud rebuilt (:mod:`.surface`), the floaters removed, the
noise smoothed, the bottom cut flat and closed and every hole filled (:mod:`.clean`), the faces
decimated, and the scale checked against a reading taken with a ruler or a caliper. Written into
PROPS_DIR: ``NAME.stl`` (binary, mm, +Z up, the bottom's middle at the origin) and an
``[[object]]`` entry in ``PROPS_DIR/props.toml`` (units, up, mass, the regions never seen as
``exclude``, and as ``scan`` the noise the smoothing took out, what it left and whether the scale
was measured),
added to the manifest already there. Nothing is written unless all of it can be: the files go in
whole, and a name already in the folder is refused, never overwritten.
"""

from __future__ import annotations

import os
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from ..config import WIDTH_JND_FRACTION
from ..errors import ConfigError, MeshError
from ..mesh.frames import check_units
from ..mesh.regions import Region
from .clean import close, without_floaters
from .read import read_scan
from .surface import MAX_FACES, decimate, flat, rebuild, reconstruct, residual, smooth

#: what a --measured-mm reading may name: an extent along the prop's axes after the cut
MEASURED_AXES = ("height", "x", "y", "diameter")
#: a reading more than this factor off the scan is a mistake (another axis, other units), not a
#: scale
MAX_SCALE_FACTOR = 2.0
MANIFEST = "props.toml"
#: a surface rebuilt from a cloud is refused when more than this share of a draw of this many of
#: its points lie farther than this from it (mm)
OFF_SURFACE_SHARE, OFF_SURFACE_SAMPLE, OFF_SURFACE_MM = 0.05, 5000, 2.0
#: the smoothed scan is decimated to this share of the faces kept before it is closed
FACES_BEFORE_CLOSING = 0.97


@dataclass
class Imported:
    """A prop made from a scan: where it was written, its mesh and what was done, line by line."""

    name: str
    mesh_path: Path
    manifest: Path
    mesh: trimesh.Trimesh
    exclude: list
    noise_mm: float
    #: the error the smoothing left (mm RMS), what the match's trust in a pinch is measured at
    residual_mm: float
    scale: float
    scale_verified: bool
    #: (4, 4) the scan file's coordinates to the prop's (mm, +Z up, the bottom's middle at 0)
    from_scan: np.ndarray
    lines: list = field(default_factory=list)


def parse_measured(text: str | None) -> tuple[str, float] | None:
    """``AXIS=VALUE`` (mm) of --measured-mm, or None."""
    if text is None:
        return None
    found = re.fullmatch(r"\s*([a-z]+)\s*=\s*([0-9.eE+-]+)\s*", str(text))
    value = float(found.group(2)) if found and _number(found.group(2)) else None
    if not found or found.group(1) not in MEASURED_AXES or value is None or not value > 0:
        raise ConfigError(f"--measured-mm {text}: give AXIS=VALUE, AXIS one of "
                          f"{', '.join(MEASURED_AXES)} and VALUE in mm, e.g. height=96.5")
    return found.group(1), value


def _number(text: str) -> bool:
    try:
        return np.isfinite(float(text))
    except ValueError:
        return False


def _extent(mesh: trimesh.Trimesh, axis: str) -> float:
    size = mesh.extents
    return float({"height": size[2], "x": size[0], "y": size[1],
                  "diameter": max(size[0], size[1])}[axis])


def import_prop(scan_path, props_dir, *, name: str | None = None, units: str | None = None,
                up: str | None = None, measured: str | None = None,
                mass_g: float | None = None, faces: int = MAX_FACES) -> Imported:
    """A prop from the scan at ``scan_path``, written into ``props_dir`` (module notes).

    Parameters
    ----------
    scan_path : path-like
        The scan: USDZ/USD, glTF/GLB, OBJ, PLY (mesh or point cloud), STL or OFF.
    props_dir : path-like
        Where the prop's mesh goes and whose ``props.toml`` gets its entry.
    name : str, optional
        The prop's name (default: the scan's file name without its suffix).
    units, up : str, optional
        The scan's unit and up where its file carries none (OBJ, PLY, STL).
    measured : str, optional
        ``AXIS=VALUE``: an extent of the object measured in mm (``height``, ``x``, ``y``,
        ``diameter``); the scan is scaled to it.
    mass_g : float, optional
        The prop's mass, grams.
    faces : int
        At most this many faces in the prop's mesh.

    Returns
    -------
    Imported
        What was written and done.

    Examples
    --------
    >>> import tempfile
    >>> prop = import_prop(can_obj, tempfile.mkdtemp(), units="m", measured="height=66")
    >>> prop.name, prop.scale_verified, round(float(prop.mesh.extents[2]), 1)
    ('can', True, 66.0)
    """
    scan_path, props_dir = Path(scan_path), Path(props_dir)
    name = name or scan_path.stem
    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}", name):
        raise ConfigError(f"--name {name!r}: use letters, digits, '_', '-' and '.' (at most 64)")
    reading = parse_measured(measured)
    if mass_g is not None and not (np.isfinite(mass_g) and mass_g > 0):
        raise ConfigError(f"--mass-g {mass_g}: give the prop's mass in grams, above 0")
    mesh_path, manifest = props_dir / f"{name}.stl", props_dir / MANIFEST
    _check_free(mesh_path, manifest, name)
    scan = read_scan(scan_path, units=units, up=up)
    lines = [f"read {scan_path.name}: {len(scan.vertices)} "
             f"{'points' if scan.is_cloud else 'vertices'}, in {scan.units_in} with "
             f"{scan.up_label} up ({scan.source})"]
    if scan.is_cloud:
        mesh = reconstruct(scan.vertices, scan_path)
        lines.append(f"rebuilt the surface from the point cloud (screened Poisson): "
                     f"{len(mesh.faces)} faces")
    else:
        mesh = trimesh.Trimesh(scan.vertices, scan.faces, process=True)
        if not len(mesh.faces) or not mesh.area > 0:
            raise MeshError(f"{scan_path}: the scan has no faces with area; export it again")
    check_units(scan_path, float(np.ptp(mesh.vertices, axis=0).max()), scan.units_in)
    mesh, removed = without_floaters(mesh, scan_path)
    if removed:
        lines.append(removed)
    if flat(mesh.vertices):
        raise MeshError(f"{scan_path}: the scan is flat (a sheet, not an object); scan the object "
                        f"all round")
    # at the scan's own density: a collapse first would keep its noise
    mesh, noise = smooth(mesh, rebuilt=scan.is_cloud)
    smoothed = bool(np.isfinite(noise))
    left = residual(mesh, noise) if smoothed else 0.0
    lines.append(f"smoothed its noise along the normal: {noise:.2f} mm RMS, {left:.2f} mm left"
                 if smoothed else
                 "not smoothed: smoothing would change its shape (a model, not a scan)")
    before = len(mesh.faces)
    # the fans that close it add a few faces
    mesh = decimate(mesh, int(FACES_BEFORE_CLOSING * faces), keep_topology=scan.is_cloud)
    if len(mesh.faces) < before:
        lines.append(f"decimated {before} faces to {len(mesh.faces)}")
    try:
        closed = close(mesh, scan_path, noise if smoothed else 0.0)
    except MeshError:  # open edges no face can close as they are: a surface through them
        mesh = rebuild(mesh, scan_path)
        closed = close(mesh, scan_path, noise if smoothed else 0.0)
        closed.lines.insert(0, "its open edges could not be closed as they were: the surface was "
                               "rebuilt through them (screened Poisson)")
    lines += closed.lines
    mesh = closed.mesh
    if scan.is_cloud:
        _check_rebuilt(mesh, scan.vertices, scan_path)
    scale, verified = 1.0, reading is not None
    if reading is not None:
        axis, value = reading
        # a height reading runs from where it stood: the scan's lowest point, not the cut's
        below = closed.cut_above_mm if axis == "height" and closed.cut_above_mm else 0.0
        scale = value / (_extent(mesh, axis) + below)
        if below:
            lines.append(f"its bottom was open and cut {below:.1f} mm above its lowest point: the "
                         f"height reading counts from that point, where it stood")
        if not 1 / MAX_SCALE_FACTOR <= scale <= MAX_SCALE_FACTOR:
            raise MeshError(f"{scan_path}: --measured-mm {axis}={value:g} disagrees with the "
                            f"scan's {_extent(mesh, axis) + below:.1f} mm by {scale:.2f}x; check "
                            f"the axis "
                            f"and the units (--units), or measure again")
        off = abs(scale - 1.0)
        lines.append(f"scaled by {scale:.4f} to the measured {axis} of {value:g} mm" + (
            f": the scan's scale was off by {100 * off:.1f} %, more than a width JND "
            f"({100 * WIDTH_JND_FRACTION:.2f} %)" if off > WIDTH_JND_FRACTION else
            " (the scan's scale was within a width JND)"))
    else:
        lines.append("scale unverified: no --measured-mm reading; a phone scan's scale is right "
                     "only with a depth sensor (measure the height and import again)")
    return _write(scan_path, name, mesh, closed.exclude, scale, verified,
                  (noise if smoothed else 0.0, left), mass_g, mesh_path, manifest, lines,
                  scan.from_file)


def _check_rebuilt(mesh: trimesh.Trimesh, points: np.ndarray, path: Path) -> None:
    """Refuse a surface rebuilt from a cloud that leaves its points behind: more than
    ``OFF_SURFACE_SHARE`` of them (a fixed draw) farther than ``OFF_SURFACE_MM`` from it, as when
    a thin wall, its normals estimated from both of its sides, is turned inside out."""
    rng = np.random.default_rng(0)
    some = points[rng.choice(len(points), min(len(points), OFF_SURFACE_SAMPLE), replace=False)]
    _, distance, _ = mesh.nearest.on_surface(some)
    off = float(np.mean(distance > OFF_SURFACE_MM))
    if off > OFF_SURFACE_SHARE:
        raise MeshError(f"{path}: the surface rebuilt from the point cloud misses "
                        f"{100 * off:.0f} % of its points by more than {OFF_SURFACE_MM:g} mm (a "
                        f"thin wall turned inside out?); export the scan as a mesh")


def _check_free(mesh_path: Path, manifest: Path, name: str) -> None:
    if mesh_path.exists():
        raise ConfigError(f"{mesh_path}: a file of that name is already there; choose another "
                          f"--name, or move it away")
    if manifest.is_file() and re.search(rf'^name = "{re.escape(name)}"$', manifest.read_text(
            encoding="utf-8", errors="replace"), re.M):
        raise ConfigError(f"{manifest}: it already lists a prop named {name!r}; choose another "
                          f"--name")


def _write(scan_path: Path, name: str, mesh: trimesh.Trimesh, exclude: list, scale: float,
           verified: bool, noise: tuple, mass_g, mesh_path: Path, manifest: Path,
           lines: list, from_file: np.ndarray) -> Imported:
    """The prop scaled, its bottom's middle put at the origin, written whole (mesh then manifest:
    each into a temporary file renamed into place)."""
    lo, hi = mesh.bounds
    shift = -np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    mesh = mesh.copy()
    mesh.apply_translation(shift)
    mesh.apply_scale(scale)
    regions = [_moved(r, shift, scale) for r in exclude]
    noise = tuple(scale * float(n) for n in noise)  # (removed, left), mm of the prop
    entry = _entry(scan_path, name, mass_g, regions, verified, noise)
    mesh_path.parent.mkdir(parents=True, exist_ok=True)
    old = manifest.read_text(encoding="utf-8") if manifest.is_file() else ""
    sep = "" if not old or old.endswith("\n\n") else ("\n" if old.endswith("\n") else "\n\n")
    _replace(mesh_path, mesh.export(file_type="stl"))
    try:
        _replace(manifest, (old + sep + entry).encode("utf-8"))
    except OSError:
        mesh_path.unlink(missing_ok=True)
        raise
    lines.append(f"wrote {mesh_path} ({len(mesh.faces)} faces, {mesh.volume / 1000:.1f} cm3) and "
                 f"its entry in {manifest}")
    placed = np.diag([scale, scale, scale, 1.0])
    placed[:3, 3] = shift * scale
    return Imported(name, mesh_path, manifest, mesh, regions, noise[0], noise[1], scale, verified,
                    placed @ from_file, lines)


def _moved(region: Region, shift: np.ndarray, scale: float) -> Region:
    if region.kind == "sphere":
        return Region.sphere((np.array(region.a) + shift) * scale, region.b * scale)
    return Region.box((np.array(region.a) + shift) * scale, (np.array(region.b) + shift) * scale)


def _entry(scan_path: Path, name: str, mass_g, regions: list, verified: bool,
           noise: tuple) -> str:
    def number(x) -> str:
        return f"{float(x):.3f}".rstrip("0").rstrip(".")

    def region(r) -> str:
        d = r.as_dict()
        return "{ " + ", ".join(
            f"{k} = [{', '.join(number(v) for v in d[k])}]" if isinstance(d[k], list) else
            f"{k} = {number(d[k])}" for k in d) + " }"

    head = [f"# from the scan {scan_path.name}: noise {noise[0]:.2f} mm RMS, scale "
            f"{'checked against a measurement' if verified else 'unverified'}; the regions "
            f"under exclude were never seen (the bottom where it stood, the holes closed)",
            "[[object]]", f'file = "{name}.stl"', f'name = "{name}"', 'units = "mm"', 'up = "z"']
    if mass_g is not None:
        head.append(f"mass_g = {number(mass_g)}")
    head.append("exclude = [" + ", ".join(region(r) for r in regions) + "]")
    # the noise the smoothing took out and what it left: the match's trust in each pinch
    head.append(f"scan = {{ noise_mm = {number(noise[0])}, residual_mm = {number(noise[1])}, "
                f"scale_verified = {'true' if verified else 'false'} }}")
    return "\n".join(head) + "\n"


def _replace(path: Path, data: bytes) -> None:
    fd, temp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".part")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(temp, path)
    except BaseException:
        Path(temp).unlink(missing_ok=True)
        raise
