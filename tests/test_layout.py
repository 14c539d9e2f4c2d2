"""The package's layout is the pipeline: stage contracts hold, no private names cross modules,
modules stay small, and the public API resolves."""

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import pinchmatch

PACKAGE = Path(pinchmatch.__file__).parent
MODULES = sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def test_the_stage_contracts_hold():
    """lint-imports checks the contracts of pyproject.toml: a stage never imports a later one."""
    tool = (shutil.which("lint-imports", path=os.path.dirname(sys.executable))
            or shutil.which("lint-imports"))
    if tool is None:
        pytest.fail("lint-imports (import-linter) is not installed; pip install -e '.[test]'")
    root = PACKAGE.parents[1]
    done = subprocess.run([tool, "--no-cache", "--config", str(root / "pyproject.toml")], cwd=root,
                          capture_output=True, text=True,
                          env=dict(os.environ, PYTHONPATH=str(PACKAGE.parent)), timeout=120)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert "0 broken" in done.stdout


def _imports(path: Path):
    """(module imported from, name) of every ``from ... import name`` in a module of the package."""
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if (isinstance(node, ast.ImportFrom)
            and (node.level > 0 or (node.module or "").startswith("pinchmatch"))):
            for alias in node.names:
                yield node.module, alias.name


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_private_name_crosses_a_module(path):
    private = [f"{module}.{name}" for module, name in _imports(path) if name.startswith("_")
               and name != "__version__"]
    assert not private, (f"{path.name} imports private names {private}; make them public in their "
                         "own module")


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_modules_hold_one_concept_each(path):
    assert len(path.read_text().splitlines()) <= 600


#: the longest line a module may hold, in UTF-8 bytes (code, comments, docstrings)
MAX_LINE = 100


#: the repository's other Python: the tests, the benchmarks and the tools
SCRIPTS = sorted(p for folder in ("tests", "benchmarks", "tools")
                 for p in (PACKAGE.parents[1] / folder).glob("*.py"))


@pytest.mark.parametrize("path", MODULES + SCRIPTS,
                         ids=lambda p: str(p.relative_to(PACKAGE.parents[1])))
def test_lines_are_at_most_100_characters(path):
    """Counted in UTF-8 bytes, as most tools count them: a σ or a ≤ takes two or three."""
    long = [f"{path.name}:{k}: {len(line.encode())} bytes" for k, line in
            enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
            if len(line.encode()) > MAX_LINE]
    assert not long, "lines over 100 characters; break them:\n" + "\n".join(long)


def test_the_public_api_resolves_to_its_defining_modules():
    for name in pinchmatch.__all__:
        value = getattr(pinchmatch, name)
        if name != "__version__":
            assert value.__module__.startswith("pinchmatch."), name
    with pytest.raises(AttributeError):
        pinchmatch.no_such_name  # noqa: B018


def test_importing_the_package_loads_no_stage():
    """``import pinchmatch`` is cheap: the API resolves on first use (the command line starts
    fast)."""
    code = ("import sys, pinchmatch; print(sorted(m for m in sys.modules if "
            "m.startswith('pinchmatch.')))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.stdout.strip() == "['pinchmatch.version']"


def test_every_mutant_listed_as_equivalent_names_a_line_of_the_code():
    import importlib.util

    path = Path(__file__).parents[1] / "benchmarks" / "mutation.py"
    spec = importlib.util.spec_from_file_location("mutation", path)
    mutation = importlib.util.module_from_spec(spec)
    sys.modules["mutation"] = mutation  # its dataclasses look their module up
    spec.loader.exec_module(mutation)
    for module, line, description in mutation.EQUIVALENT:
        assert module in mutation.CORE, module
        source = [s.strip() for s in (PACKAGE / module).read_text().splitlines()]
        assert line in source, (module, line)
        assert (mutation.EQUIVALENT[(module, line,
                                     description)]), "an equivalent mutant needs its reason"


@pytest.mark.parametrize("argv",
                         [["--help"], ["match", "--help"], ["--version"], ["match", "--bogus"], []])
def test_help_version_and_bad_options_answer_without_loading_the_pipeline(argv):
    code = ("import sys\nfrom pinchmatch.cli.main import main\n"
            "try:\n    main(sys.argv[1:])\nexcept SystemExit:\n    pass\n"
            "heavy = [m for m in ('numpy', 'scipy', 'trimesh', 'matplotlib', "
            "'pinchmatch.cli.commands') if m in sys.modules]\n"
            "print(heavy, file=sys.stderr)")
    done = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True,
                          timeout=60)
    assert done.stderr.strip().splitlines()[-1] == "[]", done.stderr
