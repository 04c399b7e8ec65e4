"""``mppf press``, ``mppf status``, ``mppf stop``, ``mppf reset``: drive the press PLC.

Thin wrappers over :class:`mppf.drivers.modbus.ModbusPress`; which press, the
confirmation and SIGTERM follow :mod:`mppf.cli.press_policy` (as ``mppf loop``). See
``docs/driver.md``.
"""

from __future__ import annotations

import math
from pathlib import Path

import click
import numpy as np
from rich.table import Table

from mppf.cli._common import RichReporter, console, print_json
from mppf.cli.press_policy import (confirm_motion, connect, press_description, press_link, sigterm_as_ctrl_c,
                                   time_scale_option)
from mppf.core.errors import InputError

plc_option = click.option(
    "--plc",
    "plc_url",
    metavar="URL",
    help="PLC address: tcp://HOST:PORT?unit=1 or rtu:///dev/ttyUSB0?baud=115200&parity=E&unit=1.",
)
audit_option = click.option(
    "--audit",
    "audit_path",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Audit log (SQLite). Default: $MPPF_HOME/audit.sqlite or ~/.local/share/mppf/audit.sqlite.",
)


def _need_plc(plc_url: str | None) -> str:
    if not plc_url:
        raise InputError("no PLC given", hint="add --plc tcp://HOST:PORT?unit=1 (or rtu:///dev/ttyUSB0?...)")
    return plc_url


def _audit(audit_path):
    """The audit log at ``audit_path`` (None: the default one)."""
    from mppf.drivers.audit import AuditLog

    return AuditLog(audit_path)


def _select_steps(job, step: int | None) -> list[int]:
    n = len(job.steps)
    if step is None:
        return list(range(1, n + 1))
    if not 1 <= step <= n:
        raise InputError(f"--step {step} does not exist: the job has steps 1..{n}")
    return [step]


def _result_table(step: int, result, tolerance_mm: float) -> Table:
    table = Table(title=f"step {step}: job sequence {result.sequence}, motion {result.duration_s:.2f} s")
    table.add_column("matrix")
    for col in ("punches", "targets (mm)", "largest error (mm)", f"beyond {tolerance_mm:g} mm"):
        table.add_column(col, justify="right")
    for side, target, actual in (("upper", result.target_upper_mm, result.actual_upper_mm),
                                 ("lower", result.target_lower_mm, result.actual_lower_mm)):
        err = np.abs(actual - target)
        table.add_row(side, str(target.size), f"{target.min():.2f} .. {target.max():.2f}", f"{err.max():.3f}",
                      str(int((err > tolerance_mm).sum())))
    return table


@click.command("press")
@click.argument("job_path", metavar="JOB.json", type=click.Path(dir_okay=False, path_type=Path))
@plc_option
@click.option("--step", type=int, default=None, help="Press only step K (1-based). Default: every step in order.")
@click.option("--yes", is_flag=True, help="Do not ask for confirmation before moving a real press.")
@audit_option
@click.option("--timeout", "timeout_s", type=click.FloatRange(min=0.1), default=None,
              help="Motion timeout per step in s (default: from the longest move, speed and acceleration).")
@click.option("--word-order", type=click.Choice(["auto", "ABCD", "CDAB"]), default="auto", show_default=True,
              help="Expected word order of 32-bit registers.")
