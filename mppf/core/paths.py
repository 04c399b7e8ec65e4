"""Where mppf keeps its own files (audit log, plate history, plate work folders, the seal key, the press)."""

from __future__ import annotations

import os
from pathlib import Path


def data_dir() -> Path:
    """``$MPPF_HOME`` if set, else ``~/.local/share/mppf`` (not created here)."""
    home = os.environ.get("MPPF_HOME")
    return Path(home) if home else Path.home() / ".local" / "share" / "mppf"


def seal_key_path() -> Path:
    """The installation's job seal key: ``$MPPF_SEAL_KEY`` if set, else ``data_dir()/seal.key``.

    Made on first use with mode 0600 (:func:`mppf.core.seal.load_key`); never part of a job.
    ``MPPF_SEAL_KEY`` lets an installation keep the key apart from the data folder (and the
    tests share one key between processes that use different data folders).
    """
    key = os.environ.get("MPPF_SEAL_KEY")
    return Path(key) if key else data_dir() / "seal.key"


def installed_press_path() -> Path:
    """The installation's own press description: ``data_dir()/press.toml`` (copied there once).

    ``mppf press`` validates every job against it (or against ``--press``), never against the
    press block a job carries; see ``docs/operator-workflow.md``.
    """
    return data_dir() / "press.toml"
