"""``mppf loop``, ``mppf history`` and ``mppf demo``: the bend - measure - compare loop.

Thin wrappers: the loop itself is :mod:`mppf.loop.cycle`, the history :mod:`mppf.loop.history`.
Dry runs (no ``--plc``) start the simulated PLC in this process and talk to it over
loopback Modbus through the real driver; the simulated plate and scanner come from
:mod:`mppf.sim.shop`.
"""

from __future__ import annotations

import contextlib
import os
import time
from pathlib import Path

import click
from rich.table import Table

from mppf.cli._common import RichReporter, console, err_console, print_json, units_option
from mppf.cli.plan_cmd import MATERIALS
from mppf.core.errors import InputError

DEFAULT_TIME_SCALE = 50.0
"""Dry runs move the simulated punches this many times faster than the real press."""

DRY_RUN_TIMEOUT_S = 5.0
"""Reply timeout of the loopback link to the in-process simulated PLC (s)."""

SCAN_SIM = "sim"


# -- shared wiring --------------------------------------------------------------------------


def _history(path):
    from mppf.loop.history import History

    return History(path)


def _audit(path):
    from mppf.drivers.audit import AuditLog

    return AuditLog(path)


@contextlib.contextmanager
def _press_link(press, plc_url: str | None, audit, time_scale: float, reporter):
    """A connected PressLink: the real PLC at ``plc_url``, or a simulated PLC in this process."""
    from mppf.drivers.modbus import ModbusPress

    if plc_url:
        with ModbusPress(plc_url, press, audit=audit) as link:
            yield link
        return
    from mppf.sim.plc import run_simulated_plc

    reporter.info(f"dry run: simulated PLC in this process, motion {time_scale:g}x faster than the real press")
    # the simulated PLC shares this process (and its CPU) with the comparison: a longer
    # reply timeout than on a real link keeps a busy machine from looking like a dead link
    with run_simulated_plc(press, time_scale=time_scale) as sim, \
            ModbusPress(sim.url, press, audit=audit, timeout_s=DRY_RUN_TIMEOUT_S) as link:
        yield link


def _scanner(spec: str, press, plate, history_plate_cycle1_job, seed: int, scan_timeout_s: float):
    """The Scanner named by ``--scanner``: "sim" or a folder."""
    if spec != SCAN_SIM:
        from mppf.loop.scanners import DirectoryScanner

        return DirectoryScanner(spec, timeout_s=scan_timeout_s)
    from mppf.geometry.io import read_points
    from mppf.sim.shop import SimulatedPlateScanner

    flat = read_points(plate.flat_path, units=plate.settings.get("units", "mm"))
    material = MATERIALS[plate.settings.get("material", "steel")]
    return SimulatedPlateScanner.for_job(press, plate.thickness_mm, history_plate_cycle1_job, flat.points, seed=seed,
                                         material=material)


def _check_link_and_scanner(plc_url: str | None, scanner_spec: str) -> None:
    """Refuse a malformed PLC URL or a missing scan folder (InputError)."""
    if plc_url:
        from mppf.drivers.url import parse_plc_url

        parse_plc_url(plc_url)
    if scanner_spec != SCAN_SIM:
        from mppf.loop.scanners import DirectoryScanner

        DirectoryScanner(scanner_spec)


def _cycle_table(cycles, title: str) -> Table:
    table = Table(title=title, title_justify="left", caption="deviations in mm; within% = share of the scan "
                  "within the tolerance; gain = mean correction gain of the strokes", caption_justify="left")
    for name, justify in (("cycle", "right"), ("state", "left"), ("steps", "right"), ("max|dev|", "right"),
                          ("RMS", "right"), ("within%", "right"), ("gain", "right"), ("decision", "left")):
        table.add_column(name, justify=justify, no_wrap=True)
    for c in cycles:
        table.add_row(
            str(c.cycle), c.state + (" (interrupted)" if c.interrupted else ""),
            f"{c.steps_done}/{len(c.steps)}",
            "-" if c.max_abs_mm is None else f"{c.max_abs_mm:.2f}",
            "-" if c.rms_mm is None else f"{c.rms_mm:.2f}",
            "-" if c.within_pct is None else f"{c.within_pct:.1f}",
            "-" if c.gain is None else f"{c.gain:.2f}",
            c.decision or "-",
        )
    return table