@time_scale_option
def press_command(job_path, plc_url, step, yes, audit_path, timeout_s, word_order, time_scale):
    """Send a planned job to the press and follow it, step by step.

    Without --plc this is a DRY RUN against an in-process simulated PLC (nothing moves).
    With --plc every step is uploaded, read back and verified, validated by the PLC
    (CRC and sequence) and only then started; the actual positions are checked against
    the targets. A real press asks for confirmation first (or takes --yes).

    Exit codes: 0 done, 2 bad input (job, URL, strokes beyond limits), 3 link failure,
    4 press fault or refusal (also: no confirmation), 130 cancelled by Ctrl-C or SIGTERM
    (STOP was sent).
    """
    from mppf.planning.job import load_job

    if timeout_s is not None and not math.isfinite(timeout_s):
        raise InputError(f"--timeout must be a finite number of seconds, got {timeout_s}",
                         hint="leave it out for the default (from the longest move)")
    job = load_job(job_path)
    steps = _select_steps(job, step)
    dry_run = plc_url is None
    with sigterm_as_ctrl_c(), press_link(job.press, plc_url, audit=_audit(audit_path), time_scale=time_scale,
                                         reporter=RichReporter(), heartbeat_s=0.25, word_order=word_order,
                                         job_sha256=job.sha256()) as plc:
        # every step checked against the limits before the first moves
        setpoints = {k: job.steps[k - 1].setpoints_mm(job.press) for k in steps}
        for k in steps:
            plc.check_setpoints(*setpoints[k])
        # a real press: the operator confirms
        if not dry_run:
            confirm_motion(plc, f"job {job_path.name}, step(s) {', '.join(map(str, steps))}, on "
                                f"{press_description(plc)}", yes)
        # press, step by step
        for k in steps:
            reporter = RichReporter(enabled=True)
            reporter.info(f"step {k} of {len(job.steps)}")
            result = plc.run_step(*setpoints[k], reporter=reporter, timeout_s=timeout_s)
            console.print(_result_table(k, result, job.press.position_tolerance_mm))
        console.print(f"{'dry run: ' if dry_run else ''}{len(steps)} step(s) pressed, all punches in position "
                      f"within {job.press.position_tolerance_mm} mm")


@click.command("status")
@plc_option
@click.option("--json", "as_json", is_flag=True, help="Print the status as JSON.")
def status_command(plc_url, as_json):
    """Read the PLC's identity and status (reads only; nothing is written)."""
    with connect(_need_plc(plc_url), heartbeat_s=None) as plc:
        report = plc.status_report()
    if as_json:
        print_json(report)
        return
    table = Table(title=f"PLC at {report['plc']}", show_header=False)
    table.add_column("item")
    table.add_column("value")
    flags = report["status"]
    table.add_row("matrix", f"{report['rows']} x {report['cols']} punches, map version {report['map_version']}, "
                            f"word order {report['word_order']}")
    table.add_row("status", ", ".join(name for name, on in flags.items() if on) or "(no bit set)")
    table.add_row("fault", f"{report['fault_code']}: {report['fault_text']}")
    table.add_row("last refusal", f"{report['refusal_code']}: {report['refusal_text']}")
    table.add_row("sequence", f"acknowledged {report['acknowledged_sequence']}, motion {report['motion_sequence']}")
    table.add_row("heartbeats", f"PLC {report['plc_heartbeat']}, master {report['master_heartbeat']}")
    for side, (lo, hi) in report["limits_mm"].items():
        table.add_row(f"{side} limits", f"{lo:.2f}..{hi:.2f} mm")
    console.print(table)


@click.command("stop")
@plc_option
@audit_option
def stop_command(plc_url, audit_path):
    """Command STOP: every punch decelerates to a standstill (always accepted)."""
    with connect(_need_plc(plc_url), audit=_audit(audit_path), heartbeat_s=None) as plc:
        plc.stop("mppf stop")
    console.print(f"STOP sent to {plc.url}")


@click.command("reset")
@plc_option
@audit_option
def reset_command(plc_url, audit_path):
    """Reset latched faults (refused while the cause, e.g. the e-stop, is present)."""
    with connect(_need_plc(plc_url), audit=_audit(audit_path), heartbeat_s=None) as plc:
        plc.reset()
        st = plc.status()
    console.print(f"faults reset on {plc.url}: {st.fault_text}; ready: {st.ready}")


COMMANDS: list = [press_command, status_command, stop_command, reset_command]
