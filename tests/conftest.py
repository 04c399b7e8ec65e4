"""Shared, generic pytest fixtures."""

from __future__ import annotations

from pathlib import Path

import pytest

import mppf


@pytest.fixture(scope="session")
def hull_dir() -> Path:
    """Folder of the bundled real hull plates (61 x 41 grids, mm, hull coordinates)."""
    return Path(mppf.__file__).parent / "examples" / "hull"