def _print_cycle(record, comparison) -> None:
    """Per-cycle line while the loop runs."""
    if record.state == "compared":
        err_console.print(
            f"[bold]cycle {record.cycle}[/]: max |dev| {record.max_abs_mm:.2f} mm, RMS {record.rms_mm:.2f} mm, "
            f"{record.within_pct:.1f} % within tolerance -> [bold]{record.decision}[/]"
        )


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


def run_plate(history, plate, *, plc_url, scanner_spec, time_scale, audit, reporter, scan_timeout_s,
              on_cycle=_print_cycle):
    """Connect the press and scanner recorded for ``plate`` and run its loop to the end."""
    from mppf.planning.job import load_job
    from mppf.loop.cycle import run_loop
    from mppf.planning.press import press_from_dict

    press = press_from_dict(plate.press, source=f"history of plate {plate.plate_id}")
    first_job = load_job(history.cycle(plate.plate_id, 1).job_path)
    scanner = _scanner(scanner_spec, press, plate, first_job, int(plate.settings.get("seed", 0)), scan_timeout_s)
    with _press_link(press, plc_url, audit, time_scale, reporter) as link:
        return run_loop(history, plate.plate_id, link, scanner, reporter=reporter, on_cycle=on_cycle)


# -- mppf loop --------------------------------------------------------------------------------


