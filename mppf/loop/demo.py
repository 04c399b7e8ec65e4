"""The demo: the whole chain on a bundled hull plate, unfold - plan - press - scan - compare - correct.

:func:`run_demo` unfolds a bundled design, plans it, records the plate in a history in
the output folder, and runs the loop on the press it is given (by default the in-process
press, instant; ``mppf demo`` gives it the simulated PLC over loopback Modbus, a faithful
dry run) with a simulated plate and scanner (:mod:`mppf.sim.shop`). It returns what
happened (:class:`DemoRun`); the pictures and the HTML report are drawn from that by
:func:`mppf.report.convergence.demo_report`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, ContextManager

from mppf.core.errors import InputError
from mppf.core.presslink import PressLink
from mppf.core.progress import NULL_REPORTER, Reporter
from mppf.loop.settings import LoopSettings

if TYPE_CHECKING:  # the demo's heavy modules are imported when it runs: the CLI reads the defaults here
    from mppf.geometry.read import PointCloud
    from mppf.geometry.unfold import Unfolding
    from mppf.loop.cycle import CycleCallback, LoopResult
    from mppf.loop.records import PlateRecord
    from mppf.model.job import Job
    from mppf.model.press import PressConfig

DEMO_PLATE = "P1_midbody_bilge_smooth"
"""The bundled plate of the demo (the DTC midship bilge)."""

DEMO_THICKNESS_MM = 20.0
DEMO_SEED = 1

#: Connects a press for the demo: ``connect(press)`` is a context manager giving a PressLink.
Connect = Callable[["PressConfig"], ContextManager[PressLink]]


@dataclass(frozen=True)
class DemoRun:
    """What the demo did.

    Attributes
    ----------
    out : Path
        The output folder (history, audit log, plate files).
    plate_name : str
    thickness_mm : float
    seed : int
    settings : LoopSettings
    unfolding : Unfolding
        The design's flat shape.
    flat_path : Path
        The flat shape, written as a point file into ``out``.
    job : Job
        The first cycle's job.
    plate : PlateRecord
        The plate as recorded at the end.
    result : LoopResult
    comparisons : dict of int to Comparison
        Each cycle's comparison, by cycle.
    flat_dxf_path : Path or None
        The flat for the cutter (DXF: cut and net outlines, the reference mark), in ``out``.
    """

    out: Path
    plate_name: str
    thickness_mm: float
    seed: int
    settings: LoopSettings
    unfolding: Unfolding
    flat_path: Path
    job: Job
    plate: PlateRecord
    result: LoopResult
    comparisons: dict = field(default_factory=dict)
    flat_dxf_path: Path | None = None


def bundled_plate(plate_name: str) -> PointCloud:
    """The bundled hull plate ``plate_name`` (``mppf/examples/hull/NAME.csv``); InputError naming the others."""
    import mppf
    from mppf.geometry.read import read_points

    hull = Path(mppf.__file__).parent / "examples" / "hull"
    design_path = hull / f"{plate_name}.csv"
    if not design_path.exists():
        names = sorted(p.stem for p in hull.glob("*.csv"))
        raise InputError(f"no bundled plate named {plate_name!r}", hint=f"choose one of {', '.join(names)}")
    return read_points(design_path)


def in_process_press(press: PressConfig) -> ContextManager[PressLink]:
    """The demo's default press: :class:`mppf.sim.plc.link.InProcessPress` (instant)."""
    from mppf.sim.plc.link import InProcessPress

    return InProcessPress(press)


