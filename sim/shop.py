"""The dry-run shop floor: a simulated plate, pressed step by step, measured by a simulated scanner.

:class:`SimulatedPlateScanner` implements :class:`mppf.core.scanner.Scanner` for dry runs.
For each cycle it presses the simulated plate with EVERY step the press did in that cycle,
in order, from the tip positions the press read back (:attr:`mppf.core.scanner.ScanContext.steps`;
a step interrupted during its motion part of the way, :data:`INTERRUPTED_SHARE`), then scans
its top skin with noise, occlusion, outliers and an arbitrary pose
(:class:`mppf.sim.scanner.SimulatedScanner`) into the plate's work folder.

The plate is one of the two simulated plates behind one interface
(:class:`mppf.sim.simulated_plate.SimulatedPlate`): by default the simulated steel plate
(:class:`mppf.sim.plate.plate.SteelPlate`: an elastic-plastic plate in equilibrium between the balls,
plastic memory from step to step and cycle to cycle, press compliance, seeded scatter), written
independently of the planner's plate model; ``plate_model="fe"`` the FE plate
(:class:`mppf.sim.fe.plate.FEPlate`: computed by CalculiX, one ccx run per press step, its restart file in
the state). The plate's state is saved in the work folder after every
cycle (:data:`STATE_FILE`, with the steps it has been pressed with), so a dry run resumed in
another process (``mppf loop --resume``) continues on the same plate and never presses a
step on it twice.

The press side of a dry run is the simulated PLC (:func:`mppf.sim.plc.run_simulated_plc`)
driven over loopback Modbus by the real driver (``mppf loop`` without ``--plc``,
``mppf demo``), or the in-process press (:class:`mppf.sim.plc.link.InProcessPress`).
A plate larger than the bed is pressed section by section: each step of a section carries where the
press's punch axes lie in the plate's frame (``placement_mm`` of the loop's steps, the first section's
press x, y), and the steel plate is shifted there before the step (:meth:`mppf.sim.plate.plate.SteelPlate.place`),
so the plate formed by one section is re-pressed in the overlap by the next; the scan is of the whole plate.
Each cycle's scan uses its own seed (``seed * 1000 + cycle``), so a scan repeated after a
resume is the same scan. A rescan of the cycle (:meth:`SimulatedPlateScanner.rescan`: a fixed
station scans the plate again where it lies) is a new take with its own noise and outliers
(seeded by ``[seed, cycle, rescan]``), in the pose of the cycle's first take: aimed at the areas
the rescan request lists on the press (the station set up for them: seen whole, no occlusion
blobs), else of the whole plate with its own occlusion blobs.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mppf.core.errors import InputError
from mppf.core.polygon import convex_outline
from mppf.core.scanner import PressedStep, ScanContext
from mppf.core.transform import apply_tf
from mppf.model.job import Job
from mppf.model.job_parts import reference_corner_xy
from mppf.model.material import Material
from mppf.sim.scanner import SimulatedScanner
from mppf.sim.simulated_plate import SimulatedPlate

PLATE_MODELS = ("steel", "fe")
"""The simulated plates (:class:`mppf.sim.simulated_plate.SimulatedPlate`): the finite-difference steel plate of
:mod:`mppf.sim.plate`, or the FE plate computed by CalculiX (:mod:`mppf.sim.fe`)."""

PHYSICS = {"fd": "steel", "fe": "fe"}
"""The ``--physics`` choices of the commands and the plate model each one names."""

STATE_FILE = "sim-plate.npz"
"""The simulated plate's state in the plate's work folder."""

INTERRUPTED_SHARE = 0.5
"""Share of its way a step interrupted during its motion took the tips (the PLC halted them)."""


def plate_outline_xy(job: Job, flat_points) -> np.ndarray:
    """The plate's outline in press x, y.

    The layout's ``outline_mm`` (the design seen from above on the press, grown by the
    trim margin the plate is cut with) when the job has it, else the convex hull of the
    flat points placed by ``tf_press_flat``.

    Parameters
    ----------
    job : Job
        Its ``tf_press_flat`` places the flat plate on the press.
    flat_points : (n, 3) float
        The flat plate (flat coordinates, mm).

    Returns
    -------
    (k, 2) float
        Polygon, counter-clockwise, mm.
    """
    if job.layout is not None:
        return job.layout.outline_mm
    return convex_outline(apply_tf(job.tf_press_flat, flat_points)[:, :2], "the flat plate on the press")


@dataclass(frozen=True)
class ShopOptions:
    """The simulated plate and scanner of a :class:`SimulatedPlateScanner`.

    Attributes
    ----------
    material : Material
        Nominal material (the steel plate's nominal steel unless ``steel`` is given).
    plate_model : str
        "steel" (default) or "fe" (:data:`PLATE_MODELS`).
    steel : PlateSteel, optional
        The steel plate's nominal steel (default ``PlateSteel.from_material(material)``):
        a mill's steel differs from the nominal material the planner assumes.
    plate_options : dict, optional
        More keyword arguments of :class:`mppf.sim.plate.plate.SteelPlate` (``scatter``,
        ``compliance``, ``grid_spacing_mm``...), or of :class:`mppf.sim.fe.plate.FEPlate` (``scatter``,
        ``compliance``, ``cells_per_pitch``, ``layers``).
    noise_mm, occlusion_fraction, outlier_fraction : float
        Scanner imperfections (mm; shares of the points; see :class:`mppf.sim.scanner.SimulatedScanner`).
    spacing_mm : float
        The scanner's point spacing on the plate, mm.
    suffix : str
        Scan file format (".ply" or ".csv").
    reference_mark : bool
        Pick the plate's reference-corner mark (:func:`mppf.model.job_parts.reference_corner_xy` of the
        outline as cut, margin included) in every scan and write it next to the scan (``<scan>.mark.json``), as
        the operator does on the shop floor; the scan's pose stays arbitrary.
    """

    material: Material = field(default_factory=Material)
    plate_model: str = "steel"
    steel: Any = None
    plate_options: dict | None = None
    noise_mm: float = 0.3
    occlusion_fraction: float = 0.2
    outlier_fraction: float = 0.01
    spacing_mm: float = 20.0
    suffix: str = ".ply"
    reference_mark: bool = True


class SimulatedPlateScanner:
    """A :class:`mppf.core.scanner.Scanner` that presses and scans a simulated plate.

    Parameters
    ----------
    press : PressConfig
    thickness_mm : float
        Nominal thickness; the plate's true one scatters around it.
    outline_xy_mm : (k, 2) float
        The plate's outline on the press (:func:`plate_outline_xy`).
    seed : int
        Seeds the plate's true properties and every scan.
    net_outline_xy_mm : (j, 2) float, optional
        The net plate's outline (without the trim margin); default ``outline_xy_mm``.
    **options
        The fields of :class:`ShopOptions`: the plate (``material``, ``plate_model``,
        ``steel``, ``plate_options``) and the scanner (``noise_mm``, ``occlusion_fraction``,
        ``outlier_fraction``, ``spacing_mm``, ``suffix``, ``reference_mark``).
    """

    folder = None  # no station folder: its scans are made here (the Scanner protocol)

    def __init__(self, press, thickness_mm: float, outline_xy_mm, *, seed: int = 0, net_outline_xy_mm=None,
                 **options):
        opts = ShopOptions(**options)
        plate_model = opts.plate_model
        if plate_model not in PLATE_MODELS:
            raise InputError(f"unknown simulated plate model {plate_model!r}", hint=f"use {' or '.join(PLATE_MODELS)}")
        if plate_model == "fe":
            from mppf.sim.fe.ccx import find_ccx

            find_ccx()  # without CalculiX: how to install it, before anything is pressed
        self.press = press
        self.thickness_mm = float(thickness_mm)
        self.outline_xy_mm = np.asarray(outline_xy_mm, dtype=float)
        self.seed = int(seed)
        self.material = opts.material
        self.plate_model = plate_model
        self.steel = opts.steel
        self.plate_options = dict(opts.plate_options or {})
        self.noise_mm = opts.noise_mm
        self.occlusion_fraction = opts.occlusion_fraction
        self.outlier_fraction = opts.outlier_fraction
        self.spacing_mm = float(opts.spacing_mm)
        self.suffix = opts.suffix
        self.net_outline_xy_mm = (self.outline_xy_mm if net_outline_xy_mm is None
                                  else np.asarray(net_outline_xy_mm, dtype=float))
        # the mark is on the corner of the plate as cut (mppf.model.job_parts.PlateLayout.reference_corner_mm)
        self.mark_xy_mm = reference_corner_xy(self.outline_xy_mm) if opts.reference_mark else None
        self.plate = self.new_plate()
        self.pressed: list[list[int]] = []  # (cycle, step) pressed on self.plate, in order
        self.last_formed = None

    @classmethod
    def for_job(cls, press, thickness_mm: float, job: Job, flat_points, **options) -> SimulatedPlateScanner:
        """The scanner of a job's plate: the plate as cut (trim margin included) and its net outline.

        Parameters
        ----------
        press : PressConfig
        thickness_mm : float
            Nominal thickness.
        job : Job
            The plate's (first) job.
        flat_points : (n, 3) float
            The flat plate, flat coordinates (mm).
        **options
            Further keyword arguments of the constructor (``seed``, ``material``...).
        """
        net = None if job.layout is None else job.layout.net_outline_mm
        return cls(press, thickness_mm, plate_outline_xy(job, flat_points), net_outline_xy_mm=net, **options)

    def new_plate(self) -> SimulatedPlate:
        """The flat plate before its first step (its true properties drawn from the seed)."""
        from mppf.sim.plate.material import PlateSteel

        steel = PlateSteel.from_material(self.material) if self.steel is None else self.steel
        if self.plate_model == "fe":
            from mppf.sim.fe.plate import FEPlate

            return FEPlate(self.press, self.outline_xy_mm, self.thickness_mm, steel, seed=self.seed,
                           **self.plate_options)
        from mppf.sim.plate.plate import SteelPlate

        return SteelPlate(self.press, self.outline_xy_mm, self.thickness_mm, steel, seed=self.seed,
                          **self.plate_options)

    def acquire(self, cycle: int, context: ScanContext, path=None) -> Path:
        """Press the plate with the cycle's steps (each once, in order) and scan it into the work folder (or to
        ``path``; its mark beside it, ``<path>.mark.json``)."""
        context.reporter.info(f"cycle {cycle}: simulated forming and scan")
        formed = self._formed(cycle, context)
        return self.scan_formed(cycle, formed, path or context.work_dir / f"scan-cycle-{cycle:02d}{self.suffix}")

    def scan_formed(self, cycle: int, formed, path) -> Path:
        """The cycle's first take of ``formed`` written to ``path`` (its mark beside it, when marks are picked)."""
        return self._take(cycle).scan(formed, path, self.mark_xy_mm)

    def rescan(self, cycle: int, number: int, context: ScanContext, path=None) -> Path:
        """The plate of the cycle scanned again where it lies, in the pose of the cycle's first take, without a
        mark (the first take's places it): its own noise and outliers (seeded by ``[seed, cycle, number]``).

        Aimed at the request's areas where it lists them on the press (``context.regions``' corners): the
        station is set up for them, so they are seen whole (no occlusion blobs); else the whole plate again,
        with its own occlusion blobs. Written into the work folder, or to ``path``.
        """
        context.reporter.info(f"cycle {cycle}: simulated rescan {number}")
        formed = self._formed(cycle, context)
        pose = self._take(cycle).sample(formed, self.mark_xy_mm).tf_scan_press  # the first take, drawn again
        aim = [r["corners_press_mm"] for r in context.regions if r.get("corners_press_mm")]
        take = SimulatedScanner(noise_mm=self.noise_mm, occlusion_fraction=0.0 if aim else self.occlusion_fraction,
                                outlier_fraction=self.outlier_fraction, spacing_mm=self.spacing_mm,
                                seed=[self.seed, int(cycle), int(number)])
        path = path or context.work_dir / f"scan-cycle-{cycle:02d}-rescan-{number}{self.suffix}"
        return take.scan(formed, path, tf_scan_press=pose, aim_xy_mm=aim)

    def _take(self, cycle: int) -> SimulatedScanner:
        """The scanner of the cycle's first take (its seed)."""
        return SimulatedScanner(noise_mm=self.noise_mm, occlusion_fraction=self.occlusion_fraction,
                                outlier_fraction=self.outlier_fraction, spacing_mm=self.spacing_mm,
                                seed=self.seed * 1000 + cycle)

    def _formed(self, cycle: int, context: ScanContext):
        """The plate pressed with every step of the cycle not yet pressed on it (its state saved)."""
        context.work_dir.mkdir(parents=True, exist_ok=True)
        state_path = context.work_dir / STATE_FILE
        # 1. the plate as the last run left it (another process, after a crash)
        self.restore(state_path)
        if hasattr(self.plate, "progress"):  # the FE plate: ccx's progress lines to the operator
            self.plate.progress = context.reporter.info
        # 2. press every step of the cycle not yet pressed on it, in order
        steps = context.steps or (PressedStep(cycle, 1, context.upper_mm, context.lower_mm, context.active),)
        for step in steps:
            if [step.cycle, step.step] not in self.pressed:
                self._press(step)
        self._save(state_path)
        self.last_formed = self.plate.formed
        return self.last_formed

    def _press(self, step: PressedStep) -> None:
        """One step on the plate; an interrupted one takes the tips :data:`INTERRUPTED_SHARE` of the way.

        A step of a section of a plate larger than the bed carries ``placement_mm``, where the press's punch
        axes lie in the plate's frame (the first section's press x, y): the plate is shifted there first.
        """
        placement = getattr(step, "placement_mm", None)
        self.plate.place((0.0, 0.0) if placement is None else placement)  # the FE plate refuses a later section
        share = 1.0 if step.complete else INTERRUPTED_SHARE
        self.plate.press_step(step.upper_mm, step.lower_mm, step.active, share=share)
        self.pressed.append([int(step.cycle), int(step.step)])

    def _save(self, path: Path) -> None:
        """The plate's state and the steps pressed on it, written atomically."""
        state = self.plate.state_dict()
        state["pressed_json"] = json.dumps(self.pressed)
        partial = path.with_name(path.name + ".part.npz")
        np.savez(partial, **state)
        os.replace(partial, path)

    def restore(self, path: Path) -> None:
        """Take the saved plate when it has been pressed with more than the plate in memory."""
        if not path.exists():
            return
        with np.load(path) as saved:
            pressed = json.loads(str(saved["pressed_json"]))
            if pressed == self.pressed:
                return
            state = {name: saved[name] for name in saved.files if name != "pressed_json"}
        self.plate = type(self.plate).from_state(state)
        self.pressed = pressed
