"""Props known by their sizes: a manifest's ``shape`` in place of a mesh file.

People often know their prop as "a cylinder 54 mm across and 66 mm tall". A manifest entry may
give ``shape`` instead of ``file``: one part, or a list of parts stacked bottom to top along +Z,
each centred on the axis and resting on the one below, the first standing on z = 0. Sizes are in
mm and the axis is +Z whatever the manifest's ``[defaults]`` say::

    [[object]]
    name = "can"
    shape = { kind = "cylinder", diameter_mm = 54, height_mm = 66 }

    [[object]]
    name = "tower"
    shape = [
      { kind = "box", size_mm = [40, 30, 25] },
      { kind = "frustum", diameter_mm = 30, top_diameter_mm = 12, height_mm = 40 },
    ]

The parts are the ones ``pinchmatch design`` builds its props from (:mod:`pinchmatch.mesh.stacks`),
so a described prop and a designed one are the same solids: ``sphere`` (alone), ``cylinder``,
``box`` (``size_mm`` across X, across Y, tall; ``turn_deg`` about Z), ``frustum``
(``top_diameter_mm`` 0 makes a cone) and ``barrel`` (the middle of an ellipsoid: ``diameter_mm`` at
mid-height, ``end_diameter_mm`` at both cut faces).

The solid is written once as a binary STL named by the digest of its parts and of the code that
builds it, in this user's private folder of the system's temporary directory (``SHAPES_FOLDER``
and the user id, mode 0700), so that loading, the cache and the workers treat it as any mesh file;
the same sizes give the same file, byte for byte. A file there that is not a whole STL is written
again.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
import tempfile
from pathlib import Path

from ..config import finite_number
from ..options import code_digest
from .stacks import Part, Stack, stack_mesh

#: the folder of the temporary directory where described props are written
SHAPES_FOLDER = "pinchmatch-shapes"
#: a described prop is held in one hand: every size at most this (mm)
MAX_SIZE_MM = 1000.0
#: the least size of a part (mm): smaller than a millimetre, no fingertip feels it and the solid's
#: union falls below the mesh tolerances
MIN_SIZE_MM = 1.0
#: parts in one described stack at most
MAX_DESCRIBED_PARTS = 8
#: each kind's keys: required, then optional
SHAPE_KEYS = {
    "sphere": (("diameter_mm",), ()),
    "cylinder": (("diameter_mm", "height_mm"), ()),
    "box": (("size_mm",), ("turn_deg",)),
    "frustum": (("diameter_mm", "top_diameter_mm", "height_mm"), ()),
    "barrel": (("diameter_mm", "end_diameter_mm", "height_mm"), ()),
}


def _size(value) -> bool:
    return finite_number(value) and MIN_SIZE_MM <= value <= MAX_SIZE_MM


def _part(table, at: str, problems: list[str]) -> Part | None:
    """One part from its table, or ``None`` with its problems added as ``'AT: what; fix'``."""
    if not isinstance(table, dict) or table.get("kind") not in SHAPE_KEYS:
        got = table.get("kind") if isinstance(table, dict) else table
        problems.append(f"{at}: kind {got!r} is not a shape; use one of {', '.join(SHAPE_KEYS)}, "
                        "e.g. { kind = \"cylinder\", diameter_mm = 54, height_mm = 66 }")
        return None
    kind = table["kind"]
    required, optional = SHAPE_KEYS[kind]
    wrong = sorted(set(table) - {"kind", *required, *optional})
    missing = [k for k in required if k not in table]
    if wrong or missing:
        problems.append(f"{at}: a {kind} takes {', '.join(required + optional)}"
                        + (f" (unknown: {', '.join(wrong)})" if wrong else "")
                        + (f" (missing: {', '.join(missing)})" if missing else ""))
        return None
    if kind == "box":
        size = table["size_mm"]
        if not (isinstance(size, list) and len(size) == 3 and all(_size(v) for v in size)):
            problems.append(f"{at}: size_mm must be [across X, across Y, tall], each from "
                            f"{MIN_SIZE_MM:g} to {MAX_SIZE_MM:g} mm (sizes are in mm)")
            return None
        turn = table.get("turn_deg", 0.0)
        if not finite_number(turn):
            problems.append(f"{at}: turn_deg must be a number of degrees")
            return None
        return Part("box", float(size[2]), float(size[0]), turn_deg=float(turn),
                    depth_mm=float(size[1]))
    sizes = {k: table[k] for k in required}
    top = sizes.pop("top_diameter_mm", sizes.pop("end_diameter_mm", None))
    bad = [k for k, v in sizes.items() if not _size(v)]
    if top is not None and not (_size(top) or (kind == "frustum" and top == 0)):
        bad.append("top_diameter_mm" if kind == "frustum" else "end_diameter_mm")
    if bad:
        problems.append(f"{at}: {', '.join(bad)} must be from {MIN_SIZE_MM:g} to {MAX_SIZE_MM:g} "
                        "mm (sizes are in mm)"
                        + (" (a cone's top_diameter_mm may be 0)" if kind == "frustum" else ""))
        return None
    d = float(sizes["diameter_mm"])
    if kind == "sphere":
        return Part("barrel", d, d, 0.0)
    if kind == "barrel" and top >= d:
        problems.append(f"{at}: a barrel's end_diameter_mm must be below its diameter_mm (its "
                        "middle)")
        return None
    return Part(kind, float(sizes["height_mm"]), d, None if top is None else float(top))


def read_shape(value, where: str) -> tuple[Stack | None, list[str]]:
    """The stack a manifest's ``shape`` describes, or ``None`` and its problems (one line each,
    ``'WHERE: shape...: what; fix'``)."""
    tables = value if isinstance(value, list) else [value]
    problems: list[str] = []
    if not tables or len(tables) > MAX_DESCRIBED_PARTS:
        return None, [f"{where}: shape: give 1 to {MAX_DESCRIBED_PARTS} parts, bottom to top"]
    parts = [_part(t, f"{where}: shape" + (f"[{k}]" if isinstance(value, list) else ""), problems)
             for k, t in enumerate(tables)]
    is_sphere = [isinstance(t, dict) and t.get("kind") == "sphere" for t in tables]
    if len(tables) > 1 and any(is_sphere):
        problems.append(f"{where}: shape: a sphere stands alone (it touches a part above or below "
                        "at one point)")
    if problems:
        return None, problems
    return Stack(tuple(parts)), []


def _private_folder() -> Path:
    """This user's folder of described solids: ``pinchmatch-shapes-<uid>`` in the temporary
    directory, made 0700 and used only while it is a real folder this user owns that no one else may
    write; otherwise a fresh private folder of this process (shared temporary directories let anyone
    plant a file)."""
    folder = Path(tempfile.gettempdir()) / f"{SHAPES_FOLDER}-{os.getuid()}"
    try:
        folder.mkdir(mode=0o700, exist_ok=True)
        info = os.lstat(folder)
        if stat.S_ISDIR(info.st_mode) and info.st_uid == os.getuid() and not info.st_mode & 0o077:
            return folder
    except OSError:
        pass
    return Path(tempfile.mkdtemp(prefix=f"{SHAPES_FOLDER}-"))


def _whole_stl(path: Path) -> bool:
    """A regular file holding a whole binary STL: 84 bytes of header and count, 50 bytes a
    triangle."""
    try:
        info = os.lstat(path)
        if not stat.S_ISREG(info.st_mode) or info.st_size < 84:
            return False
        with open(path, "rb") as fh:
            count = int.from_bytes(fh.read(84)[80:84], "little")
        return count > 0 and info.st_size == 84 + 50 * count
    except OSError:
        return False


def shape_file(stack: Stack) -> Path:
    """The stack's solid as a binary STL in mm, +Z up, named by its parts and the code that builds
    it (written once per user; a damaged file is written again)."""
    text = json.dumps([p.as_dict() for p in stack.parts], sort_keys=True) + code_digest()
    digest = hashlib.sha256(text.encode()).hexdigest()[:24]
    folder = _private_folder()
    path = folder / f"{digest}.stl"
    if _whole_stl(path):
        return path
    data = stack_mesh(stack).export(file_type="stl")
    fd, partial = tempfile.mkstemp(dir=folder, suffix=".part")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(partial, path)  # whole or not at all, whoever writes it first
    except BaseException:
        Path(partial).unlink(missing_ok=True)
        raise
    return path
