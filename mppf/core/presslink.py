"""The one interface of "a press": what workflows need from the press, whatever drives it.

The press driver (:class:`mppf.drivers.plc_press.PlcPress`) implements it on the register
map: :class:`mppf.drivers.modbus.ModbusPress` against a real or simulated PLC over Modbus,
:class:`mppf.sim.plc.link.InProcessPress` on the simulated PLC's program in this thread
(instant, for tests and library dry runs). Workflows (``mppf press``, ``mppf loop``, the
demo) take a :class:`PressLink` as an argument and never import a driver themselves.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

from mppf.core.progress import NULL_REPORTER, Reporter

if TYPE_CHECKING:  # numpy only for the annotations: ``mppf stop`` imports this module without it
    import numpy as np


@dataclass(frozen=True)
class PressStatus:
    """A snapshot of the PLC's status (docs/register-map.md).

    Attributes
    ----------
    state : str
        The PLC's state: ``IDLE``, ``LOADED``, ``VALIDATED``, ``EXECUTING``, ``COMPLETE``,
        ``STOPPING``, ``STOPPED`` or ``FAULT``.
    ready, busy, in_position, fault, estop, remote_enabled, owned, lease_ok, setpoints_locked : bool
        Status-word bits.
    fault_code : int
        PLC fault code (0 = none).
    fault_text : str
        Human-readable fault code.
    owner_master : int
        Id of the master holding the PLC's lease (0: none).
    validated_sequence, motion_sequence : int
        Sequence of the validated job and of the last job started.
    plc_heartbeat : int
        PLC heartbeat counter.
    """

    state: str
    ready: bool
    busy: bool
    in_position: bool
    fault: bool
    estop: bool
    remote_enabled: bool
    owned: bool
    lease_ok: bool
    setpoints_locked: bool
    fault_code: int = 0
    fault_text: str = ""
    owner_master: int = 0
    validated_sequence: int = 0
    motion_sequence: int = 0
    plc_heartbeat: int = 0


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
        Time from GO to the PLC's COMPLETE (s of the press's clock: wall time, or simulated
        time for the in-process press).
    """

    sequence: int
    target_upper_mm: np.ndarray
    target_lower_mm: np.ndarray
    actual_upper_mm: np.ndarray
    actual_lower_mm: np.ndarray
    max_error_mm: float
    duration_s: float


@runtime_checkable
class PressLink(Protocol):
    """A connected press (context manager: closing it stops heartbeats, not the press).

    Attributes
    ----------
    job_sha256 : str or None
        The seal (sha256) of the job being pressed, written with every audit log entry; the
        loop sets it before it presses a cycle's job. None: no job named.
    """

    job_sha256: str | None

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
            see :meth:`mppf.model.job_parts.StepStrokes.setpoints_mm`).

        Raises
        ------
        LimitError, InputError
            A setpoint beyond the press limits, or not a finite number (nothing is written).
        LinkError
            The link failed (the press is sent STOP where the link allows).
        PlcError
            The PLC refused a request (after GO the press is sent STOP).
        PressRefused
            The PLC (or the driver's own checks) refused before any motion.
        PressFault
            The PLC faulted or was stopped during the motion, or positions are out of
            tolerance.
        Cancelled
            The operator pressed Ctrl-C (the press is sent STOP).
        """

    def stop(self) -> None:
        """Command STOP (its own register: obeyed from anyone, in every state)."""

    def reset(self) -> None:
        """Reset latched faults (on request only)."""

    def close(self) -> None:
        """Disconnect."""

    def __enter__(self) -> PressLink: ...

    def __exit__(self, *exc) -> None: ...
