"""The press driver on the register map, whatever carries the registers: sends one step safely, follows it.

:class:`PlcPress` implements :class:`mppf.core.presslink.PressLink` on a register transport
and a clock (:class:`mppf.drivers.session.PlcSession`): :class:`mppf.drivers.modbus.ModbusPress`
gives it Modbus TCP / RTU, the wall clock and a heartbeat thread;
:class:`mppf.sim.plc.link.InProcessPress` the simulated PLC's program itself and the
program's simulated time. No register number appears here (the register map of
``drivers/register_map.toml``). One press step (:meth:`PlcPress.run_step`) is:

1. the setpoints through the one job validator (nothing is written if one fails);
2. CLAIM (nothing is written while another master owns the PLC), RESET of a finished job;
3. upload of both setpoint blocks and read-back of every register;
4. VALIDATE with the job token (a new sequence, the CRC of the setpoints), acknowledged;
5. GO with the same token (one attempt), acknowledged, EXECUTING within the start timeout;
6. follow until COMPLETE with the token, the PLC's in-position and the driver's own check
   of every punch.

Steps 1-5 are :mod:`mppf.drivers.handshake`, step 6 :mod:`mppf.drivers.follow`; what is
sent after trouble is :mod:`mppf.drivers.safety`. STOP is sent on Ctrl-C, on a fault, on a
timeout, on a refusal after GO and when the link is lost (once, after reconnecting), and
the heartbeat goes on until the press is at rest. Latched faults are reset only by
:meth:`PlcPress.reset`. Every command and write is written ahead into the audit log.
"""

from __future__ import annotations

import math

import numpy as np

from mppf.core.errors import Cancelled, InputError, LinkError, MppfError, PlcError
from mppf.core.presslink import StepResult
from mppf.core.progress import NULL_REPORTER, Reporter
from mppf.drivers import regmap as rm
from mppf.drivers.follow import Follow, abandon
from mppf.drivers.handshake import Handshake
from mppf.drivers.safety import Safety
from mppf.drivers.session import PlcSession, WallClock
from mppf.model.press import PressConfig

__all__ = ["PlcPress", "WallClock"]


