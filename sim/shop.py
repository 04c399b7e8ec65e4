"""The dry-run shop floor: a simulated plate measured by a simulated scanner.

:class:`SimulatedPlateScanner` implements :class:`mppf.core.scanner.Scanner` for dry runs:
for each cycle it forms the simulated plate (:func:`mppf.sim.forming.form_plate`) from
the tip positions the press reported for the cycle's last step (the PLC's actual
positions, read back by the driver), lets it spring back with the plate's true,
seeded material (:func:`mppf.sim.forming.sample_plate`), and scans its top skin with
noise, occlusion, outliers and an arbitrary pose (:class:`mppf.sim.scanner.SimulatedScanner`)
into the plate's work folder. The press side of a dry run is the simulated PLC
(:func:`mppf.sim.plc.run_simulated_plc`) driven over loopback Modbus by the real driver
(``mppf loop`` without ``--plc``, ``mppf demo``), or the in-process press
(:class:`mppf.sim.plc.link.InProcessPress`: the same driver on the PLC program itself, instant).

Each cycle's scan uses its own seed (``seed * 1000 + cycle``), so a scan repeated after a
resume is the same scan.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mppf.core.polygon import convex_outline
from mppf.planning.job import Job, reference_corner_xy
from mppf.core.scanner import ScanContext
from mppf.sim.forming import form_plate, sample_plate
from mppf.sim.scanner import SimulatedScanner
from mppf.forming.material import Material
from mppf.core.transform import apply_tf


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


class SimulatedPlateScanner:
    """A :class:`mppf.core.scanner.Scanner` that forms and scans a simulated plate.

    Parameters
    ----------
    press : PressConfig
    thickness_mm : float
        Nominal thickness; the plate's true one scatters around it.
    outline_xy_mm : (k, 2) float
        The plate's outline on the press (:func:`plate_outline_xy`).
    seed : int
        Seeds the plate's true material and every scan.
    material : Material
        Nominal material.
    noise_mm, occlusion_fraction, outlier_fraction : float
        Scanner imperfections (see :class:`mppf.sim.scanner.SimulatedScanner`).
    suffix : str
        Scan file format (".ply" or ".csv").
    reference_mark : bool
        Pick the plate's reference-corner mark (:func:`mppf.planning.job.reference_corner_xy` of the
        net outline) in every scan and write it next to the scan (``<scan>.mark.json``), as
        the operator does on the shop floor; the scan's pose stays arbitrary.
    net_outline_xy_mm : (j, 2) float, optional
        The net plate's outline (without the trim margin), where the reference corner is
        scribed; default ``outline_xy_mm``.
    """

    def __init__(self, press, thickness_mm: float, outline_xy_mm, *, seed: int = 0,
                 material: Material = Material(), noise_mm: float = 0.3, occlusion_fraction: float = 0.2,
                 outlier_fraction: float = 0.01, suffix: str = ".ply", reference_mark: bool = True,
                 net_outline_xy_mm=None):
        self.press = press
        self.plate = sample_plate(thickness_mm, material, seed)
        self.outline_xy_mm = np.asarray(outline_xy_mm, dtype=float)
        self.seed = int(seed)
        self.noise_mm = noise_mm
        self.occlusion_fraction = occlusion_fraction
        self.outlier_fraction = outlier_fraction
        self.suffix = suffix
        net = self.outline_xy_mm if net_outline_xy_mm is None else np.asarray(net_outline_xy_mm, dtype=float)
        self.mark_xy_mm = reference_corner_xy(net) if reference_mark else None
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

    def acquire(self, cycle: int, context: ScanContext) -> Path:
        """Form the plate from the cycle's last tip positions and scan it into the work folder."""
        context.reporter.info(f"cycle {cycle}: simulated forming and scan")
        formed = form_plate(self.press, context.upper_mm, context.lower_mm, context.active, self.plate,
                            self.outline_xy_mm)
        self.last_formed = formed
        scanner = SimulatedScanner(noise_mm=self.noise_mm, occlusion_fraction=self.occlusion_fraction,
                                   outlier_fraction=self.outlier_fraction, seed=self.seed * 1000 + cycle)
        context.work_dir.mkdir(parents=True, exist_ok=True)
        return scanner.scan(formed, context.work_dir / f"scan-cycle-{cycle:02d}{self.suffix}", self.mark_xy_mm)
