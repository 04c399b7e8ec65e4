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
- **SIGTERM** (kill, a service manager, a CI cancel) and **SIGHUP** (the terminal or the SSH
  session lost) are handled like Ctrl-C while the press may move: the driver sends STOP
  first, keeps its heartbeat and lease until the press is at rest, records why in the audit
  log, and the command exits 130 (SIGTERM) or 129 (SIGHUP).
- **A STOP of someone else.** A press found STOPPED by a STOP this mppf did not send is RESET
  only after the operator says so at the terminal (``--yes`` answers yes); without a terminal
  and without ``--yes`` nothing is written: exit 4 naming who stopped the press.

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
from mppf.core.errors import Cancelled, LinkError, PlcError, PressRefused
from mppf.core.progress import NULL_REPORTER, Reporter

DRY_RUN_WATCHDOG_S = 2.0
"""The watchdog of the dry run's simulated PLC: the simulator shares this process's CPU with the driver,
so it is given twice the recommended 1 s (the driver beats every tenth of it and starts no motion
when a beat came later than a quarter)."""

time_scale_option = click.option(
    "--time-scale", type=click.FloatRange(min=0.1), default=DRY_RUN_TIME_SCALE, show_default=True,
    help="Dry runs (no --plc): the simulated press moves this many times faster than the real one. With --plc "
         "only for a simulator there ('mppf sim --time-scale'): a real press is taken to move no faster than its "
         "description, and a COMPLETE sooner than that is refused (STOP).",
)


def _plc_time_scale() -> float:
    """The speed-up of the press at --plc: 1 (a real press), or a --time-scale given on the command line."""
    from click.core import ParameterSource

    ctx = click.get_current_context(silent=True)
    if ctx is None or ctx.get_parameter_source("time_scale") in (None, ParameterSource.DEFAULT):
        return 1.0
    return float(ctx.params["time_scale"])


def connect(plc_url: str, press=None, *, audit=None, **options):
    """A connected :class:`~mppf.drivers.modbus.ModbusPress` (the driver is imported only when needed).

    ``options`` go to ``ModbusPress`` (``heartbeat_s``, ``word_order``, ``job_sha256``, ``timeout_s``).
    """
    from mppf.drivers.modbus import ModbusPress

    return ModbusPress(plc_url, press, audit=audit, **options)


class HungUp(Cancelled):
    """SIGHUP while the press could move: STOP was sent; exit code 129 (128 + the signal's number)."""

    exit_code = 129


def reset_question(yes: bool):
    """The ``confirm_reset`` of the driver: ``--yes``, else the operator at the terminal, else no."""

    def confirm(question: str) -> bool:
        if yes:
            click.echo(f"NOTE: {question}: yes (--yes)", err=True)
            return True
        if not sys.stdin.isatty():
            return False
        return click.confirm(f"{question}?", default=False, err=True)

    return confirm


@contextlib.contextmanager
def press_link(press, plc_url: str | None, *, audit=None, time_scale: float = DRY_RUN_TIME_SCALE,
               reporter: Reporter = NULL_REPORTER, yes: bool = False, **options) -> Iterator:
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
    yes : bool
        ``--yes``: also answers the question before a STOP of someone else is RESET.
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
            plc_url, options = sim.url, {"timeout_s": DRY_RUN_REPLY_TIMEOUT_S, "motion_time_scale": time_scale,
                                         **options}
        options.setdefault("motion_time_scale", _plc_time_scale())  # a real press: no faster than its description
        link = stack.enter_context(connect(plc_url, press, audit=audit, **options))
        link.confirm_reset = reset_question(yes)
        yield link


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
            f"refusing to move the press without confirmation ({what}): stdin is not a terminal"
            + _stopped_by_someone(link),
            hint="run it at a terminal to confirm, or add --yes when the press is clear",
        )
    if not click.confirm(f"Move {what}? Check that the press is clear", default=False, err=True):
        raise PressRefused("the operator declined: nothing was sent to the press")


def _stopped_by_someone(link) -> str:
    """``; the press is STOPPED by ...`` when a STOP of someone else would also need confirming (else "")."""
    try:
        report = link.status_report()
    except (LinkError, PlcError):  # only the extra detail of a refusal is lost
        return ""
    stops = report["stops"]
    if report["state"] != "STOPPED" or stops["cause"] != "STOP_REQUEST":
        return ""
    return (f"; the press is also STOPPED by a STOP request of master 0x{stops['last_master']:08X} "
            f"({stops['count']} since the PLC started), whose reset would need confirming too")


def press_description(link) -> str:
    """Where the press is, for :func:`confirm_motion`: URL and matrix size."""
    return f"the press at {link.url} ({link.identity.rows} x {link.identity.cols} punches)"


@contextlib.contextmanager
def sigterm_as_ctrl_c() -> Iterator[None]:
    """While pressing, SIGTERM and SIGHUP are handled like Ctrl-C: the driver sends STOP first.

    SIGTERM exits 130 like Ctrl-C; SIGHUP exits 129 (:class:`HungUp`). The signal's name is the
    reason the driver records with its STOP in the audit log. After SIGHUP a terminal that is
    gone takes no more output: stdout and stderr are then sent to /dev/null.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []

    def terminate(signum, frame):
        received.append(signum)
        if signum == signal.SIGHUP:
            _drop_dead_terminal()
            raise KeyboardInterrupt("SIGHUP: the terminal or session was lost")
        raise KeyboardInterrupt("SIGTERM: terminated")

    previous = {sig: signal.signal(sig, terminate) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    except (Cancelled, KeyboardInterrupt) as exc:
        if signal.SIGHUP not in received:
            raise
        done = exc.message if isinstance(exc, Cancelled) else "cancelled before the press was reached"
        done = done.replace(" (SIGHUP: the terminal or session was lost)", "").replace("cancelled by the operator; ", "")
        raise HungUp(f"SIGHUP (the terminal or session was lost): {done}",
                     hint="check the press ('mppf status') from a new session") from None
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _drop_dead_terminal() -> None:
    """Send stdout and stderr to /dev/null when they are a terminal (a hung-up terminal answers writes with EIO)."""
    import os

    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is not None and stream.isatty():
                null = os.open(os.devnull, os.O_WRONLY)
                os.dup2(null, stream.fileno())
                os.close(null)
        except (OSError, ValueError):
            pass
