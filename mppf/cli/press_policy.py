"""How the command line drives a press: one policy for ``mppf press`` and ``mppf loop``.

- **Which press.** ``--plc URL``: the PLC there, through :class:`mppf.drivers.modbus.ModbusPress`.
  No ``--plc``: a dry run, the simulated PLC started in this process and driven over
  loopback Modbus by the same driver (the real dry run: same protocol, handshake and
  checks), its motion :data:`mppf.core.defaults.DRY_RUN_TIME_SCALE` times faster than the
  real press (``--time-scale``), with the patient reply timeout
  :data:`mppf.core.defaults.DRY_RUN_REPLY_TIMEOUT_S` (the simulator shares this process's CPU).
- **Confirmation.** Every run with ``--plc`` asks the operator at the terminal before the
  press moves, whatever answers at that address (a simulator reached with ``--plc`` too:
  nothing the PLC says about itself skips the question); ``--yes`` skips it; without a
  terminal and without ``--yes`` nothing moves: :class:`~mppf.core.errors.PressRefused`,
  exit code 4. Only the in-process dry run (no ``--plc``) moves without asking.
- **SIGTERM** (kill, a service manager, a CI cancel) is handled like Ctrl-C while the press
  may move: the driver sends STOP first, the command exits 130.

The light commands (``mppf status``, ``stop``, ``reset``) connect with
:func:`mppf.cli.plc_ops.connect_session`, which imports neither numpy nor the planning code.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator

import click

from mppf.cli.plc_ops import connect_session  # noqa: F401 - the light session, here with the other connectors
from mppf.core.defaults import DRY_RUN_REPLY_TIMEOUT_S, DRY_RUN_TIME_SCALE
from mppf.core.errors import PressRefused
from mppf.core.progress import NULL_REPORTER, Reporter

DRY_RUN_WATCHDOG_S = 2.0
"""The watchdog of the dry run's simulated PLC: the simulator shares this process's CPU with the driver,
so it is given twice the recommended 1 s (the driver beats every tenth of it and starts no motion
when a beat came later than a quarter)."""

time_scale_option = click.option(
    "--time-scale", type=click.FloatRange(min=0.1), default=DRY_RUN_TIME_SCALE, show_default=True,
    help="Dry runs only (no --plc): the simulated press moves this many times faster than the real one.",
)


def connect(plc_url: str, press=None, *, audit=None, **options):
    """A connected :class:`~mppf.drivers.modbus.ModbusPress` (the driver is imported only when needed).

    ``options`` go to ``ModbusPress`` (``heartbeat_s``, ``word_order``, ``job_sha256``, ``timeout_s``).
    """
    from mppf.drivers.modbus import ModbusPress

    return ModbusPress(plc_url, press, audit=audit, **options)


@contextlib.contextmanager
def press_link(press, plc_url: str | None, *, audit=None, time_scale: float = DRY_RUN_TIME_SCALE,
               reporter: Reporter = NULL_REPORTER, **options) -> Iterator:
    """The press to drive: the PLC at ``plc_url``, or (None) a dry run on the simulated PLC.

    Parameters
    ----------
    press : PressConfig
    plc_url : str or None
    audit : AuditLog, optional
    time_scale : float
        Dry runs: motion speed-up of the simulated PLC.
    reporter : Reporter
        Told that this is a dry run.
    **options
        Keyword arguments of ``ModbusPress``.

    Yields
    ------
    ModbusPress
    """
    with contextlib.ExitStack() as stack:
        if plc_url is None:
            from mppf.sim.plc.host import run_simulated_plc

            sim = stack.enter_context(run_simulated_plc(press, time_scale=time_scale, watchdog_s=DRY_RUN_WATCHDOG_S))
            reporter.info(f"DRY RUN against the simulated PLC at {sim.url} in this process "
                          f"(motion {time_scale:g}x faster than the real press); no press moves")
            plc_url, options = sim.url, {"timeout_s": DRY_RUN_REPLY_TIMEOUT_S, **options}
        yield stack.enter_context(connect(plc_url, press, audit=audit, **options))


def confirm_motion(link, what: str, yes: bool) -> None:
    """Ask before moving the press at ``--plc`` (see the module docstring).

    Parameters
    ----------
    link : ModbusPress
        The connected press.
    what : str
        What is about to move, for the question (job or plate, steps, where).
    yes : bool
        ``--yes``: do not ask.

    Raises
    ------
    PressRefused
        No terminal to ask at, or the operator declined: nothing was sent.
    """
    if yes:
        return
    if not sys.stdin.isatty():
        raise PressRefused(
            f"refusing to move the press without confirmation ({what}): stdin is not a terminal",
            hint="run it at a terminal to confirm, or add --yes when the press is clear",
        )
    if not click.confirm(f"Move {what}? Check that the press is clear", default=False, err=True):
        raise PressRefused("the operator declined: nothing was sent to the press")


def press_description(link) -> str:
    """Where the press is, for :func:`confirm_motion`: URL and matrix size."""
    return f"the press at {link.url} ({link.identity.rows} x {link.identity.cols} punches)"


@contextlib.contextmanager
def sigterm_as_ctrl_c() -> Iterator[None]:
    """While pressing, SIGTERM is handled like Ctrl-C: the driver sends STOP first (exit 130)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminate(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
