"""The layering contract: no package imports one above it, no private name crosses a module.

mppf's packages are layers (``docs/architecture.md``, "Layers"), lowest first::

    core < model < geometry < examples < registration < forming < correct < planning
         < drivers < measure < sim < loop < report < panel < cli

A module may import its own package and any package below it, never one above. The scan reads
the source of every module of ``mppf/``, ``drivers/`` (``mppf.drivers``) and ``sim/``
(``mppf.sim``) with :mod:`ast`, the imports inside functions included, so a lazy import that
runs up fails as well. import-linter cannot do this here: it walks only the folder of the
top-level package, and ``mppf.drivers`` and ``mppf.sim`` are installed from other folders
(``package-dir`` in ``pyproject.toml``).
"""

from __future__ import annotations

import ast
import functools
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

LAYERS = ("core", "model", "geometry", "examples", "registration", "forming", "correct", "planning",
          "drivers", "measure", "sim", "loop", "report", "panel", "cli")
"""mppf's packages, lowest first (``mppf/__init__.py`` counts as ``core``, ``mppf/__main__.py`` as ``cli``)."""

FOLDERS = {"mppf": ROOT / "mppf", "mppf.drivers": ROOT / "drivers", "mppf.sim": ROOT / "sim"}
"""Where each installed package's source lies (``[tool.setuptools] package-dir``)."""

KNOWN_UPWARD: dict[tuple[str, str], str] = {}
"""Upward imports still to remove, (importer, imported module) -> why it is still there."""

KNOWN_PRIVATE: dict[tuple[str, str], str] = {}
"""Private names still imported across modules, (importer, imported module) -> why."""


@dataclass(frozen=True)
class Import:
    """One import statement of a module: who imports what, where."""

    importer: str
    path: Path
    line: int
    module: str
    names: tuple[str, ...]