@click.command("loop")
@click.argument("design", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.argument("flat", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--press", "press_path", type=click.Path(path_type=Path), help="Press description (TOML).")
@click.option("--thickness", type=float, help="Plate thickness (mm).")
@click.option("--plc", "plc_url", help="PLC URL (tcp://HOST:PORT?unit=1); none = dry run on the simulated PLC.")
@click.option("--scanner", "scanner_spec", help="'sim' (simulated scan; default in dry runs) or the folder the "
              "scanner software writes scan files into.")
@click.option("--tolerance", type=float, default=2.5, show_default=True,
              help="Largest absolute form deviation (mm; scanner point noise averaged out).")
@click.option("--rms-tolerance", type=float, default=1.0, show_default=True, help="Largest RMS deviation (mm).")
@click.option("--max-cycles", type=int, default=5, show_default=True, help="Press cycles at most.")
@click.option("--gain", type=float, default=1.0, show_default=True, help="Gain of the first correction.")
@click.option("--no-springback", is_flag=True, help="Plan without springback pre-compensation.")
@click.option("--margin", "margin_mm", type=float, default=None,
              help="Trim margin (mm) the flat plate is cut with and trimmed off after forming; default the "
                   "press's [forming] margin_mm.")
@click.option("--material", type=click.Choice(["steel", "ah36"]), default="steel", show_default=True,
              help="Nominal plate material (springback pre-compensation; the simulated plate).")
@click.option("--history", "history_path", type=click.Path(dir_okay=False, path_type=Path),
              help="History database [default: $MPPF_HOME/history.sqlite or ~/.local/share/mppf/].")
@click.option("--audit", "audit_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Audit log of PLC commands [default: next to the history].")
@click.option("--plate-id", help="Plate id (new plate), or the plate to --resume.")
@click.option("--work-dir", type=click.Path(file_okay=False, path_type=Path),
              help="Folder for the plate's job and scan files [default: plates/ID next to the history].")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the simulated plate and scans.")
@click.option("--time-scale", type=float, default=DEFAULT_TIME_SCALE, show_default=True,
              help="Dry runs: simulated motion this many times faster than real.")
@click.option("--scan-timeout", type=float, default=1800.0, show_default=True,
              help="Longest wait for the operator's scan file (s).")
@click.option("--resume", is_flag=True, help="Continue an interrupted plate (never presses a cycle twice).")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@click.option("--yes", is_flag=True, help="Do not ask before driving a real press.")
@units_option
def loop(design, flat, press_path, thickness, plc_url, scanner_spec, tolerance, rms_tolerance, max_cycles, gain,
         no_springback, margin_mm, material, history_path, audit_path, plate_id, work_dir, seed, time_scale, scan_timeout, resume,
         as_json, yes, units):
    """Plan, press, measure, compare, correct, press again, until the plate is in tolerance.

    Stops when the largest absolute form deviation is within --tolerance and the RMS within
    --rms-tolerance, after --max-cycles, or when the error diverges (the RMS grows by
    more than 1.5 times, or by more than 0.1 mm two cycles in a row). Every cycle is recorded in the history; after a
    crash or power cut, 'mppf loop --resume' continues at the right cycle and never
    presses a cycle twice.

    Without --plc this is a dry run: the simulated PLC (real Modbus over loopback), a
    simulated plate and a simulated scanner.
    """
    from mppf.geometry.io import read_points
    from mppf.loop.cycle import LoopSettings, new_plate_id, start_plate
    from mppf.planning.press import load_press

    reporter = RichReporter(enabled=not as_json)
    with _history(history_path) as history:
        if resume:
            if design or flat:
                raise InputError("--resume continues a recorded plate and takes no DESIGN or FLAT",
                                 hint="drop the file arguments, name the plate with --plate-id")
            plate = _pick_plate(history, plate_id)
            if plate.status != "active":
                raise InputError(f"plate {plate.plate_id} has finished ({plate.status}); nothing to resume",
                                 hint="see 'mppf history --plate-id " + plate.plate_id + "'")
            plc_url = plc_url or plate.settings.get("plc")
            scanner_spec = scanner_spec or plate.settings.get("scanner", SCAN_SIM)
        else:
            if design is None or flat is None or press_path is None or thickness is None:
                raise InputError("mppf loop needs DESIGN, FLAT, --press and --thickness (or --resume)",
                                 hint="e.g. mppf loop design.csv flat.csv --press press.toml --thickness 20")
            scanner_spec = scanner_spec or SCAN_SIM
            _check_link_and_scanner(plc_url, scanner_spec)  # before planning and recording anything
            if plc_url and scanner_spec == SCAN_SIM:
                err_console.print("[yellow]note:[/] real PLC with the simulated scanner: the scans are simulated")
            press = load_press(press_path)
            settings = LoopSettings(tolerance_mm=tolerance, rms_tolerance_mm=rms_tolerance, max_cycles=max_cycles,
                                    gain=gain, springback=not no_springback, margin_mm=margin_mm)
            design_cloud = read_points(design, units=units)
            flat_cloud = read_points(flat, units=units)
            plate_id = plate_id or new_plate_id(design)
            work = work_dir or history.path.parent / "plates" / plate_id
            plate = start_plate(
                history, design_cloud, flat_cloud, press, thickness, plate_id=plate_id, work_dir=work,
                settings=settings, material=MATERIALS[material], reporter=reporter,
                setup={"plc": plc_url, "scanner": scanner_spec, "seed": seed, "units": units, "material": material},
            )
        if plc_url and not yes:
            click.confirm(f"Drive the press at {plc_url} for plate {plate.plate_id}?", abort=True, err=True)
        audit = _audit(audit_path or history.path.parent / "audit.sqlite")
        try:
            result = run_plate(history, plate, plc_url=plc_url, scanner_spec=scanner_spec, time_scale=time_scale,
                               audit=audit, reporter=reporter, scan_timeout_s=scan_timeout)
        finally:
            reporter.finish()
            audit.close()
    if as_json:
        print_json({"plate_id": result.plate_id, "status": result.status, "resumed_state": result.resumed_state,
                    "cycles": [c.to_dict(grids=False) for c in result.cycles]})
        return
    console.print(_cycle_table(result.cycles, f"plate {result.plate_id}: {result.status}"))


# -- mppf history ---------------------------------------------------------------------------


@click.command("history")
@click.option("--history", "history_path", type=click.Path(dir_okay=False, path_type=Path),
              help="History database [default: $MPPF_HOME/history.sqlite or ~/.local/share/mppf/].")
@click.option("--plate-id", help="Show this plate's cycles only.")
@click.option("--json", "as_json", is_flag=True, help="Print as JSON (with strokes and deviation grids).")
def history(history_path, plate_id, as_json):
    """List the plates of the history and their press cycles."""
    if history_path is not None and not history_path.exists():
        raise InputError(f"history {history_path} does not exist", hint="check the path given with --history")
    with _history(history_path) as hist:
        plates = [hist.plate(plate_id)] if plate_id else hist.plates()
        if as_json:
            print_json({"history": str(hist.path), "plates": [
                {**p.to_dict(), "cycles": [c.to_dict() for c in hist.cycles(p.plate_id)]} for p in plates]})
            return
        if not plates:
            console.print(f"no plates in {hist.path}")
            return
        table = Table(title=f"plates in {hist.path}", title_justify="left",
                      caption="max|dev|, RMS: deviations (mm) of the last measured cycle; t: thickness (mm)",
                      caption_justify="left")
        for name in ("plate", "status", "cycles", "max|dev|", "RMS", "t", "updated (UTC)"):
            table.add_column(name, no_wrap=name == "status", overflow="fold", min_width=5 if name != "t" else 2)
        for p in plates:
            cycles = hist.cycles(p.plate_id)
            done = [c for c in cycles if c.max_abs_mm is not None]
            table.add_row(p.plate_id, p.status, str(len(cycles)),
                          f"{done[-1].max_abs_mm:.2f}" if done else "-", f"{done[-1].rms_mm:.2f}" if done else "-",
                          f"{p.thickness_mm:g}", p.updated_utc[:16].replace("T", " "))
        console.print(table)
        if plate_id:
            console.print(_cycle_table(hist.cycles(plate_id), f"cycles of {plate_id}"))


# -- mppf demo ------------------------------------------------------------------------------

DEMO_PLATE = "P1_midbody_bilge_smooth"
DEMO_THICKNESS_MM = 20.0


def _run_demo(out: Path, plate_name: str, seed: int, thickness_mm: float, time_scale: float, reporter) -> dict:
    """Unfold, plan, press, scan, compare and loop on a bundled plate; pictures into ``out``."""
    import mppf
    from mppf.geometry.io import read_points, write_points
    from mppf.planning.job import load_job
    from mppf.loop.cycle import LoopSettings, run_loop, start_plate
    from mppf.planning.press import example_press_path, load_press
    from mppf.sim.shop import SimulatedPlateScanner
    from mppf.geometry.unfold import unfold
    from mppf.report.deviation import plot_deviation
    from mppf.report.convergence import loop_report, plot_convergence, plot_punch_deviation
    from mppf.report.strokes import plot_strokes
    from mppf.report.strain import plot_strain

    hull = Path(mppf.__file__).parent / "examples" / "hull"
    design_path = hull / f"{plate_name}.csv"
    if not design_path.exists():
        names = sorted(p.stem for p in hull.glob("*.csv"))
        raise InputError(f"no bundled plate named {plate_name!r}", hint=f"choose one of {', '.join(names)}")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder {out}: {exc.strerror}") from None
    files = []
    # 1. the design and its flat shape
    design = read_points(design_path)
    reporter.info(f"unfolding {plate_name} ({design.n_points} points)")
    unfolding = unfold(design.points)
    flat = read_points(write_points(out / f"{plate_name}.flat.csv", unfolding.flat))
    files += [flat.path, plot_strain(unfolding, out / "strain.png", f"{plate_name}: strain of the unfolding")]
    # 2. plan the first cycle (springback pre-compensated) and record the plate
    press = load_press(example_press_path())
    settings = LoopSettings()
    with _history(out / "history.sqlite") as history:
        plate_id = f"demo-{plate_name.split('_')[0]}-s{seed}-{time.strftime('%Y%m%d-%H%M%S')}"
        plate = start_plate(history, design, flat, press, thickness_mm, plate_id=plate_id,
                            work_dir=out / "plates" / plate_id, settings=settings,
                            setup={"plc": None, "scanner": SCAN_SIM, "seed": seed}, reporter=reporter)
        job = load_job(history.cycle(plate_id, 1).job_path)
        files.append(plot_strokes(job, out / "strokes.png"))
        # 3. the loop on the simulated press, plate and scanner; a deviation map per cycle
        scanner = SimulatedPlateScanner.for_job(press, thickness_mm, job, flat.points, seed=seed)
        cycle_pictures = {}

        def on_cycle(record, comparison):
            _print_cycle(record, comparison)
            if comparison is not None:
                n = record.cycle
                shots = [(f"cycle {n}: deviation of the scan from the design",
                          plot_deviation(comparison, out / f"deviation-cycle-{n}.png",
                                         f"cycle {n}: deviation of the scan from the design")),
                         (f"cycle {n}: deviation at the punches",
                          plot_punch_deviation(comparison, job.punch_x_mm, job.punch_y_mm,
                                               out / f"punch-deviation-cycle-{n}.png"))]
                files.extend(path for _, path in shots)
                cycle_pictures[n] = [(caption, path.read_bytes()) for caption, path in shots]

        with _audit(out / "audit.sqlite") as audit, _press_link(press, None, audit, time_scale, reporter) as link:
            result = run_loop(history, plate_id, link, scanner, reporter=reporter, on_cycle=on_cycle)
        # 4. convergence chart and the HTML report
        files.append(plot_convergence(result.cycles, out / "convergence.png", settings.tolerance_mm,
                                      settings.rms_tolerance_mm))
        html = loop_report(
            history.plate(plate_id), result.cycles, tolerance_mm=settings.tolerance_mm,
            rms_tolerance_mm=settings.rms_tolerance_mm, cycle_pictures=cycle_pictures,
            pictures=[("strain of the unfolding", (out / "strain.png").read_bytes()),
                      ("strokes of the first cycle's last step", (out / "strokes.png").read_bytes())],
            intro=f"Dry run of mppf demo on the bundled hull plate {plate_name}, {thickness_mm:g} mm, seed {seed}: "
                  f"simulated PLC over loopback Modbus (motion {time_scale:g}x faster than real), simulated "
                  "plate (true material scattered around the nominal) and simulated scanner.",
        )
        report = out / "report.html"
        report.write_text(html)
        files.append(report)
    return {"result": result, "plate": plate, "files": files}


@click.command("demo")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=Path("mppf-demo"),
              show_default=True, help="Output folder (pictures, report, history).")
@click.option("--plate", "plate_name", default=DEMO_PLATE, show_default=True,
              help="Bundled hull plate (mppf/examples/hull/NAME.csv).")
@click.option("--seed", type=int, default=1, show_default=True, help="Seed of the simulated plate and scans.")
@click.option("--thickness", type=float, default=DEMO_THICKNESS_MM, show_default=True, help="Plate thickness (mm).")
@click.option("--time-scale", type=float, default=DEFAULT_TIME_SCALE, show_default=True,
              help="Simulated motion this many times faster than the real press.")
def demo(out_dir, plate_name, seed, thickness, time_scale):
    """Unfold, plan, press, scan, compare and loop on a bundled hull plate, all simulated.

    A dry run: the simulated PLC runs in this process and is driven over loopback Modbus
    by the real driver; the plate and the scanner are simulated. Writes pictures (strain,
    strokes, deviation per cycle, convergence), an HTML report and the history into
    --out, and prints a summary table.
    """
    started = time.monotonic()
    reporter = RichReporter()
    try:
        summary = _run_demo(out_dir, plate_name, seed, thickness, time_scale, reporter)
    finally:
        reporter.finish()
    result = summary["result"]
    console.print(_cycle_table(result.cycles, f"demo plate {plate_name} ({thickness:g} mm, seed {seed}): "
                                              f"{result.status}"))
    console.print(f"dry run: simulated PLC over loopback Modbus, motion {time_scale:g}x faster than the real press",
                  soft_wrap=True)
    console.print(f"pictures and report in {out_dir}{os.sep}:", soft_wrap=True)
    for path in summary["files"]:
        console.print(f"  {path}", soft_wrap=True)
    console.print(f"done in {time.monotonic() - started:.1f} s")


COMMANDS = [loop, history, demo]