class PlcPress(Handshake, Follow, Safety, PlcSession):
    """A press PLC behind a register transport (a :class:`mppf.core.presslink.PressLink`).

    Connects on construction (:class:`~mppf.drivers.session.PlcSession`): reads the magic
    (word order), map version, matrix size, scan time, stroke limits and watchdog.

    Parameters
    ----------
    io
        The register transport.
    url : PlcUrl or str
        Where the PLC is (messages, audit log).
    press : PressConfig or None
        The press description (limits, speed, tolerance). None is enough for
        :meth:`status`, :meth:`stop` and :meth:`reset` but not for :meth:`run_step`.
    poll_s : float
        Status polling period during motion (s of the clock).
    motion_time_scale : float or None
        How many times faster than the press description the punches move (1 for a real
        press, the dry run's time scale for the simulated one); given, a COMPLETE sooner than
        half the fastest possible move is an error (STOP if anything moves). None: not checked.
    **options
        ``word_order``, ``unit``, ``audit``, ``job_sha256``, ``register_map``, ``clock``,
        ``reply_timeout_s``, ``master_id`` of :class:`~mppf.drivers.session.PlcSession`.

    Raises
    ------
    InputError
        Bad word order.
    LinkError
        The PLC cannot be reached, or is not an mppf press PLC with this register map.
    ConfigError
        The press description does not match the PLC's matrix size.
    """

    def __init__(self, io, url, press: PressConfig | None = None, *, poll_s: float = 0.05,
                 register_map: rm.RegisterMap | None = None, motion_time_scale: float | None = None, **options):
        self.poll_s = float(poll_s)
        self.motion_time_scale = motion_time_scale
        super().__init__(io, url, press, register_map=register_map, **options)

    def run_step(self, upper_mm: np.ndarray, lower_mm: np.ndarray, *, reporter: Reporter = NULL_REPORTER,
                 timeout_s: float | None = None) -> StepResult:
        """Validate, upload, verify, start and follow one press step (see the module docstring).

        Parameters
        ----------
        upper_mm, lower_mm : (rows, cols) float
            Tip-height setpoints, finite numbers (parking heights for inactive punches).
        reporter : Reporter
            Receives "upload" progress (registers written and read back), then "motion"
            progress (mm of travel done, summed over all punches).
        timeout_s : float, optional
            Motion timeout; default twice the time of the longest move plus 10 s.

        Returns
        -------
        StepResult

        Raises
        ------
        LimitError, InputError
            Nothing was written.
        LinkError
            The link failed; STOP was attempted once if GO had been sent.
        PlcError
            The PLC refused a request (before GO: nothing moved; after GO: STOP was sent).
        PressRefused
            Another master owns the PLC, the verification failed, or the PLC refused the job
            or GO; nothing moved.
        PressFault
            A fault, a STOP, a restart, a halted PLC, a timeout, or punches out of tolerance;
            STOP was sent.
        Cancelled
            Ctrl-C; STOP was sent.
        """
        _check_timeout(timeout_s)
        go_sent, seq = False, None
        try:
            # 1-4: the validator, ownership, upload, read-back, VALIDATE
            seq, crc, targets_mm = self._prepare(upper_mm, lower_mm, reporter)
            start_mm = self.read_actuals_mm()
            # 5: GO, once; the PLC executing our job
            go_sent = True
            t0 = self._clock.now()
            raw = self._go(seq, crc)
            # 6: follow the motion to COMPLETE, check the positions
            return self._follow(seq, crc, raw, targets_mm, start_mm, reporter, timeout_s, t0)
        except KeyboardInterrupt as exc:
            raise self._cancelled(exc, reporter, go_sent) from None
        except PlcError as exc:
            if not go_sent:
                raise  # refused before GO: nothing moved
            abandon(reporter, "stopped")
            raise self._refused_after_go(exc, seq) from None
        except LinkError as exc:
            abandon(reporter, "link lost")
            raise self._lost_link(exc, seq, go_sent) from None
        except Exception as exc:
            self._stop_on_unexpected(exc, go_sent)
            raise

    def _stop_on_unexpected(self, exc: Exception, go_sent: bool) -> None:
        """STOP after GO on an error that is not the driver's own (a bug, a failing progress display).

        The driver's own failures (PressFault, PressRefused, ...) have already done what is
        safe; anything else after GO must not leave the press moving until the watchdog notices.
        """
        if go_sent and not isinstance(exc, MppfError):
            self._stop_after_trouble(f"unexpected error: {type(exc).__name__}: {exc}")

    def _cancelled(self, exc: KeyboardInterrupt, reporter: Reporter, go_sent: bool) -> Cancelled:
        """STOP after Ctrl-C (or SIGTERM / SIGHUP) and the :class:`Cancelled` to raise.

        Parameters
        ----------
        exc : KeyboardInterrupt
            Its text names the signal (:mod:`mppf.cli.press_policy`); empty for Ctrl-C.
        reporter : Reporter
            The step's progress, abandoned as "cancelled".
        go_sent : bool
            Whether GO had been sent (then the message says whether the press came to rest).
        """
        signal_name = str(exc)
        why = "cancelled by the operator" + (f" ({signal_name})" if signal_name else "")
        abandon(reporter, "cancelled")
        self._stop_after_trouble(why, fresh=True)
        rest = ("; it did not report rest in time: check the press" if self._not_at_rest
                else "; it came to rest" if go_sent else "")
        return Cancelled(f"cancelled by the operator; STOP was sent to the press{rest}"
                         + (f" ({signal_name})" if signal_name else ""))

    def upload(self, upper_mm: np.ndarray, lower_mm: np.ndarray, *, reporter: Reporter = NULL_REPORTER) -> int:
        """Check, upload, verify and have the PLC validate one step, without starting it.

        Steps 1-4 of :meth:`run_step` (no GO): the setpoints are in the PLC, read back, and
        validated under a new job sequence (state VALIDATED).

        Returns
        -------
        int
            The job sequence the PLC validated.

        Raises
        ------
        LimitError, InputError, PressRefused, LinkError, PlcError
            As :meth:`run_step`.
        """
        try:
            return self._prepare(upper_mm, lower_mm, reporter)[0]
        except LinkError as exc:
            reporter.finish()
            raise self._lost_link(exc, None, False) from None


def _check_timeout(timeout_s: float | None) -> None:
    """Raise :class:`InputError` unless the motion timeout (s) is None or a positive number."""
    if timeout_s is not None and not (math.isfinite(timeout_s) and timeout_s > 0):
        raise InputError(f"the motion timeout must be a positive number of seconds, got {timeout_s}",
                         hint="give --timeout in s, or leave it out for the default")
