"""``mppf loop``: the bend - measure - compare loop of one plate (thin over :mod:`mppf.loop`).

The loop itself is :mod:`mppf.loop.cycle`, the history :mod:`mppf.loop.history`. The press
follows :mod:`mppf.cli.press_policy` like ``mppf press``: without ``--plc`` a dry run on the
simulated PLC in this process over loopback Modbus, with ``--plc`` the operator confirms
first (or ``--yes``), SIGTERM stops the press like Ctrl-C. The simulated plate and scanner
of dry runs come from :mod:`mppf.sim.shop`.
"""

from __future__ import annotations

from pathlib import Path

import click

from mppf.cli._common import RichReporter, console, err_console, print_json, units_option
from mppf.cli._cycles import cycle_table, print_cycle
from mppf.cli.history_cmd import history_option, open_history
from mppf.cli.press_policy import confirm_motion, press_description, press_link, sigterm_as_ctrl_c, time_scale_option
from mppf.core.errors import InputError
from mppf.forming.material import MATERIALS
from mppf.loop.settings import LoopSettings

SCAN_SIM = "sim"
_DEFAULTS = LoopSettings()  # the loop's defaults (tolerances from mppf.core.defaults), written once


def _scanner(spec: str, press, plate, first_job, seed: int, scan_timeout_s: float):
    """The Scanner named by ``--scanner``: "sim" or a folder."""
    if spec != SCAN_SIM:
        from mppf.loop.scanners import DirectoryScanner

        return DirectoryScanner(spec, timeout_s=scan_timeout_s)
    from mppf.geometry.read import read_points
    from mppf.sim.shop import SimulatedPlateScanner

    flat = read_points(plate.flat_path, units=plate.settings.get("units", "mm"))
    material = MATERIALS[plate.settings.get("material", "steel")]
    return SimulatedPlateScanner.for_job(press, plate.thickness_mm, first_job, flat.points, seed=seed,
                                         material=material)


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


def run_plate(history, plate, *, plc_url, scanner_spec, time_scale, audit, reporter, scan_timeout_s, yes=False,
              on_cycle=print_cycle):
    """Connect the press and scanner recorded for ``plate``, confirm, and run its loop to the end."""
    from mppf.loop.cycle import run_loop
    from mppf.planning.job import load_job
    from mppf.planning.press import press_from_dict

    press = press_from_dict(plate.press, source=f"history of plate {plate.plate_id}")
    first_job = load_job(history.cycle(plate.plate_id, 1).job_path)
    scanner = _scanner(scanner_spec, press, plate, first_job, int(plate.settings.get("seed", 0)), scan_timeout_s)
    with sigterm_as_ctrl_c(), press_link(press, plc_url, audit=audit, time_scale=time_scale,
                                         reporter=reporter) as link:
        if plc_url:
            confirm_motion(link, f"plate {plate.plate_id} on {press_description(link)}", yes)
        return run_loop(history, plate.plate_id, link, scanner, reporter=reporter, on_cycle=on_cycle)


def _new_plate(history, design, flat, press_path, thickness, plc_url, scanner_spec, settings, material, plate_id,
               work_dir, seed, units, reporter):
    """Check the link and the scanner, plan and record a new plate."""
    from mppf.geometry.read import read_points
    from mppf.loop.plate import new_plate_id, start_plate
    from mppf.planning.press import load_press

    if design is None or flat is None or press_path is None or thickness is None:
        raise InputError("mppf loop needs DESIGN, FLAT, --press and --thickness (or --resume)",
                         hint="e.g. mppf loop design.csv flat.csv --press press.toml --thickness 20")
    _check_link_and_scanner(plc_url, scanner_spec)  # before planning and recording anything
    if plc_url and scanner_spec == SCAN_SIM:
        err_console.print("[yellow]note:[/] real PLC with the simulated scanner: the scans are simulated")
    press = load_press(press_path)
    design_cloud = read_points(design, units=units)
    flat_cloud = read_points(flat, units=units)
    plate_id = plate_id or new_plate_id(design)
    work = work_dir or history.path.parent / "plates" / plate_id
    return start_plate(
        history, design_cloud, flat_cloud, press, thickness, plate_id=plate_id, work_dir=work,
        settings=settings, material=MATERIALS[material], reporter=reporter,
        setup={"plc": plc_url, "scanner": scanner_spec, "seed": seed, "units": units, "material": material},
    )


