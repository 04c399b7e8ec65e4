"""The layering contract: import-linter's contracts, and what import-linter cannot see.

mppf's packages are layers (``docs/architecture.md``, "Layers"), lowest first::

    core < model < geometry < examples < registration < forming < correct < planning
         < drivers < measure < sim < loop < report < panel < cli

The layers and the rule that no modules of a package import each other in a circle are two
import-linter contracts in ``pyproject.toml`` (``[tool.importlinter]``), checked here by running
``lint-imports``. grimp, under import-linter, walks only the folder of the top-level package, and
``mppf.drivers`` and ``mppf.sim`` are installed from ``drivers/`` and ``sim/`` (``package-dir``), so
the run is on a link tree: a temporary ``mppf/`` whose entries link to the repository's, with
``drivers`` and ``sim`` linked in, and ``lint-imports`` run in the folder above it (it puts its working
directory first on ``sys.path``; ``PYTHONPATH`` names it too), so that this ``mppf`` is the one found.

import-linter sees modules, not names. The scan of the sources with :mod:`ast` (every module of
``mppf/``, ``drivers/`` and ``sim/``, imports inside functions included) checks what it cannot:
no private name (``_name``) imported from another module, shared types imported from where they
live, and no package and one of its own modules importing each other.
"""

from __future__ import annotations

import ast
import functools
import os
import subprocess
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

FOLDERS = {"mppf": ROOT / "mppf", "mppf.drivers": ROOT / "drivers", "mppf.sim": ROOT / "sim"}
"""Where each installed package's source lies (``[tool.setuptools] package-dir``)."""

KNOWN_PRIVATE: dict[tuple[str, str], str] = {}
"""Private names still imported across modules, (importer, imported module) -> why."""

LINT_IMPORTS = "import sys; from importlinter.cli import lint_imports_command; sys.exit(lint_imports_command())"
"""The ``lint-imports`` script's own code (import-linter's entry point), run by this interpreter."""

LINT_TIMEOUT_S = 120.0
"""Longest a ``lint-imports`` run may take (about 0.5 s on an idle 2-core machine)."""


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


