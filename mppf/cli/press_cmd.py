"""``mppf press``, ``mppf status``, ``mppf stop``, ``mppf reset``: drive the press PLC.

Thin wrappers over :class:`mppf.drivers.modbus.ModbusPress` (``press``) and the light
:class:`mppf.drivers.modbus_session.ModbusSession` (``status``, ``stop``, ``reset``: they
import neither numpy nor rich nor the planning code, so that STOP leaves at once). Which
press, the confirmation and SIGTERM follow :mod:`mppf.cli.press_policy` (as ``mppf loop``).
See ``docs/driver.md``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import click

from mppf.cli.plc_ops import connect_session, open_audit, stop_plc
from mppf.cli.press_policy import confirm_motion, press_description, press_link, sigterm_as_ctrl_c, time_scale_option
from mppf.core.errors import ConfigError, InputError, LimitError

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


def parse_plc_url(plc_url: str):
    """The parsed URL (InputError for a malformed one), without importing the driver's Modbus code."""
    from mppf.drivers.url import parse_plc_url as parse

    return parse(plc_url)


def _load_sealed_job(job_path, plc_url, audit_path):
    """The job file through the one strict loader; a job refused by its seal is recorded in the audit log.

    Raises
    ------
    InputError
        As :func:`mppf.planning.job.load_job` (a :class:`~mppf.core.seal.SealError`
        for a seal that does not match).
    """
    from mppf.core.seal import SealError
    from mppf.planning.job import load_job

    try:
        return load_job(job_path)
    except SealError as exc:  # an edited job: who tried to press it, and what changed, are kept
        with open_audit(audit_path) as audit:
            audit.record(plc_url or "dry run", "seal", "refused", detail=exc.message[:500])
        raise


def _check_before_connecting(job, job_path, press, press_source: str, plc_url, audit_path) -> None:
    """The job against the machine's press, before any PLC is connected (or simulated).

    Never the job's own press block: a job planned for another press (identity or limits), or
    one whose placements do not follow from its plan, is refused here and the refusal recorded in
    the audit log; the whole validation runs again against the PLC once connected.

    Raises
    ------
    ConfigError, LimitError
        Naming the job file.
    """
    from mppf.planning.validate import validate_job

    try:
        validate_job(job, press_file=press, press_source=press_source)
    except (ConfigError, LimitError) as exc:
        with open_audit(audit_path) as audit:
            audit.record(plc_url or "dry run", "limits", "refused", job_sha256=job.sha256(),
                         detail=f"job {job_path}: {exc.message}"[:500])
        raise type(exc)(f"job {job_path}: {exc.message}", hint=exc.hint) from None


def _select_steps(job, step: int | None) -> list[int]:
    n = len(job.steps)
    if step is None:
        return list(range(1, n + 1))
    if not 1 <= step <= n:
        raise InputError(f"--step {step} does not exist: the job has steps 1..{n}",
                         hint=f"give --step from 1 to {n}, or leave it out to press every step")
    return [step]


def _result_table(step: int, result, tolerance_mm: float):
    import numpy as np
    from rich.table import Table

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
@click.option("--section", type=int, default=None,
              help="A plate in sections: press only section N (1-based). Default: every section in order.")
@click.option("--yes", is_flag=True, help="Do not ask for confirmation before moving the press at --plc.")
@click.option("--press", "press_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="This machine's press description (default: the installed $MPPF_HOME/press.toml; dry runs "
                   "without one: the bundled example press). The job must have been planned for it, every key "
                   "equal; the job's own press block is never used.")
@audit_option
@click.option("--timeout", "timeout_s", type=click.FloatRange(min=0.1), default=None,
              help="Motion timeout per step in s (default: from the longest move, speed and acceleration).")
@click.option("--word-order", type=click.Choice(["auto", "ABCD", "CDAB"]), default="auto", show_default=True,
              help="Expected word order of 32-bit registers.")
