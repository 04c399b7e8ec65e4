"""Where mppf keeps its own files (audit log, plate history, plate work folders)."""

from __future__ import annotations

import os
from pathlib import Path


def data_dir() -> Path:
    """``$MPPF_HOME`` if set, else ``~/.local/share/mppf`` (not created here)."""
    home = os.environ.get("MPPF_HOME")
    return Path(home) if home else Path.home() / ".local" / "share" / "mppf"
