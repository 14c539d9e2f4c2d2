"""numba's ``njit``, with a place to keep the compiled kernels wherever pinchmatch is installed.

The kernels (:mod:`pinchmatch.mesh.topology_kernel`, ``neighbours_kernel``,
``distance_field_kernel``, ``lowest_kernel``, :mod:`pinchmatch.grasp.jets`, ``spread_kernel``) are
compiled on first use and kept on disk (``cache=True``). numba keeps them beside the source, or else
in the user's cache folder; where neither can be written (a package installed read-only for a user
with no writable home) numba refuses to compile a cached kernel at all. So, unless
``NUMBA_CACHE_DIR`` says where, a package folder that cannot be written sends the kernels to
``$XDG_CACHE_HOME/pinchmatch/numba`` (``~/.cache/...``), else to a folder of this user's in the
system's temporary folder. Set before numba is first imported, so workers inherit it.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def _writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return os.access(folder, os.W_OK | os.X_OK)


def kernel_cache_dir() -> str | None:
    """Where numba should keep the kernels: None where its own choice works (module notes)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    package = Path(__file__).resolve().parent
    if all(os.access(p, os.W_OK | os.X_OK) for p in (package / "mesh", package / "grasp")):
        return None
    base = Path(os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"))
    for folder in (base / "pinchmatch" / "numba",
                   Path(tempfile.gettempdir()) / f"pinchmatch-numba-{os.getuid()}"):
        if _writable(folder):
            return str(folder)
    return None


_FOLDER = kernel_cache_dir()
if _FOLDER is not None:
    os.environ["NUMBA_CACHE_DIR"] = _FOLDER

from numba import njit  # noqa: E402  (after the cache folder is chosen)

__all__ = ["njit", "kernel_cache_dir"]