@time_scale_option
def press_command(job_path, plc_url, step, section, yes, press_path, audit_path, timeout_s, word_order, time_scale):
    """Send a planned job to the press and follow it, step by step.

    Without --plc this is a DRY RUN against the simulated PLC in this process (nothing
    moves, nothing is asked). With --plc the operator confirms first (or gives --yes).
    The job passes the job validator (numbers, limits, tip gaps, dimpling, parking,
    monotonic steps, the PLC's matrix and limits, the press file) before anything is
    written; every step is then uploaded, read back, validated by the PLC with its job
    token and started; the actual positions are checked against the targets.

    Exit codes: 0 done, 2 bad input (job, URL, strokes beyond limits, tampered job), 3 link
    failure, 4 press fault or refusal (also: no confirmation), 129 the terminal or session
    was lost (SIGHUP; STOP was sent), 130 cancelled by Ctrl-C or SIGTERM (STOP was sent).
    """
    from mppf.cli._common import RichReporter, check_db_path, console
    from mppf.cli._placement import placement_lines
    from mppf.planning.press import machine_press

    if timeout_s is not None and not math.isfinite(timeout_s):
        raise InputError(f"--timeout must be a finite number of seconds, got {timeout_s}",
                         hint="leave it out for the default (from the longest move)")
    job = _load_sealed_job(job_path, plc_url, audit_path)  # numbers where numbers belong, the seal, first
    if section is not None and job.sections is None:
        raise InputError(f"--section {section}: the job {job_path.name} is a single piece (no sections)",
                         hint="leave --section out for a single-piece job")
    steps = _select_steps(job, step) if job.sections is None else []
    if plc_url:
        parse_plc_url(plc_url)
    press, press_source = machine_press(press_path, dry_run=plc_url is None)
    if audit_path is not None:
        check_db_path(audit_path, "the audit log", "--audit")
    _check_before_connecting(job, job_path, press, press_source, plc_url, audit_path)
    job.press = press  # equal to the job's block (checked): park heights and tolerances are the machine's
    dry_run = plc_url is None
    with sigterm_as_ctrl_c(), press_link(press, plc_url, audit=open_audit(audit_path), time_scale=time_scale,
                                         reporter=RichReporter(), word_order=word_order, yes=yes,
                                         job_sha256=job.sha256()) as plc:
        # the one job validator, against this PLC's identity and limits and the machine's press, before any write
        try:
            plc.check_job(job, press, press_source)
        except (ConfigError, LimitError) as exc:  # name the job file (the refusal is in the audit log)
            raise type(exc)(f"job {job_path}: {exc.message}", hint=exc.hint) from None
        if job.sections is not None:  # a plate larger than the bed: section by section (docs/sections.md)
            from mppf.cli._sections import SectionRun, press_sections

            run = SectionRun(job_name=job_path.name, dry_run=dry_run, yes=yes, timeout_s=timeout_s,
                             section=section, step=step)
            n = press_sections(plc, job, run, show_result=lambda what, r: console.print(
                                   _result_table(what, r, job.press.position_tolerance_mm)),
                               echo=console.print, make_reporter=lambda: RichReporter(enabled=True),
                               placement_lines=placement_lines)
            console.print(f"{'dry run: ' if dry_run else ''}{n} step(s) pressed, all punches in position "
                          f"within {job.press.position_tolerance_mm} mm")
            return
        _press_steps(plc, job, job_path, steps, dry_run, yes, timeout_s)