def _resumed_plate(history, design, flat, plate_id):
    """The unfinished plate to continue."""
    if design or flat:
        raise InputError("--resume continues a recorded plate and takes no DESIGN or FLAT",
                         hint="drop the file arguments, name the plate with --plate-id")
    plate = _pick_plate(history, plate_id)
    if plate.status != "active":
        raise InputError(f"plate {plate.plate_id} has finished ({plate.status}); nothing to resume",
                         hint="see 'mppf history --plate-id " + plate.plate_id + "'")
    return plate


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
@click.option("--gain", type=float, default=_DEFAULTS.gain, show_default=True, help="Gain of the first correction.")
@click.option("--no-springback", is_flag=True, help="Plan without springback pre-compensation.")
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
@time_scale_option
@click.option("--scan-timeout", type=float, default=1800.0, show_default=True,
              help="Longest wait for the operator's scan file (s).")
@click.option("--resume", is_flag=True, help="Continue an interrupted plate (never presses a cycle twice).")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@click.option("--yes", is_flag=True, help="Do not ask before driving a real press.")
@units_option
def loop(design, flat, press_path, thickness, plc_url, scanner_spec, tolerance, rms_tolerance, max_cycles, gain,
         no_springback, margin_mm, material, history_path, audit_path, plate_id, work_dir, seed, time_scale,
         scan_timeout, resume, as_json, yes, units):
    """Plan, press, measure, compare, correct, press again, until the plate is in tolerance.

    Stops when the largest absolute form deviation is within --tolerance and the RMS within
    --rms-tolerance, after --max-cycles, or when the error diverges (the RMS grows by
    more than 1.5 times, or by more than 0.1 mm two cycles in a row). Every cycle is recorded in the history; after a
    crash or power cut, 'mppf loop --resume' continues at the right cycle and never
    presses a cycle twice.

    Without --plc this is a dry run: the simulated PLC (real Modbus over loopback), a
    simulated plate and a simulated scanner. With --plc a real press asks for confirmation
    first (or takes --yes; without a terminal it refuses, exit 4).
    """
    from mppf.drivers.audit import AuditLog

    reporter = RichReporter(enabled=not as_json)
    with open_history(history_path) as history:
        if resume:
            plate = _resumed_plate(history, design, flat, plate_id)
            plc_url = plc_url or plate.settings.get("plc")
            scanner_spec = scanner_spec or plate.settings.get("scanner", SCAN_SIM)
        else:
            scanner_spec = scanner_spec or SCAN_SIM
            settings = LoopSettings(tolerance_mm=tolerance, rms_tolerance_mm=rms_tolerance, max_cycles=max_cycles,
                                    gain=gain, springback=not no_springback, margin_mm=margin_mm)
            plate = _new_plate(history, design, flat, press_path, thickness, plc_url, scanner_spec, settings, material,
                               plate_id, work_dir, seed, units, reporter)
        audit = AuditLog(audit_path or history.path.parent / "audit.sqlite")
        try:
            result = run_plate(history, plate, plc_url=plc_url, scanner_spec=scanner_spec, time_scale=time_scale,
                               audit=audit, reporter=reporter, scan_timeout_s=scan_timeout, yes=yes)
        finally:
            reporter.finish()
            audit.close()
    if as_json:
        print_json({"plate_id": result.plate_id, "status": result.status, "resumed_state": result.resumed_state,
                    "cycles": [c.to_dict(grids=False) for c in result.cycles]})
        return
    console.print(cycle_table(result.cycles, f"plate {result.plate_id}: {result.status}"))


COMMANDS = [loop]
