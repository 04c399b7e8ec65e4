"""The simulated press PLC: its program, its Modbus server, a thread host, an in-process press.

=====================================  ==========================================================
module                                 what
=====================================  ==========================================================
:mod:`mppf.sim.plc.program`            the PLC program: register image, commands, checks,
                                       watchdog, hydraulic motion; advanced by explicit time
                                       steps (no pymodbus, no threads)
:mod:`mppf.sim.plc.commands`          the program's side of a master write: protection,
                                       validation, GO / STOP / RESET
:mod:`mppf.sim.plc.program_faults`     the program's injectable faults (stuck, e-stop,
                                       overpressure, freeze)
:mod:`mppf.sim.plc.server`             pymodbus hosting (TCP, RTU) and the link's faults
:mod:`mppf.sim.plc.host`               the background thread: ``start_simulated_plc``,
                                       ``run_simulated_plc``, ``SimHandle``
:mod:`mppf.sim.plc.link`               ``InProcessPress``: a ``PressLink`` on the program itself,
                                       instant and seeded (no Modbus, no threads)
=====================================  ==========================================================

``start_simulated_plc``, ``run_simulated_plc``, ``SimHandle`` and ``InProcessPress`` can be
imported from here; they are loaded on first use, so importing the program alone does not
import pymodbus.
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "start_simulated_plc": "host",
    "run_simulated_plc": "host",
    "SimHandle": "host",
    "PlcProgram": "program",
    "InProcessPress": "link",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)
