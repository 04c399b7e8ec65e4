"""Tests mirror the package: each module of ``mppf.cli`` and ``mppf.panel`` has its own test module.

The mirrored name of ``mppf/<stage>/<module>.py`` is ``tests/<stage>/test_<module>.py`` (a leading
underscore dropped: ``mppf/cli/_common.py`` -> ``tests/cli/test_common.py``), or
``tests/<stage>/test_<stage>_<module>.py`` where two stages have a module of one name (the test folders
are not packages, so test module names are unique across ``tests/``); see ``docs/architecture.md``,
"Rules".
"""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

MIRRORED_STAGES = ("cli", "panel")
"""The stages every module of which has a mirrored test module."""


def mirrored_names(module: Path) -> tuple[Path, Path]:
    """The two test modules that may mirror ``mppf/<stage>/<module>.py``."""
    stage, name = module.parent.name, module.stem.lstrip("_")
    return ROOT / "tests" / stage / f"test_{name}.py", ROOT / "tests" / stage / f"test_{stage}_{name}.py"


def unmirrored(stage: str) -> list[str]:
    """The modules of ``mppf/<stage>/`` without a mirrored test module."""
    modules = sorted(p for p in (ROOT / "mppf" / stage).glob("*.py") if p.name != "__init__.py")
    return [str(p.relative_to(ROOT)) for p in modules if not any(t.exists() for t in mirrored_names(p))]


@pytest.mark.parametrize("stage", MIRRORED_STAGES)
def test_every_module_has_its_mirrored_test_module(stage):
    missing = unmirrored(stage)
    assert not missing, (f"add tests/{stage}/test_<module>.py for each of these (or rename the test module that "
                         "covers it):\n" + "\n".join(missing))


def test_a_module_without_a_test_is_found(tmp_path, monkeypatch):
    """A module whose only test carries another name is named; ``_common.py`` is mirrored by ``test_common.py``."""
    for path in ("mppf/cli/_common.py", "mppf/cli/probe.py", "mppf/cli/__init__.py", "tests/cli/test_common.py",
                 "tests/cli/test_probe_cmd.py"):
        (tmp_path / path).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / path).write_text("")
    monkeypatch.setitem(globals(), "ROOT", tmp_path)
    assert unmirrored("cli") == ["mppf/cli/probe.py"]


def test_test_module_names_are_unique_across_tests():
    # the test folders are not packages: two test modules of one name stop pytest's collection
    by_name: dict[str, list[str]] = {}
    for path in sorted((ROOT / "tests").rglob("test_*.py")):
        by_name.setdefault(path.name, []).append(str(path.relative_to(ROOT)))
    twice = {name: paths for name, paths in by_name.items() if len(paths) > 1}
    assert not twice, ("rename one of each pair to tests/<stage>/test_<stage>_<module>.py:\n"
                       + "\n".join(" and ".join(paths) for paths in twice.values()))