def _press_steps(plc, job, job_path: Path, steps: list[int], dry_run: bool, yes: bool, timeout_s) -> None:
    """Press the chosen steps of a single-piece job: setpoints checked, the placement printed, confirmed, pressed.

    Parameters
    ----------
    plc : the connected press link (:func:`mppf.cli.press_policy.press_link`)
    job : Job
        Checked against the PLC; ``job.press`` the machine's press.
    job_path : Path
        The job file (named in the confirmation).
    steps : list of int
        The 1-based steps to press, in order.
    dry_run : bool
        The simulated PLC in this process: nothing is asked.
    yes : bool
        Do not ask before driving a real press.
    timeout_s : float or None
        Longest wait for one step, s; None: from the longest move.
    """
    from mppf.cli._common import RichReporter, console
    from mppf.cli._placement import placement_lines

    press = job.press
    setpoints = {k: job.steps[k - 1].setpoints_mm(press) for k in steps}
    for k in steps:
        plc.check_setpoints(*setpoints[k], active=job.steps[k - 1].active)
    # where to lay the plate; at --plc the operator confirms it lies there and the press is clear
    for line in placement_lines(job):
        console.print(line, markup=False, highlight=False)
    if not dry_run:
        confirm_motion(plc, f"job {job_path.name}, step(s) {', '.join(map(str, steps))}, on "
                            f"{press_description(plc)}, with the plate laid as printed above", yes)
    # press, step by step
    for k in steps:
        reporter = RichReporter(enabled=True)
        reporter.info(f"step {k} of {len(job.steps)}")
        try:
            result = plc.run_step(*setpoints[k], reporter=reporter, timeout_s=timeout_s)
        finally:
            reporter.close()
        console.print(_result_table(k, result, job.press.position_tolerance_mm))
    console.print(f"{'dry run: ' if dry_run else ''}{len(steps)} step(s) pressed, all punches in position "
                  f"within {job.press.position_tolerance_mm} mm")


def _status_rows(report: dict) -> list[tuple[str, str]]:
    flags = report["status"]
    last, stops = report["last_command"], report["stops"]
    rows = [
        ("matrix", f"{report['rows']} x {report['cols']} punches, map version {report['map_version']}, "
                   f"word order {report['word_order']}"),
        ("timing", f"scan time {report['scan_time_ms']} ms, watchdog {report['watchdog_ms']} ms"),
        ("state", report["state"]),
        ("status", ", ".join(name for name, on in flags.items() if on) or "(no bit set)"),
        ("fault", f"{report['fault_code']}: {report['fault_text']}"),
        ("owner", f"master 0x{report['owner_master']:08X}" if report["owner_master"] else "none"),
        ("last command", f"{last['command']} (counter {last['counter']}) of master 0x{last['master']:08X}: "
                         f"{last['result_text']}"),
        ("jobs", f"validated {report['validated']['sequence']}, motion {report['motion']['sequence']}, "
                 f"last sequence {report['last_sequence']}"),
        ("stops", f"{stops['count']} (last: {stops['cause']}, master 0x{stops['last_master']:08X})"),
        ("refused writes", str(report["refused_writes"])),
        ("heartbeats", f"PLC {report['plc_heartbeat']}, master 0x{report['heartbeat']['master']:08X} "
                       f"counter {report['heartbeat']['counter']}"),
    ]
    rows += [(f"{side} limits", f"{lo:.2f}..{hi:.2f} mm") for side, (lo, hi) in report["limits_mm"].items()]
    return rows


@click.command("status")
@plc_option
@click.option("--json", "as_json", is_flag=True, help="Print the status as JSON.")
def status_command(plc_url, as_json):
    """Read the PLC's identity and status (reads only; nothing is written)."""
    with connect_session(_need_plc(plc_url), heartbeat_s=None) as plc:
        report = plc.status_report()
    if as_json:
        click.echo(json.dumps(report, indent=2))
        return
    width = max(len(name) for name, _ in _status_rows(report))
    click.echo(f"PLC at {report['plc']}")
    for name, value in _status_rows(report):
        click.echo(f"  {name:<{width}}  {value}")


@click.command("stop")
@plc_option
@audit_option
def stop_command(plc_url, audit_path):
    """Command STOP: every punch brakes to a standstill (obeyed from anyone, in every state)."""
    stop_plc(_need_plc(plc_url), audit_path)


@click.command("reset")
@plc_option
@audit_option
def reset_command(plc_url, audit_path):
    """Reset latched faults (refused while the cause, e.g. the e-stop, is present, or another master owns the PLC)."""
    with connect_session(_need_plc(plc_url), audit=open_audit(audit_path)) as plc:
        plc.reset()
        st = plc.status()
    click.echo(f"faults reset on {plc.url}: {st.fault_text}; state {st.state}; ready: {st.ready}")


COMMANDS: list = [press_command, status_command, stop_command, reset_command]
