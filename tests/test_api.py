"""The library's public API: what ``import pinchmatch`` offers, how it is called, what it raises.

Every public name resolves, is seen by static tools, and has a docstring; every public function
has an example, and the examples run here (``doctest`` over the API's modules, on the files in
``EXAMPLE_FILES``).
"""

import ast
import doctest
import importlib
import inspect
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

import pinchmatch
from pinchmatch import ConfigError

INIT = Path(pinchmatch.__file__)


def test_every_public_name_resolves_and_static_tools_see_it():
    tree = ast.parse(INIT.read_text())
    checked = [n for n in tree.body if isinstance(n, ast.If) and ast.unparse(n.test)
               == "TYPE_CHECKING"]
    assert len(checked) == 1
    seen = {}
    for node in checked[0].body:
        assert isinstance(node, ast.ImportFrom) and node.level == 1
        seen.update({a.name: node.module for a in node.names})
    assert seen == pinchmatch._API
    assert sorted(pinchmatch.__all__) == sorted([*pinchmatch._API, "__version__"])
    for name, module in pinchmatch._API.items():
        value = getattr(pinchmatch, name)
        assert value is getattr(importlib.import_module(f"pinchmatch.{module}"), name)
        assert inspect.getdoc(value), f"{name} has no docstring"


@pytest.mark.parametrize("name",
                         ["select_props", "coverage_curve", "design_props", "DesignSettings",
                          "calibrate",
                                  "read_ratings", "register_poses", "CostModel", "Weights",
                                  "evaluate_pairs"])
def test_what_the_readme_sells_is_exported(name):
    assert name in pinchmatch.__all__


def _functions():
    return sorted(n for n in pinchmatch._API if inspect.isfunction(getattr(pinchmatch, n)))


@pytest.mark.parametrize("name", _functions())
def test_every_public_function_has_an_example(name):
    doc = inspect.getdoc(getattr(pinchmatch, name))
    assert ">>> " in doc, f"{name}: no example in its docstring"


def _section(doc: str, title: str) -> list[str]:
    """The lines of a numpy-style section of ``doc`` (its entries and their descriptions)."""
    lines = doc.splitlines()
    for k in range(len(lines) - 1):
        if lines[k].strip() == title and set(lines[k + 1].strip()) == {"-"}:
            out = []
            for line in lines[k + 2:]:
                if line.strip() and not line.startswith(" ") and out and not out[-1].strip():
                    break  # the next section's title, or the examples' text
                out.append(line)
            return out
    return []


@pytest.mark.parametrize("name", _functions())
def test_every_public_function_documents_its_parameters_and_what_it_returns(name):
    """numpy-style ``Parameters`` naming every parameter of the signature (``a, b : type`` names
    two), and ``Returns``."""
    function = getattr(pinchmatch, name)
    doc = inspect.getdoc(function)
    named = set()
    for line in _section(doc, "Parameters"):
        if line and not line.startswith(" ") and " : " in line:
            named |= {n.strip() for n in line.split(" : ")[0].split(",")}
        elif line.startswith("**"):
            named.add(line.strip())
    params = {("**" + p.name) if p.kind is p.VAR_KEYWORD else p.name
              for p in inspect.signature(function).parameters.values()}
    assert named == params, f"{name}: documented {sorted(named)}, takes {sorted(params)}"
    assert any(line.strip() for line in _section(doc, "Returns")), f"{name}: no Returns section"


def _callables():
    """Every public function of the API and every public method of its classes, by name."""
    out = []
    for name in sorted(pinchmatch._API):
        value = getattr(pinchmatch, name)
        if inspect.isfunction(value):
            out.append((name, value))
        elif inspect.isclass(value):
            out += [(f"{name}.{m}", f) for m, f in sorted(vars(value).items())
                    if inspect.isfunction(f) and not m.startswith("_")]
    return out


@pytest.mark.parametrize("name, function", _callables(), ids=[n for n, _ in _callables()])
def test_options_of_longer_signatures_are_keyword_only(name, function):
    """A function of more than two parameters takes its options (those with a default) by name only:
    ``select_props(cost, loud, 2, "max")`` cannot be read as anything but what it is."""
    params = [p for p in inspect.signature(function).parameters.values()
              if p.name not in ("self", "cls")]
    positional = [p.name for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
                  and p.default is not p.empty]
    assert len(params) <= 2 or not positional, f"{name}: {positional} should follow a '*'"


def test_an_option_given_by_position_is_refused():
    cost = np.array([[0.2, 1.5], [2.0, 0.3]])
    with pytest.raises(TypeError):
        pinchmatch.select_props(cost, cost >= 1.0, 1, "max")
    assert pinchmatch.select_props(cost, cost >= 1.0, 1, objective="max").props.shape == (1,)