def link_tree(dest: Path) -> Path:
    """A folder for ``PYTHONPATH`` whose ``mppf/`` holds all three installed packages; returns ``dest``.

    ``dest/mppf`` is a real folder whose entries link to those of the repository's ``mppf/``, with
    ``drivers`` and ``sim`` linking to ``drivers/`` and ``sim/``. grimp walks the folder of the top-level
    package it imports (following links), so it finds ``mppf.drivers`` and ``mppf.sim`` there. Nothing is
    copied and nothing in the repository changes.
    """
    package = dest / "mppf"
    package.mkdir(parents=True)
    for entry in FOLDERS["mppf"].iterdir():
        if entry.name != "__pycache__":
            (package / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    for name, folder in FOLDERS.items():
        if name != "mppf":
            (package / name.rpartition(".")[2]).symlink_to(folder, target_is_directory=True)
    return dest


def open_up(link: Path) -> Path:
    """Turn a link to a folder of the link tree into a real folder of links, so a test may add a module to it."""
    target = link.resolve()
    link.unlink()
    link.mkdir()
    for entry in target.iterdir():
        if entry.name != "__pycache__":
            (link / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    return link


def lint_imports(tree: Path, command: list[str] | None = None) -> subprocess.CompletedProcess[str]:
    """Run ``lint-imports`` with the contracts of ``pyproject.toml`` on the link tree ``tree``, no cache.

    The script beside this interpreter, else (where pip put scripts elsewhere) its entry point.
    """
    if command is None:
        script = Path(sys.executable).with_name("lint-imports")
        command = [str(script)] if script.exists() else [sys.executable, "-c", LINT_IMPORTS]
    return subprocess.run([*command, "--no-cache", "--no-logo", str(ROOT / "pyproject.toml")], cwd=tree,
                          env=os.environ | {"PYTHONPATH": str(tree)}, capture_output=True, text=True,
                          timeout=LINT_TIMEOUT_S, check=False)


def test_import_linter_keeps_the_contracts(tmp_path):
    """No package imports one above it; no modules of a package import each other in a circle; every package
    has a layer. It reads every module of the three folders (a run that saw fewer would pass too easily)."""
    run = lint_imports(link_tree(tmp_path))
    assert run.returncode == 0, run.stdout + run.stderr
    assert f"Analyzed {len(source_files())} files" in run.stdout, run.stdout
    assert "Contracts: 2 kept, 0 broken." in run.stdout, run.stdout


@pytest.mark.parametrize(("package", "modules", "broken"), [
    ("core", {"probe.py": "def f():\n    from mppf.sim.shop import run\n"}, "- mppf.core.probe -> mppf.sim.shop (l.2)"),
    ("drivers", {"probe.py": "from mppf.loop import cycle\n"}, "- mppf.drivers.probe -> mppf.loop.cycle (l.1)"),
    ("report", {"probe_a.py": "from mppf.report import probe_b\n", "probe_b.py": "import mppf.report.probe_a\n"},
     "No cycles are allowed in mppf.report."),
])
def test_import_linter_fails_on_a_broken_contract(tmp_path, package, modules, broken):
    """An upward import (a lazy one, one from ``drivers/``) or a circle, written into the link tree, fails the run."""
    folder = open_up(link_tree(tmp_path) / "mppf" / package)
    for name, source in modules.items():
        (folder / name).write_text(source)
    run = lint_imports(tmp_path)
    assert run.returncode == 1, run.stdout + run.stderr
    assert broken in run.stdout, run.stdout


def test_the_entry_point_of_lint_imports_checks_the_same(tmp_path):
    """The fallback where the script is not beside the interpreter: the same contracts, the same failure."""
    (open_up(link_tree(tmp_path) / "mppf" / "model") / "probe.py").write_text("import mppf.planning.job\n")
    run = lint_imports(tmp_path, [sys.executable, "-c", LINT_IMPORTS])
    assert run.returncode == 1, run.stdout + run.stderr
    assert "- mppf.model.probe -> mppf.planning.job (l.1)" in run.stdout, run.stdout


def test_import_linter_fails_on_a_package_without_a_layer(tmp_path):
    (link_tree(tmp_path) / "mppf" / "probe").mkdir()
    (tmp_path / "mppf" / "probe" / "__init__.py").write_text("")
    run = lint_imports(tmp_path)
    assert run.returncode == 1, run.stdout + run.stderr
    assert "- mppf.probe\n" in run.stdout, run.stdout


def test_the_documented_order_is_the_contract():
    """``docs/architecture.md`` lists the layers of the contract in ``pyproject.toml``, lowest first."""
    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
    (layers,) = [c["layers"] for c in contracts if c["type"] == "layers"]
    text = (ROOT / "docs" / "architecture.md").read_text().split("## Layers", 1)[1]
    block = text.split("```", 2)[1]
    assert [name.strip() for name in block.split("<")] == layers[::-1]


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
    """An exception that no longer occurs is removed from the list, so the contract only tightens."""
    pairs = {(i.importer, i.module) for i in all_imports()}
    gone = sorted(set(KNOWN_PRIVATE) - pairs)
    assert not gone, f"remove these fixed exceptions from tests/test_layers.py: {gone}"


@pytest.mark.parametrize(("source", "expected"), [
    ("from mppf.loop.cycle import run\n", "mppf.loop.cycle"),
    ("def f():\n    from mppf.cli import main\n", "mppf.cli"),
    ("from ..correct.step import x\n", "mppf.correct.step"),
    ("import mppf.panel.app as app\n", "mppf.panel.app"),
])
def test_the_scan_sees_every_kind_of_import(tmp_path, monkeypatch, source, expected):
    """The scan finds module-level, lazy, relative and aliased imports (a scan that saw none would pass)."""
    folder = tmp_path / "mppf" / "forming"
    folder.mkdir(parents=True)
    path = folder / "probe.py"
    path.write_text(source)
    monkeypatch.setitem(FOLDERS, "mppf", tmp_path / "mppf")
    (found,) = imports_of(path)
    assert found.module == expected
    assert found.importer == "mppf.forming.probe" and found.line >= 1


def test_every_package_is_installed():
    """A package folder missing from ``[tool.setuptools] packages`` is missing from a fresh (non-editable) install."""
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
