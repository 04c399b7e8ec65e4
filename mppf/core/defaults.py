"""Defaults that more than one stage or command uses, written once.

Lengths in mm, times in s. A value here is a default, never a limit: the commands
validate what the user gives with :mod:`mppf.core.validate`.
"""

from __future__ import annotations

TOLERANCE_MM = 2.5
"""Largest absolute form deviation a formed plate may have (the shop's acceptance tolerance)."""

RMS_TOLERANCE_MM = 1.0
"""Largest RMS deviation a formed plate may have."""

DRY_RUN_TIME_SCALE = 50.0
"""How much faster than real time the simulated press moves in a dry run (``mppf press``, ``mppf loop``)."""

DRY_RUN_REPLY_TIMEOUT_S = 5.0
"""Modbus reply timeout of a dry run: the in-process simulator shares the CPU, so be patient."""

MAD_SCALE = 1.4826
"""Median absolute deviation to standard deviation of a normal distribution: robust scale = MAD_SCALE x MAD."""