def module_name(path: Path) -> str:
    """The dotted name of the module at ``path`` (``sim/plc/host.py`` -> ``mppf.sim.plc.host``)."""
    for package, folder in FOLDERS.items():
        if path.is_relative_to(folder):
            parts = list(path.relative_to(folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            return ".".join([package, *parts])
    raise ValueError(f"{path} lies in none of {sorted(map(str, FOLDERS.values()))}")


def source_files() -> list[Path]:
    """Every module of the three installed folders."""
    return sorted(p for folder in FOLDERS.values() for p in folder.rglob("*.py") if "__pycache__" not in p.parts)


def imports_of(path: Path) -> list[Import]:
    """The mppf imports of one module, at any depth (inside functions too), relative ones resolved."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found += [Import(name, path, node.lineno, a.name, ()) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([module] if module else []))
            found.append(Import(name, path, node.lineno, module, tuple(a.name for a in node.names)))
    return [i for i in found if i.module == "mppf" or i.module.startswith("mppf.")]


def layer_of(module: str) -> str:
    """The layer of a dotted mppf module name."""
    parts = module.split(".")
    if len(parts) == 1:
        return "core"  # the package root: its version and the root error
    return "cli" if parts[1] == "__main__" else parts[1]


@functools.cache
def model_names_of(module: str) -> dict[str, str]:
    """The names a module outside :mod:`mppf.model` takes from ``mppf.model.*`` at its top level -> that module."""
    path = next((p for p in source_files() if module_name(p) == module), None)
    if path is None or module.startswith("mppf.model"):
        return {}
    return {alias.asname or alias.name: node.module for node in ast.parse(path.read_text()).body
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("mppf.model.")
            for alias in node.names}


def taken_second_hand(found: list[Import]) -> list[str]:
    """Each shared type imported from a module that itself imports it from :mod:`mppf.model`, and where it lives."""
    return [f"{i.path.relative_to(ROOT)}:{i.line}: {i.importer} imports {n} from {i.module}; it lives in {home}"
            for i in found for n in i.names if (home := model_names_of(i.module).get(n))]


@functools.cache
def all_imports() -> tuple[Import, ...]:
    """Every mppf import of every module, read once per test session."""
    return tuple(i for path in source_files() for i in imports_of(path))


def test_every_package_has_a_layer():
    packages = {layer_of(module_name(p)) for p in source_files()}
    assert packages <= set(LAYERS), (f"package(s) {sorted(packages - set(LAYERS))} have no layer: add them to "
                                     "LAYERS in tests/test_layers.py and to docs/architecture.md")


def test_no_package_imports_one_above_it():
    rank = {layer: k for k, layer in enumerate(LAYERS)}
    upward = [i for i in all_imports() if rank[layer_of(i.module)] > rank[layer_of(i.importer)]]
    unexplained = [f"{i.path.relative_to(ROOT)}:{i.line}: {i.importer} ({layer_of(i.importer)}) imports "
                   f"{i.module} ({layer_of(i.module)}, a layer above)"
                   for i in upward if (i.importer, i.module) not in KNOWN_UPWARD]
    assert not unexplained, ("imports that run up the layers (docs/architecture.md, 'Layers'); move the shared "
                             "piece down or the importer up:\n" + "\n".join(unexplained))


def test_no_private_name_is_imported_from_another_module():
    private = [(i, n) for i in all_imports() for n in i.names
               if n.startswith("_") and not n.startswith("__") and i.module != i.importer]
    unexplained = [f"{i.path.relative_to(ROOT)}:{i.line}: {i.importer} imports {n} from {i.module}"
                   for i, n in private if (i.importer, i.module) not in KNOWN_PRIVATE]
    assert not unexplained, "private names imported across modules; make them public or move them:\n" + \
        "\n".join(unexplained)


def test_no_two_modules_import_each_other():
    """Within a layer too, the imports run one way (a lazy import inside a function counts)."""
    modules = {module_name(p) for p in source_files()}
    edges: dict[str, set[str]] = {}
    for i in all_imports():
        targets = {i.module} | {f"{i.module}.{n}" for n in i.names}  # "from mppf.planning import validate"
        edges.setdefault(i.importer, set()).update(targets & modules - {i.importer})
    pairs = sorted({tuple(sorted((a, b))) for a, bs in edges.items() for b in bs if a in edges.get(b, ())})
    assert not pairs, "modules that import each other; move what both need into a third module:\n" + \
        "\n".join(f"{a} <-> {b}" for a, b in pairs)


def test_the_known_exceptions_are_still_there():
    """An exception that no longer occurs is removed from the lists, so the contract only tightens."""
    pairs = {(i.importer, i.module) for i in all_imports()}
    gone = sorted(set(KNOWN_UPWARD) - pairs) + sorted(set(KNOWN_PRIVATE) - pairs)
    assert not gone, f"remove these fixed exceptions from tests/test_layers.py: {gone}"


@pytest.mark.parametrize(("source", "expected"), [
    ("from mppf.loop.cycle import run\n", ("mppf.loop.cycle", "loop")),
    ("def f():\n    from mppf.cli import main\n", ("mppf.cli", "cli")),
    ("from ..correct.step import x\n", ("mppf.correct.step", "correct")),
    ("import mppf.panel.app as app\n", ("mppf.panel.app", "panel")),
])
def test_the_scan_sees_every_kind_of_import(tmp_path, monkeypatch, source, expected):
    """The scan finds module-level, lazy, relative and aliased imports (a scan that saw none would pass)."""
    folder = tmp_path / "mppf" / "forming"
    folder.mkdir(parents=True)
    path = folder / "probe.py"
    path.write_text(source)
    monkeypatch.setitem(FOLDERS, "mppf", tmp_path / "mppf")
    (found,) = imports_of(path)
    assert (found.module, layer_of(found.module)) == expected
    assert found.importer == "mppf.forming.probe" and found.line >= 1


def test_every_package_is_installed():
    """A package folder missing from ``[tool.setuptools] packages`` is missing from a fresh (non-editable) install."""
    import tomllib

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    packages = {module_name(p) for p in source_files() if p.name == "__init__.py"} - {"mppf.examples"}  # package data
    assert packages <= listed, f"add {sorted(packages - listed)} to [tool.setuptools] packages in pyproject.toml"


def test_shared_types_are_imported_from_where_they_live():
    """The shared types (``mppf/model/``) are imported from there, never through a module that uses them."""
    second_hand = taken_second_hand(list(all_imports()))
    assert not second_hand, "import these names from mppf.model:\n" + "\n".join(second_hand)


def test_a_name_taken_through_its_old_home_is_found():
    """``PressConfig`` taken from :mod:`mppf.planning.press` (which uses it) is named; ``machine_press`` is not."""
    old = Import("mppf.correct.probe", ROOT / "mppf/correct/probe.py", 1, "mppf.planning.press",
                 ("PressConfig", "machine_press"))
    assert taken_second_hand([old]) == [("mppf/correct/probe.py:1: mppf.correct.probe imports PressConfig from "
                                         "mppf.planning.press; it lives in mppf.model.press")]