@pytest.fixture(scope="module")
def example_files(tmp_path_factory):
    """The files the examples read: a 60 x 40 x 20 mm box (STL, mm) and a can 54 mm across and 66 mm
    tall in metres (OBJ), and a manifest listing both."""
    folder = tmp_path_factory.mktemp("examples")
    trimesh.creation.box(extents=(60.0, 40.0, 20.0)).export(folder / "box.stl")
    can = trimesh.creation.cylinder(radius=0.027, height=0.066, sections=64)
    can.apply_translation((0.0, 0.0, 0.033))
    can.export(folder / "can.obj")
    (folder / "props.toml").write_text('[[object]]\nfile = "box.stl"\nname = "box"\nmass_g = '
                                       '120\n\n'
                                       '[[object]]\nfile = "can.obj"\nname = "can"\nunits = "m"\n')
    return {"box_stl": str(folder / "box.stl"), "can_obj": str(folder / "can.obj"),
            "props_toml": str(folder / "props.toml")}


def test_the_examples_run(example_files, monkeypatch):
    """Each module of the API, its docstrings' examples (with the example files as globals)."""
    modules = sorted({f"pinchmatch.{m}" for m in pinchmatch._API.values()})
    monkeypatch.setattr(np, "set_printoptions", np.set_printoptions)  # examples may print arrays
    failed, tried = [], 0
    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    with np.printoptions(precision=4, suppress=True):
        for name in modules:
            module = importlib.import_module(name)
            for test in finder.find(module, globs=dict(vars(module)) | example_files):
                if test.examples:
                    result = runner.run(test, out=sys.stdout.write)
                    tried += result.attempted
                    if result.failed:
                        failed.append(test.name)
    assert not failed, f"failing examples: {failed}"
    assert tried >= 2 * len(_functions())


@pytest.mark.parametrize("function, data",
                         [("match_scene", 2), ("match_virtual", 2), ("evaluate_pairs", 4)])
def test_options_are_keyword_only_and_default_to_none(function, data):
    params = list(inspect.signature(getattr(pinchmatch, function)).parameters.values())
    assert all(p.kind is p.POSITIONAL_OR_KEYWORD and p.default is p.empty for p in params[:data])
    options = params[data:]
    assert options and all(p.kind is p.KEYWORD_ONLY and p.default is None for p in options), options


def test_bad_arguments_raise_config_error():
    from pinchmatch.mesh.stacks import Part

    cost, loud = np.array([[1.0, 2.0]]), np.zeros((1, 2), bool)
    with pytest.raises(ConfigError, match="k = 3 for a shelf of 2 props"):
        pinchmatch.select_props(cost, loud, 3)
    with pytest.raises(ConfigError, match="objective 'median'"):
        pinchmatch.select_props(cost, loud, 1, objective="median")
    with pytest.raises(ConfigError, match="unknown part 'blob'"):
        Part("blob", 10.0, 10.0)
    with pytest.raises(ConfigError, match="a frustum needs top_width_mm"):
        Part("frustum", 10.0, 10.0)


def test_a_cost_model_completes_its_weights_as_match_settings_do():
    model = pinchmatch.CostModel(weights={"width": 2})
    settings = pinchmatch.MatchSettings(weights={"width": 2})
    assert dict(model.weights) == dict(settings.weights)
    assert (model.weights["width"] == 2.0 and model.weights["kmax"] == 1.0 and model.weights["com"]
            == 0.0)
    for bad in ({"widht": 1}, {"width": -1}, {"width": float("nan")}):
        with pytest.raises(ConfigError):
            pinchmatch.CostModel(weights=bad)


def test_frozen_records_hold_no_mutable_state():
    settings = pinchmatch.MatchSettings(weights={"width": 2})
    model = pinchmatch.CostModel(weights={"width": 2})
    for weights in (settings.weights, model.weights):
        with pytest.raises(TypeError):
            weights["width"] = 5.0  # read-only
    assert hash(settings.weights) == hash(model.weights)
    fields = {f.name for f in pinchmatch.Candidates.__dataclass_fields__.values()}
    # the reference search's memo is its caller's, not the candidates'
    assert "probes" not in fields


def _imports(path: Path, package: str) -> set[str]:
    """The pinchmatch modules a module imports, at the top or inside a function (not under
    TYPE_CHECKING)."""
    tree = ast.parse(path.read_text())
    skip = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If)
            and "TYPE_CHECKING" in ast.unparse(node.test)
            for n in ast.walk(node)}
    found = set()
    for node in ast.walk(tree):
        if id(node) in skip or not isinstance(node, ast.ImportFrom):
            continue
        if node.level:
            base = package.split(".")[: len(package.split(".")) - node.level + 1]
            target = ".".join(base + ([node.module] if node.module else []))
        elif (node.module or "").startswith("pinchmatch"):
            target = node.module
        else:
            continue
        found.add(target)
        found.update(f"{target}.{a.name}" for a in node.names)  # from . import commands
    return {m for m in found if _is_module(m)}


def _is_module(name: str) -> bool:
    root = INIT.parent.parent
    path = root / Path(*name.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def test_no_module_imports_itself_through_others():
    root = INIT.parent
    graph = {}
    for path in root.rglob("*.py"):
        rel = path.relative_to(root.parent).with_suffix("")
        parts = list(rel.parts)
        is_package = parts[-1] == "__init__"
        name = ".".join(parts[:-1] if is_package else parts)
        package = name if is_package else name.rsplit(".", 1)[0]
        graph[name] = {m for m in _imports(path, package) if m != name and m != "pinchmatch"}
    cycles = []
    state: dict[str, int] = {}

    def visit(node, stack):
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                cycles.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, stack + [nxt])
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    assert not cycles, cycles
