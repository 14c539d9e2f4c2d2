"""Frames files come in: units, up directions, and what size says about the units.

A mesh file's coordinates carry no unit (glTF's are metres by its specification) and no up
direction (glTF's is +Y). pinchmatch works in millimetres with each object's up known; this module
holds the units and up directions a file may be read in, and the check that an object read in
some unit has a size a hand could hold, with the units that would make it so. It imports nothing
heavy, so that the command line's parser can name the choices without loading the mesh stack.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

from ..errors import ConfigError, MeshError, option

#: millimetres per unit
UNITS_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}

#: the unit vector of each up direction a file may have
UP_VECTORS = {
    "x": (1.0, 0.0, 0.0),
    "y": (0.0, 1.0, 0.0),
    "z": (0.0, 0.0, 1.0),
    "-x": (-1.0, 0.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
    "-z": (0.0, 0.0, -1.0),
}

#: an object whose largest side is outside this range (mm) surely has the wrong units:
#: nothing smaller than a grain of rice or larger than a room is pinched.
PLAUSIBLE_SIZE_MM = (2.0, 10_000.0)
#: the sizes (mm) of objects a hand holds in a pinch, for suggesting units
GRASPABLE_SIZE_MM = (10.0, 500.0)


def parse_up(up: str, *, source: str = "--up") -> tuple[str, np.ndarray]:
    """Return the label and unit vector of an up direction like ``"z"`` or ``"-y"``."""
    import numpy as np  # here, not at import: the parser names the choices without numpy

    key = str(up).strip().lower()
    if key not in UP_VECTORS:
        raise ConfigError(
            f"{source}: unknown up direction {up!r}; use one of {', '.join(UP_VECTORS)}"
        )
    return key, np.array(UP_VECTORS[key])


def level_turn(up: str | None):
    """(3, 3) the rotation that turns a level whose up is ``up`` (a label, None: glTF's ``y``) into
    glTF's frame (+Y up), by the least turn: a z-up level turns about +X by -90 degrees (its +Z to
    +Y, its -Y to +Z, as Blender's glTF exporter turns it), so its "front" (glTF's +Z) is its -Y."""
    import numpy as np

    turns = {"y": ("x", 0.0), "z": ("x", -90.0), "-z": ("x", 90.0), "x": ("z", 90.0),
             "-x": ("z", -90.0), "-y": ("x", 180.0)}
    axis, deg = turns[parse_up(up or "y")[0]]
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    if axis == "x":
        return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def check_units(path: Path, extent_mm: float, units_in: str) -> None:
    """Raise MeshError when an object read in ``units_in`` is ``extent_mm`` across, a size nothing a
    hand pinches has, naming the units that would give it a graspable size."""
    lo, hi = PLAUSIBLE_SIZE_MM
    if lo <= extent_mm <= hi:
        return
    raw = extent_mm / UNITS_MM[units_in]
    problem = "small" if extent_mm < lo else "large"
    raise MeshError(
        f"{path}: mesh is {extent_mm:.4g} mm across when read in {units_in} (too {problem} "
        f"to pinch; were its units not {units_in}?); {units_hint(raw, units_in)}"
    )


def units_hint(raw: float, units_in: str) -> str:
    """The units that make an object ``raw`` file units across a size a hand holds, both where two
    do."""
    size = {u: raw * s for u, s in UNITS_MM.items() if u != units_in}
    lo, hi = GRASPABLE_SIZE_MM
    fits = sorted((u for u, mm in size.items() if lo <= mm <= hi),
                  key=lambda u: abs(math.log(size[u] / 100.0)))
    if not fits:
        plausible = [u for u, mm in size.items() if PLAUSIBLE_SIZE_MM[0] <= mm
                     <= PLAUSIBLE_SIZE_MM[1]]
        fits = sorted(plausible, key=lambda u: abs(math.log(size[u] / 100.0)))[:1]
    if not fits:
        return "scale the mesh to real size"
    return "read it with " + " or ".join(f"{option('units', u)} ({size[u]:.3g} mm across)"
                                         for u in fits[:2])


def cross_matrices(v: np.ndarray) -> np.ndarray:
    """(k, 3) -> (k, 3, 3) cross-product matrices: ``cross_matrices(v) @ w == np.cross(v, w)``."""
    import numpy as np

    K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return K


def rotations_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(k, 3, 3) smallest rotations taking unit vectors a (k, 3) onto b (k, 3).

    Opposite vectors get a half turn about an axis perpendicular to them.

    Parameters
    ----------
    a, b : (k, 3) float64
        Unit vectors.

    Returns
    -------
    (k, 3, 3) float64
        The rotations taking each ``a`` onto its ``b``.

    Examples
    --------
    >>> import numpy as np
    >>> R = rotations_between(np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 1.0, 0.0]]))
    >>> np.round(R[0] @ [0.0, 0.0, 1.0], 12) + 0.0
    array([0., 1., 0.])
    """
    import numpy as np  # here, not at the top: the command line's parser imports this module

    c = np.einsum("kd,kd->k", a, b)
    K = cross_matrices(np.cross(a, b))
    R = np.eye(3) + K + (K @ K) / np.maximum(1.0 + c, 1e-300)[:, None, None]
    opposite = c < -1.0 + 1e-12
    if opposite.any():  # a half turn about any perpendicular axis
        ao = a[opposite]
        perp = np.cross(ao, [1.0, 0.0, 0.0])
        small = np.linalg.norm(perp, axis=1) < 1e-6
        perp[small] = np.cross(ao[small], [0.0, 1.0, 0.0])
        perp /= np.linalg.norm(perp, axis=1, keepdims=True)
        R[opposite] = 2.0 * perp[:, :, None] * perp[:, None, :] - np.eye(3)
    return R
