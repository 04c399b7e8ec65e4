"""The run of ``mppf loop``: the new plate drafted, the press linked, the plate recorded, its loop run.

:mod:`mppf.cli.loop_cmd` checks the options and files, resolves the plate (new or resumed)
and builds one :class:`RunOptions` from the click options; this module plans the new plate
(:func:`draft_plate`, nothing recorded) and runs it (:func:`run_plate`): the job checked
against the PLC, the operator asked, the plate recorded, the loop of :mod:`mppf.loop.cycle`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from mppf.cli._common import check_design_size, err_console, read_input
from mppf.cli._cycles import print_cycle
from mppf.cli.press_policy import (
    confirm_motion,
    press_description,
    press_link,
    sigterm_as_ctrl_c,
)
from mppf.model.material import MATERIALS

SCAN_SIM = "sim"
"""``--scanner`` value of the simulated scanner."""


@dataclass(frozen=True)
class RunOptions:
    """The run's settings from the click options of ``mppf loop`` (built once, after --resume is resolved).

    Attributes
    ----------
    plc_url : str or None
        PLC URL; None = dry run on the simulated PLC.
    scanner_spec : str
        "sim" or the folder the scanner software writes scan files into.
    time_scale : float
        Time scale of the simulated PLC (``--time-scale``).
    scan_timeout_s : float
        Longest wait for a scan file (s).
    yes : bool
        Do not ask before driving a real press.
    material : str
        Nominal plate material (a key of ``MATERIALS``).
    units : str
        Units of the point files read.
    """

    plc_url: str | None
    scanner_spec: str
    time_scale: float
    scan_timeout_s: float
    yes: bool = False
    material: str = "steel"
    units: str = "mm"


@dataclass(frozen=True)
class Draft:
    """A new plate read and planned, not yet recorded."""

    plate_id: str
    design: object
    flat: object
    press: object
    job: object
    press_path: Path
    reach: dict | None = None


def draft_plate(plate_id, design, flat, press_path, thickness, settings, run: RunOptions, reporter) -> Draft:
    """Read the files and plan the new plate (nothing recorded); the link and scanner are checked before.

    ``design`` and ``flat`` are point files, ``thickness`` the plate thickness (mm).
    """
    from mppf.loop.plate import plan_first_cycle, plate_reach
    from mppf.model.press import load_press

    if run.plc_url and run.scanner_spec == SCAN_SIM:
        err_console.print("[yellow]note:[/] real PLC with the simulated scanner: the scans are simulated")
    press = load_press(press_path)
    design_cloud = read_input(design, units=run.units)
    flat_cloud = read_input(flat, units=run.units)
    for path, cloud in ((design, design_cloud), (flat, flat_cloud)):
        check_design_size(path, cloud.n_points)
    reporter.info(f"planning plate {plate_id}")
    job = plan_first_cycle(design_cloud, flat_cloud, press, thickness, settings=settings,
                           material=MATERIALS[run.material], reporter=reporter)
    reach = plate_reach(press, job, design_cloud.points, settings.tolerance_mm)
    if reach is not None:
        reporter.info(reach["text"])
    return Draft(plate_id, design_cloud, flat_cloud, press, job, Path(press_path), reach)


def _scanner(history, plate, spec: str, press, scan_timeout_s: float):
    """The Scanner named by ``--scanner``: "sim" (from the plate's recorded flat, first job and seed) or a folder."""
    if spec != SCAN_SIM:
        from mppf.loop.scanners import DirectoryScanner

        return DirectoryScanner(spec, timeout_s=scan_timeout_s)
    from mppf.geometry.read import read_points
    from mppf.planning.job import load_job
    from mppf.sim.shop import PHYSICS, SimulatedPlateScanner

    flat = read_points(plate.flat_path, units=plate.settings.get("units", "mm"))
    first_job = load_job(history.cycle(plate.plate_id, 1).job_path)
    material = MATERIALS[plate.settings.get("material", "steel")]
    return SimulatedPlateScanner.for_job(press, plate.thickness_mm, first_job, flat.points,
                                         seed=int(plate.settings.get("seed", 0)), material=material,
                                         plate_model=PHYSICS[plate.settings.get("physics", "fd")])


def run_plate(history, plate_id, draft, run: RunOptions, *, audit, reporter, record=None, on_cycle=print_cycle):
    """Connect the press and scanner, check the job against the PLC, confirm, record a drafted plate, run its loop.

    ``draft`` is a new plate (recorded by ``record(history, draft)`` once the press took
    its job and the operator confirmed), or None to continue the recorded ``plate_id``.
    """
    from mppf.cli._placement import placement_lines
    from mppf.loop.cycle import run_loop
    from mppf.model.press import press_from_dict

    plate = history.plate(plate_id) if draft is None else None
    press = draft.press if plate is None else press_from_dict(plate.press, source=f"history of plate {plate_id}")
    if run.plc_url:  # a real PLC: the press is this machine's installed one, when there is one (issue 38)
        from mppf.planning.press import check_installed_press

        check_installed_press(press, f"the press of plate {plate_id}")
    with sigterm_as_ctrl_c(), press_link(press, run.plc_url, audit=audit, time_scale=run.time_scale,
                                         reporter=reporter, yes=run.yes) as link:
        # the one job validator against this PLC (its matrix, its limits) before anything is recorded
        if draft is not None:
            link.check_job(draft.job, draft.press, str(draft.press_path))
        # where to lay the plate; at --plc the operator confirms it lies there and the press is clear
        for line in placement_lines(draft.job if draft is not None else _latest_job(history, plate_id)):
            reporter.info(line)
        if run.plc_url:
            confirm_motion(link, f"plate {plate_id} on {press_description(link)}, with the plate laid as printed "
                                 "above", run.yes)
        # a new plate is recorded now, with its first cycle; the loop takes everything from the history
        if draft is not None:
            plate = record(history, draft)
        recorded = press_from_dict(plate.press, source=f"history of plate {plate_id}")
        scanner = _scanner(history, plate, run.scanner_spec, recorded, run.scan_timeout_s)
        return run_loop(history, plate.plate_id, link, scanner, reporter=reporter, on_cycle=on_cycle,
                        place=_placer(reporter, run.yes, dry_run=not run.plc_url))


def _placer(reporter, yes: bool, *, dry_run: bool):
    """Before each section of a plate larger than the bed: the placement line; at --plc the operator confirms it."""
    from mppf.cli._sections import confirm_placement
    from mppf.core.errors import PressRefused
    from mppf.planning.sections import placement_text

    def place(section, previous) -> None:
        text = placement_text(section, previous)
        reporter.info(text)
        try:
            confirm_placement(text, yes, dry_run)
        except PressRefused as exc:  # nothing of the section was sent; the loop goes on from there when resumed
            raise PressRefused(exc.message,
                               hint="place the plate by its marks and continue with 'mppf loop --resume'") from None

    return place


def _latest_job(history, plate_id):
    """The job of a recorded plate's latest cycle (the plate lies the same way in every cycle)."""
    from mppf.planning.job import load_job

    return load_job(history.cycles(plate_id)[-1].job_path)
