"""Write the ``.meta`` file of every asset and folder of the Unity package that lacks one.

A package added by git URL is read-only in Unity, and Unity ignores an asset there that has no
``.meta`` file ("has no meta file, but it's in an immutable folder"), so the package carries them.
Folders and files whose names end in ``~`` (and everything inside them) are hidden from Unity and
get none. Each GUID is derived from the asset's path in the package (MD5 of the path), so that
running this again gives the same files; an existing ``.meta`` is never changed.

usage: python tools/unity_meta.py [PACKAGE_DIR]   (default: unity/com.pinchmatch.unity)
"""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "unity" / "com.pinchmatch.unity"

#: the importer Unity gives each kind of asset
IMPORTERS = {".cs": "MonoImporter", ".asmdef": "AssemblyDefinitionImporter",
             ".md": "TextScriptImporter", ".json": "TextScriptImporter"}
TAIL = "  externalObjects: {}\n  userData: \n  assetBundleName: \n  assetBundleVariant: \n"
MONO = ("  serializedVersion: 2\n  defaultReferences: []\n  executionOrder: 0\n"
        "  icon: {instanceID: 0}\n")


def hidden(path: Path, package: Path) -> bool:
    """Does Unity skip this path (a part ending in ``~`` or starting with ``.``)?"""
    return any(p.endswith("~") or p.startswith(".") for p in path.relative_to(package).parts)


def guid(path: Path, package: Path) -> str:
    return hashlib.md5(path.relative_to(package).as_posix().encode()).hexdigest()


def meta_text(path: Path, package: Path) -> str:
    head = f"fileFormatVersion: 2\nguid: {guid(path, package)}\n"
    if path.is_dir():
        return head + "folderAsset: yes\nDefaultImporter:\n" + TAIL
    if path.name == "package.json":
        return head + "PackageManifestImporter:\n" + TAIL
    importer = IMPORTERS.get(path.suffix, "DefaultImporter")
    return head + f"{importer}:\n" + (MONO if importer == "MonoImporter" else "") + TAIL


def assets(package: Path) -> list[Path]:
    """Every file and folder of the package that Unity imports (not the .meta files)."""
    return sorted(p for p in package.rglob("*")
                  if not hidden(p, package) and p.suffix != ".meta")


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    package = Path(argv[0]) if argv else PACKAGE
    written = 0
    for path in assets(package):
        meta = path.with_name(path.name + ".meta")
        if not meta.exists():
            meta.write_text(meta_text(path, package))
            written += 1
    print(f"{written} .meta files written in {package}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