def run_demo(out, *, plate_name: str = DEMO_PLATE, seed: int = DEMO_SEED, thickness_mm: float = DEMO_THICKNESS_MM,
             connect: Connect = in_process_press, reporter: Reporter = NULL_REPORTER,
             on_cycle: CycleCallback | None = None, physics: str = "fd") -> DemoRun:
    """Unfold, plan, press, scan, compare and loop on a bundled plate, all simulated.

    Parameters
    ----------
    out : path-like
        Output folder (created): history, plate files, the flat shape.
    plate_name : str
        A bundled hull plate.
    seed : int
        Seed of the simulated plate (its true material) and of its scans.
    thickness_mm : float
    connect : callable
        ``connect(press)``, a context manager giving the press (default: in-process).
    reporter : Reporter
    on_cycle : callable, optional
        As :func:`mppf.loop.cycle.run_loop`.
    physics : str
        The simulated plate: "fd" (the finite-difference steel plate) or "fe" (the CalculiX plate,
        :data:`mppf.sim.shop.PHYSICS`).

    Raises
    ------
    InputError
        Unknown plate, or an output folder that cannot be created.
    """
    from mppf.loop.cycle import run_loop
    from mppf.loop.history import History
    from mppf.loop.options import LoopOptions, PlateInputs
    from mppf.loop.plate import start_plate
    from mppf.model.press import example_press_path, load_press
    from mppf.planning.job import load_job
    from mppf.sim.shop import PHYSICS, SimulatedPlateScanner

    if physics not in PHYSICS:
        raise InputError(f"unknown plate physics {physics!r}", hint=f"use {' or '.join(PHYSICS)}")
    out = Path(out)
    # 1. the design and its flat shape
    design, unfolding, flat = _design_and_flat(out, plate_name, reporter)
    # 2. plan the first cycle (springback pre-compensated) and record the plate
    press = load_press(example_press_path())
    options = LoopOptions(setup={"plc": None, "scanner": "sim", "seed": seed, "physics": physics})
    comparisons, collect = _collector(on_cycle)
    with History(out / "history.sqlite") as history:
        plate_id = f"demo-{plate_name.split('_')[0]}-s{seed}-{time.strftime('%Y%m%d-%H%M%S')}"
        start_plate(history, PlateInputs(design, flat, press, thickness_mm), plate_id=plate_id,
                    work_dir=out / "plates" / plate_id, options=options, reporter=reporter)
        job = load_job(history.cycle(plate_id, 1).job_path)
        dxf = _flat_dxf(out / f"{plate_name}.flat.dxf", plate_name, unfolding, job, press)
        # 3. the loop on the press, the simulated plate and scanner
        scanner = SimulatedPlateScanner.for_job(press, thickness_mm, job, flat.points, seed=seed,
                                                plate_model=PHYSICS[physics])
        with connect(press) as link:
            result = run_loop(history, plate_id, link, scanner, reporter=reporter, on_cycle=collect)
        plate = history.plate(plate_id)
    return DemoRun(out=out, plate_name=plate_name, thickness_mm=thickness_mm, seed=seed, settings=options.settings,
                   unfolding=unfolding, flat_path=flat.path, job=job, plate=plate, result=result,
                   comparisons=comparisons, flat_dxf_path=dxf)


def _design_and_flat(out: Path, plate_name: str, reporter: Reporter):
    """The bundled design, its unfolding and the flat written into ``out`` (created) and read back."""
    from mppf.geometry.read import read_points
    from mppf.geometry.unfold import unfold
    from mppf.geometry.write import write_points

    design = bundled_plate(plate_name)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder {out}: {exc.strerror}") from None
    reporter.info(f"unfolding {plate_name} ({design.n_points} points)")
    unfolding = unfold(design.points)
    flat = read_points(write_points(out / f"{plate_name}.flat.csv", unfolding.flat))
    return design, unfolding, flat


def _collector(on_cycle: CycleCallback | None):
    """A dict of each cycle's comparison (by cycle) and the loop's callback that fills it, then calls ``on_cycle``."""
    comparisons = {}

    def collect(record, comparison):
        if comparison is not None:
            comparisons[record.cycle] = comparison
        if on_cycle is not None:
            on_cycle(record, comparison)

    return comparisons, collect


def _flat_dxf(path: Path, plate_name: str, unfolding: Unfolding, job: Job, press: PressConfig) -> Path:
    """The flat for the cutter as the job lays it on the press (cut and net outlines, the reference mark)."""
    from mppf.geometry.dxf import flat_drawing, write_flat_dxf

    margin = job.layout.margin_mm if job.layout is not None else press.margin_mm
    return write_flat_dxf(path, flat_drawing(unfolding.flat[:, :2], unfolding.faces, margin,
                                             tf_press_flat=job.tf_press_flat,
                                             label=f"{plate_name}, margin {margin:g} mm"))
