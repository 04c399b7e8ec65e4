"""``mppf loop``: the bend - measure - compare loop of one plate (thin over :mod:`mppf.loop`).

The loop itself is :mod:`mppf.loop.cycle`, the history :mod:`mppf.loop.history`. The press
follows :mod:`mppf.cli.press_policy` like ``mppf press``: without ``--plc`` a dry run on the
simulated PLC in this process over loopback Modbus, with ``--plc`` the operator confirms
first (or ``--yes``), SIGTERM stops the press like Ctrl-C. The simulated plate and scanner
of dry runs come from :mod:`mppf.sim.shop`.

Every option and file is checked, the plate planned and its job validated against the PLC
(and the operator asked) before anything is recorded; the plate and its first cycle are then
recorded in one transaction. The plate's lease (:mod:`mppf.loop.lease`) is held from before
the planning to the end: one loop per plate.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import click

from mppf.cli._common import (
    RichReporter,
    check_db_path,
    console,
    esc,
    print_json,
    units_option,
)
from mppf.cli._cycles import cycle_table, print_cycle
from mppf.cli._loop_run import SCAN_SIM, Draft, RunOptions, draft_plate, run_plate
from mppf.cli._plate_report import write_report
from mppf.cli.history_cmd import history_option, open_history
from mppf.cli.press_policy import sigterm_as_ctrl_c, time_scale_option
from mppf.core.errors import InputError
from mppf.core.validate import check_number, check_positive
from mppf.forming.material import check_yield_uncertainty
from mppf.loop.settings import MAX_RESCANS, LoopSettings
from mppf.model.material import MATERIALS

_DEFAULTS = LoopSettings()  # the loop's defaults (tolerances from mppf.core.defaults), written once
THICKNESS_MAX_MM = 200.0
"""Thickest plate the loop takes (mm): beyond it a value is a typing error (or metres / micrometres)."""


def _check_options(thickness, scan_timeout, seed, audit_path) -> None:
    """Refuse bad option values and an unwritable audit log before anything is read, planned or recorded."""
    if thickness is not None:
        check_number("--thickness", thickness, low=0.0, low_open=True, high=THICKNESS_MAX_MM, unit="mm",
                     hint=f"give the plate thickness in mm, above 0 and at most {THICKNESS_MAX_MM:g}")
    check_positive("--scan-timeout", scan_timeout, unit="s", hint="give the longest wait for a scan file in s")
    check_number("--seed", seed, low=0, integer=True, hint="give a whole number, 0 or more")
    if audit_path is not None:
        check_db_path(audit_path, "the audit log", "--audit")


def _positive(option: str, value: float) -> float:
    return check_positive(option, value, unit="s", hint="give the wait in s, above 0")


def _check_link_and_scanner(plc_url: str | None, scanner_spec: str) -> None:
    """Refuse a malformed PLC URL or a missing scan folder (InputError)."""
    if plc_url:
        from mppf.drivers.url import parse_plc_url

        parse_plc_url(plc_url)
    if scanner_spec != SCAN_SIM:
        from mppf.loop.scanners import DirectoryScanner

        DirectoryScanner(scanner_spec)


def _pick_plate(history, plate_id: str | None):
    if plate_id:
        return history.plate(plate_id)
    active = history.active_plates()
    if not active:
        raise InputError(f"no unfinished plate in the history {history.path}",
                         hint="start one with 'mppf loop DESIGN FLAT ...' or see 'mppf history'")
    if len(active) > 1:
        raise InputError(
            f"{len(active)} unfinished plates in the history: {', '.join(p.plate_id for p in active)}",
            hint="name the one to continue with --plate-id",
        )
    return active[0]


def _new_plate_id(history, design, flat, press_path, thickness, plate_id) -> str:
    """The id of the new plate, checked (safe characters, not in the history yet)."""
    if design is None or flat is None or press_path is None or thickness is None:
        raise InputError("mppf loop needs DESIGN, FLAT, --press and --thickness (or --resume)",
                         hint="e.g. mppf loop design.csv flat.csv --press press.toml --thickness 20")
    from mppf.loop.plate import new_plate_id

    plate_id = plate_id or new_plate_id(design)
    history.check_new_plate(plate_id)
    return plate_id


def _resumed_plate(history, design, flat, plate_id, press_path):
    """The unfinished plate to continue (a --press given must be the press it was planned for)."""
    if design or flat:
        raise InputError("--resume continues a recorded plate and takes no DESIGN or FLAT",
                         hint="drop the file arguments, name the plate with --plate-id")
    plate = _pick_plate(history, plate_id)
    if plate.status == "active" and not history.cycles(plate.plate_id):
        raise InputError(f"plate {plate.plate_id} was recorded without its first cycle (an older mppf stopped in "
                         "between): there is nothing to resume",
                         hint=f"start it again under its id: mppf loop DESIGN FLAT ... --plate-id {plate.plate_id}")
    if press_path is not None:
        from mppf.model.press import load_press, press_from_dict

        given, recorded = load_press(press_path), press_from_dict(plate.press, source="the history")
        if given != recorded:
            raise InputError(
                f"--press {press_path}: plate {plate.plate_id} was planned for another press ({recorded.name!r}, "
                f"{recorded.rows} x {recorded.cols} punches; the file: {given.name!r}, {given.rows} x {given.cols}); "
                "--resume continues on the press it was planned for",
                hint="leave --press out with --resume, or start a new plate for the other press")
    if plate.status != "active":
        raise InputError(f"plate {plate.plate_id} has finished ({plate.status}); nothing to resume",
                         hint="see 'mppf history --plate-id " + plate.plate_id + "'")
    return plate


def _record(history, draft: Draft, settings, work_dir, setup):
    """Record the drafted plate with its first cycle (one transaction)."""
    from mppf.loop.options import LoopOptions, PlateInputs
    from mppf.loop.plate import record_plate

    work = work_dir or history.path.parent / "plates" / draft.plate_id
    return record_plate(history, PlateInputs(draft.design, draft.flat, draft.press, draft.job.thickness_mm), draft.job,
                        plate_id=draft.plate_id, work_dir=work, options=LoopOptions(settings=settings, setup=setup))


@click.command("loop")
@click.argument("design", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.argument("flat", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--press", "press_path", type=click.Path(path_type=Path), help="Press description (TOML).")
@click.option("--thickness", type=float, help="Plate thickness (mm).")
@click.option("--plc", "plc_url", help="PLC URL (tcp://HOST:PORT?unit=1); none = dry run on the simulated PLC.")
@click.option("--scanner", "scanner_spec", help="'sim' (simulated scan; default in dry runs) or the folder the "
              "scanner software writes scan files into.")
@click.option("--tolerance", type=float, default=_DEFAULTS.tolerance_mm, show_default=True,
              help="Largest absolute form deviation (mm; scanner point noise averaged out).")
@click.option("--rms-tolerance", type=float, default=_DEFAULTS.rms_tolerance_mm, show_default=True,
              help="Largest RMS deviation (mm).")
@click.option("--max-cycles", type=int, default=_DEFAULTS.max_cycles, show_default=True, help="Press cycles at most.")
@click.option("--no-springback", is_flag=True, help="Plan without springback pre-compensation.")
@click.option("--yield-uncertainty", "yield_uncertainty", type=float, default=_DEFAULTS.yield_uncertainty_pct,
              show_default=True, help="Scatter of the plate's yield stress (+- %, the mill certificate's): the first "
              "press compensates springback for the weakest plate of the range, so it under-bends and the "
              "corrections add bend (0: the nominal yield stress; docs/planning.md).")
@click.option("--margin", "margin_mm", type=float, default=None,
              help="Trim margin (mm) the flat plate is cut with and trimmed off after forming; default the "
                   "press's [forming] margin_mm.")
@click.option("--material", type=click.Choice(sorted(MATERIALS)), default="steel", show_default=True,
              help="Nominal plate material (springback pre-compensation; the simulated plate).")
@history_option
@click.option("--audit", "audit_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Audit log of PLC commands [default: next to the history].")
@click.option("--plate-id", help="Plate id (new plate), or the plate to --resume.")
@click.option("--work-dir", type=click.Path(file_okay=False, path_type=Path),
              help="Folder for the plate's job and scan files [default: plates/ID next to the history].")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the simulated plate and scans.")
@click.option("--physics", type=click.Choice(["fd", "fe"]), default="fd", show_default=True,
              help="Simulated plate of a dry run: the finite-difference steel plate (fd) or the finite-element "
                   "plate computed by CalculiX (fe, needs ccx; docs/simulator-fe.md). Recorded with the plate.")
@time_scale_option
@click.option("--scan-timeout", type=float, default=1800.0, show_default=True,
              help="Longest wait for the operator's scan file (s).")
@click.option("--on-pressed", "on_pressed", metavar="CMD",
              help="Command run when a cycle is pressed, after the scan request file is written into the scan "
                   "folder: the request's path is its last argument and $MPPF_SCAN_REQUEST; run without a shell; "
                   "its failure is reported and the loop goes on (docs/scanner-station.md). Recorded with the "
                   "plate, like the mark waits: --resume uses the recorded ones.")
@click.option("--on-pressed-timeout", type=float, default=_DEFAULTS.on_pressed_timeout_s, show_default=True,
              help="Longest run of the --on-pressed command (s); it is killed after.")
@click.option("--mark-timeout", type=float, default=_DEFAULTS.mark_timeout_s, show_default=True,
              help="Longest wait (s) for the reference mark of a scan of a nearly symmetric plate (which is not "
                   "compared without it); then exit 4, the cycle waits for --resume.")
@click.option("--mark-settle", type=float, default=_DEFAULTS.mark_settle_s, show_default=True,
              help="How long (s) a scan without its mark waits for one saved just after it, when the plate does "
                   "not need the mark (then: the best fit).")
@click.option("--rescans", type=int, default=_DEFAULTS.rescans, show_default=True,
              help="Rescans a cycle may ask for when areas of the net plate were not measured and nothing else "
                   "needs review; the union of the scans is compared (0: stop for review at once).")
@click.option("--rescan-timeout", type=float, default=_DEFAULTS.rescan_timeout_s, show_default=True,
              help="Longest wait for a rescan file (s; at most --scan-timeout). After one unanswered rescan "
                   "request the run asks for no more and decides on the scans taken.")
@click.option("--resume", is_flag=True, help="Continue an interrupted plate (never presses a cycle twice).")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@click.option("--yes", is_flag=True, help="Do not ask before driving a real press.")
@click.option("--report/--no-report", "write_report_", default=True, show_default=True,
              help="Write the plate's pictures and report.html into its work folder at the end.")
@click.option("--operator", help="Who runs the plate (printed in the report).")
@units_option
def loop(design, flat, press_path, thickness, plc_url, scanner_spec, tolerance, rms_tolerance, max_cycles,
         no_springback, margin_mm, material, history_path, audit_path, plate_id, work_dir, seed, time_scale,
         scan_timeout, on_pressed, on_pressed_timeout, mark_timeout, mark_settle, rescans, rescan_timeout, resume,
         as_json, yes, write_report_, operator, units, physics, yield_uncertainty):
    """Plan, press, measure, compare, correct, press again, until the plate is in tolerance.

    Stops when the largest absolute form deviation is within --tolerance and the RMS within
    --rms-tolerance, after --max-cycles, or when the error diverges (the RMS more than
    1.5 times the best in two cycles running, or growing by more than 0.1 mm two cycles in
    a row). Every cycle is recorded in the history; after a crash or power cut,
    'mppf loop --resume' continues at the right cycle and never presses a cycle twice.

    Without --plc this is a dry run: the simulated PLC (real Modbus over loopback), a
    simulated plate and a simulated scanner. With --plc a real press asks for confirmation
    first (or takes --yes; without a terminal it refuses, exit 4).

    With --scanner FOLDER, each pressed cycle writes a scan request (PLATE-cycle-NN.scan-request.json)
    into the folder, runs --on-pressed, and takes the next new scan file there once its
    reference mark is in (the mark file SCAN.mark.json or a 'reference_mark_mm X Y Z' header
    line); a nearly symmetric plate is not compared without its mark (exit 4 after
    --mark-timeout). The scans are the top skin: the design's concave side (its +normal
    side), not whichever side faces up. Areas of the net plate not measured (and nothing else
    in the way of "in tolerance") are rescanned, up to --rescans times, and the union of the
    scans compared. See docs/scanner-station.md.

    Exit code: 0 in tolerance, 5 not brought into tolerance (cannot converge, diverged, max
    cycles, badly formed), 6 needs review; the verdict (why, where, what to do) is printed,
    and with --json is "verdict" and "ending".
    """
    # every option and file checked before anything is read, planned or recorded
    _check_options(thickness, scan_timeout, seed, audit_path)
    if physics == "fe":
        from mppf.sim.fe.ccx import find_ccx

        find_ccx()  # without CalculiX: how to install it (exit 2), before anything is recorded
    settings = LoopSettings(tolerance_mm=tolerance, rms_tolerance_mm=rms_tolerance, max_cycles=max_cycles,
                            springback=not no_springback, margin_mm=margin_mm, on_pressed=on_pressed,
                            yield_uncertainty_pct=check_yield_uncertainty(yield_uncertainty),
                            on_pressed_timeout_s=_positive("--on-pressed-timeout", on_pressed_timeout),
                            mark_timeout_s=_positive("--mark-timeout", mark_timeout),
                            mark_settle_s=check_number("--mark-settle", mark_settle, low=0.0, unit="s",
                                                       hint="give the wait in s, 0 or more"),
                            rescans=check_number("--rescans", rescans, low=0, high=MAX_RESCANS, integer=True),
                            rescan_timeout_s=_positive("--rescan-timeout", rescan_timeout))
    call = _PlateCall(design=design, flat=flat, press_path=press_path, thickness_mm=thickness, plate_id=plate_id,
                      resume=resume, work_dir=work_dir, seed=seed, physics=physics, audit_path=audit_path,
                      write_report=write_report_, operator=operator)
    run = RunOptions(plc_url=plc_url, scanner_spec=scanner_spec, time_scale=time_scale, scan_timeout_s=scan_timeout,
                     yes=yes, material=material, units=units)
    reporter = RichReporter(enabled=not as_json)
    # SIGTERM ends the command like Ctrl-C: the press is stopped, the lease given back
    with sigterm_as_ctrl_c(), open_history(history_path) as history:
        result = _run_plate_call(history, call, run, settings, reporter)
    _print_result(result, as_json)


@dataclass(frozen=True)
class _PlateCall:
    """The plate ``mppf loop`` was asked to run and what is recorded with it (its click options).

    Attributes
    ----------
    design, flat : Path or None
        The point files of a new plate (None with ``resume``).
    press_path : Path or None
        The press description (TOML).
    thickness_mm : float or None
        Plate thickness, mm.
    plate_id : str or None
        The new plate's id, or the plate to resume; None: made from the design's name, or the one
        unfinished plate.
    resume : bool
        Continue a recorded plate.
    work_dir : Path or None
        The plate's folder; None: ``plates/ID`` next to the history.
    seed : int
        Seed of the simulated plate and scans.
    physics : str
        ``fd`` or ``fe``: the simulated plate of a dry run.
    audit_path : Path or None
        The audit log; None: next to the history.
    write_report : bool
        Write the plate's pictures and report at the end.
    operator : str or None
        Who runs the plate.
    """

    design: Path | None
    flat: Path | None
    press_path: Path | None
    thickness_mm: float | None
    plate_id: str | None
    resume: bool
    work_dir: Path | None
    seed: int
    physics: str
    audit_path: Path | None
    write_report: bool
    operator: str | None


def _resolve_plate(history, call: _PlateCall, run: RunOptions) -> tuple[str, RunOptions]:
    """The plate to run (new: its id checked; resumed: the recorded plate) and the run with its PLC and scanner.

    A resumed plate takes the PLC URL and scanner recorded with it unless given, both checked here;
    a new plate's are checked once its lease is held (:func:`_run_plate_call`). ``run.scanner_spec``
    None: not given (a new plate: the simulated scanner).
    """
    if call.resume:
        plate = _resumed_plate(history, call.design, call.flat, call.plate_id, call.press_path)
        run = dataclasses.replace(run, plc_url=run.plc_url or plate.settings.get("plc"),
                                  scanner_spec=run.scanner_spec or plate.settings.get("scanner", SCAN_SIM))
        _check_link_and_scanner(run.plc_url, run.scanner_spec)
        return plate.plate_id, run
    run = dataclasses.replace(run, scanner_spec=run.scanner_spec or SCAN_SIM)
    return _new_plate_id(history, call.design, call.flat, call.press_path, call.thickness_mm, call.plate_id), run


def _run_plate_call(history, call: _PlateCall, run: RunOptions, settings: LoopSettings, reporter):
    """Run the plate under its lease (one loop per plate): a new one is checked, planned and drafted first.

    Returns
    -------
    LoopResult
        As :func:`mppf.cli._loop_run.run_plate`.
    """
    plate_id, run = _resolve_plate(history, call, run)
    # one loop per plate: the lease is held from here to the end
    with history.lease(plate_id) as taken_over:
        if taken_over:
            reporter.info(f"plate {plate_id}: took over the stale lease of {taken_over}")
        draft = None
        if not call.resume:
            _check_link_and_scanner(run.plc_url, run.scanner_spec)  # before planning and recording anything
            draft = draft_plate(plate_id, call.design, call.flat, call.press_path, call.thickness_mm, settings, run,
                                reporter)
        return _drive(history, plate_id, draft, call, run, settings, reporter)


def _drive(history, plate_id: str, draft: Draft | None, call: _PlateCall, run: RunOptions, settings: LoopSettings,
           reporter):
    """Record a drafted plate once the press took its job, run its cycles, then write its report.

    Returns
    -------
    LoopResult
        As :func:`mppf.cli._loop_run.run_plate`.
    """
    from mppf.drivers.audit import AuditLog

    setup = {"plc": run.plc_url, "scanner": run.scanner_spec, "seed": call.seed, "units": run.units,
             "material": run.material, "physics": call.physics, "reach": None if draft is None else draft.reach}
    audit = AuditLog(call.audit_path or history.path.parent / "audit.sqlite")
    comparisons = {}

    def on_cycle(record, comparison):
        print_cycle(record, comparison)
        if comparison is not None:
            comparisons[record.cycle] = comparison

    try:
        result = run_plate(history, plate_id, draft, run, audit=audit, reporter=reporter,
                           record=lambda h, d: _record(h, d, settings, call.work_dir, setup), on_cycle=on_cycle)
        # the plate's report, into its work folder
        if call.write_report:
            path = write_report(history, plate_id, comparisons, operator=call.operator, reporter=reporter)
            reporter.info(f"report of plate {plate_id}: {path}")
    finally:
        reporter.finish()
        audit.close()
    return result


def _print_result(result, as_json: bool) -> None:
    """Print the plate's result (a table and the verdict, or JSON); exit 5 or 6 when it did not end in tolerance."""
    end = result.ending
    if as_json:
        print_json({"plate_id": result.plate_id, "status": result.status, "resumed_state": result.resumed_state,
                    "verdict": result.verdict, "ending": None if end is None else end.to_dict(),
                    "cycles": [c.to_dict(grids=False) for c in result.cycles]})
    else:
        console.print(cycle_table(result.cycles, f"plate {esc(result.plate_id)}: {result.status}"))
        if result.verdict:
            console.print(f"verdict: {result.verdict}", markup=False, highlight=False)
    if end is not None and end.exit_code:  # 5 not in tolerance, 6 needs review (README, "Exit codes")
        raise click.exceptions.Exit(end.exit_code)


COMMANDS = [loop]
