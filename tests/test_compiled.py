"""Where the compiled kernels are kept when pinchmatch is installed where its user cannot write."""

import os
from pathlib import Path

from pinchmatch import compiled


def test_a_writable_package_or_a_given_folder_leaves_numba_its_own_choice(monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", "/somewhere")
    assert compiled.kernel_cache_dir() is None
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.setattr(compiled.os, "access", lambda path, mode: True)
    assert compiled.kernel_cache_dir() is None


def test_a_read_only_package_sends_the_kernels_to_the_users_cache_else_to_the_temporary_one(
        tmp_path, monkeypatch):
    package = Path(compiled.__file__).resolve().parent
    real_access = os.access
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setattr(compiled.os, "access", lambda path,
                        mode: not str(path).startswith(str(package))
                        and real_access(path, mode))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert compiled.kernel_cache_dir() == str(tmp_path / "cache" / "pinchmatch" / "numba")
    assert (tmp_path / "cache" / "pinchmatch" / "numba").is_dir()
    # no home to write in (a file where the cache folder would go): a folder of the user's in the
    # temporary folder
    (tmp_path / "file").write_text("not a folder")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "file"))
    monkeypatch.setattr(compiled.tempfile, "gettempdir", lambda: str(tmp_path / "tmp"))
    assert compiled.kernel_cache_dir() == str(tmp_path / "tmp" / f"pinchmatch-numba-{os.getuid()}")
