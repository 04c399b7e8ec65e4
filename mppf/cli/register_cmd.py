"""Commands of the mppf command line (this module's part)."""

from __future__ import annotations

COMMANDS: list = []
