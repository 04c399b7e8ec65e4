"""The one interface of "a press": what workflows need from the press, whatever drives it.

The press driver (:class:`mppf.drivers.plc_press.PlcPress`) implements it on the register
map: :class:`mppf.drivers.modbus.ModbusPress` against a real or simulated PLC over Modbus,
:class:`mppf.sim.plc.link.InProcessPress` on the simulated PLC's program in this thread
(instant, for tests and library dry runs). Workflows (``mppf press``, ``mppf loop``, the
demo) take a :class:`PressLink` as an argument and never import a driver themselves.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from mppf.core.progress import NULL_REPORTER, Reporter


@dataclass(frozen=True)
class PressStatus:
    """A snapshot of the PLC's status.

    Attributes
    ----------
    ready, busy, in_position, fault, estop, remote, data_valid : bool
        Status-word bits.
    fault_code : int
        PLC fault code (0 = none; meanings in docs/register-map.md).
    acknowledged_sequence : int
        Job sequence number the PLC last accepted.
    plc_heartbeat : int
        PLC heartbeat counter.
    fault_text : str
        Human-readable fault code.
    simulated : bool
        The PLC is mppf's simulated PLC (status bit ``simulated``; a real PLC leaves it 0).
    """

    ready: bool
    busy: bool
    in_position: bool
    fault: bool
    estop: bool
    remote: bool
    data_valid: bool
    fault_code: int = 0
    acknowledged_sequence: int = 0
    plc_heartbeat: int = 0
    fault_text: str = ""
    simulated: bool = False


@dataclass(frozen=True)
class StepResult:
    """Outcome of one press step.

    Attributes
    ----------
    sequence : int
        Job sequence number used for the upload.
    target_upper_mm, target_lower_mm : (rows, cols) float
        Setpoints sent (parking heights included).
    actual_upper_mm, actual_lower_mm : (rows, cols) float
        Positions read back from the PLC after motion.
    max_error_mm : float
        Largest |actual - target| over both matrices.
    duration_s : float
        Wall time from GO to in-position.
    """

    sequence: int
    target_upper_mm: np.ndarray
    target_lower_mm: np.ndarray
    actual_upper_mm: np.ndarray
    actual_lower_mm: np.ndarray
    max_error_mm: float
    duration_s: float


class PressLink(Protocol):
    """A connected press (context manager: closing it stops heartbeats, not the press)."""

    def status(self) -> PressStatus:
        """Read the PLC status."""

    def run_step(
        self,
        upper_mm: np.ndarray,
        lower_mm: np.ndarray,
        *,
        reporter: Reporter = NULL_REPORTER,
        timeout_s: float | None = None,
    ) -> StepResult:
        """Validate, upload, verify, start and follow one press step to the end.

        Parameters
        ----------
        upper_mm, lower_mm : (rows, cols) float
            Tip-height setpoints for every punch (no NaN: parking heights filled in,
            see :meth:`mppf.planning.job.StepStrokes.setpoints_mm`).

        Raises
        ------
        LimitError
            A setpoint beyond the press limits (nothing is written).
        LinkError
            The link failed (the press is sent STOP where the link allows).
        PlcError
            The PLC refused a request (after GO the press is sent STOP).
        PressFault
            The PLC faulted, refused GO, or positions are out of tolerance.
        Cancelled
            The operator pressed Ctrl-C (the press is sent STOP).
        """

    def stop(self) -> None:
        """Command STOP (never retried, always allowed)."""

    def reset(self) -> None:
        """Reset latched faults (on request only)."""

    def close(self) -> None:
        """Disconnect."""

    def __enter__(self) -> PressLink: ...

    def __exit__(self, *exc) -> None: ...
