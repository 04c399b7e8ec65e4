"""Marks that cannot be missed: a scan counts as complete only with its reference mark, or once it is known not to need one.

The scanner delivers the scan file (:mod:`mppf.loop.scanners`); :class:`MarkedScanner` then
looks for its mark, in the mark file beside it (``<scan>.mark.json``) or in its header
(:func:`mppf.measure.mark.read_scan_mark`), and waits:

- a plate that needs the mark (nearly symmetric: :func:`needs_mark`) waits up to
  ``LoopSettings.mark_timeout_s`` and says so (which file it waits for); with no mark by
  then it stops with :class:`MarkMissing` (exit 4): the cycle stays "pressed", the scan is
  not rejected, and ``mppf loop --resume`` takes the scan again with the mark saved since;
- any other plate waits up to ``LoopSettings.mark_settle_s`` for a mark saved just after
  the scan, then goes on without one and says that the best fit registers the scan.

The comparison reads the mark from the same places (:func:`mppf.measure.mark.reference_mark`),
so the mark found here is the one used. See ``docs/scanner-station.md``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from mppf.core.errors import EXIT_PRESS, InputError, MppfError
from mppf.core.progress import Reporter
from mppf.core.scanner import ScanContext, Scanner
from mppf.measure.mark import mark_path, read_scan_mark

SYMMETRY_FACTOR = 2.0
"""As :data:`mppf.registration.scan_start.SYMMETRY_FACTOR`: a scan tells two turns apart only when the
design misfits itself under the turn by more than this many times the scan's residual."""

MARK_RESIDUAL_MM = 2.0
"""The residual (mm) a scan of a pressed plate is assumed to have at least when deciding whether the
plate needs its mark (a plate's first cycles are typically some mm off; later the largest RMS of the
plate's compared cycles when that is larger)."""

ASYMMETRY_POINTS = 1500
"""Design points fitted onto the design under each half turn (:func:`design_asymmetry_mm`)."""


class MarkMissing(MppfError, TimeoutError):
    """A plate that needs its reference mark got a scan without one within the wait (exit 4).

    The cycle stays "pressed" and the scan is not rejected: ``mppf loop --resume`` takes it
    again, with the mark saved since.
    """

    exit_code = EXIT_PRESS


@dataclass(frozen=True)
class MarkNeed:
    """Whether a plate's scans need the reference mark, and why.

    Attributes
    ----------
    required : bool
        The design is nearly symmetric: a scan without the mark is not compared.
    asymmetry_mm : float
        RMS misfit of the design onto itself under its nearest half turn (mm).
    residual_mm : float
        The scan residual assumed (mm).
    """

    required: bool
    asymmetry_mm: float
    residual_mm: float

    def describe(self) -> str:
        """One line: why the mark is (not) needed."""
        how = "nearly symmetric" if self.required else "not symmetric"
        return (f"the plate is {how}: the design misfits itself by {self.asymmetry_mm:.1f} mm RMS under its nearest "
                f"half turn, against {SYMMETRY_FACTOR:g} x {self.residual_mm:.1f} mm of scan residual")


def design_asymmetry_mm(design_points) -> float:
    """RMS misfit (mm) of the design fitted onto itself from each of its three principal half turns, the least.

    The design test of :func:`mppf.registration.scan_start.start_tie` without a scan: each
    half turn of the design's principal axes is converged by a point-to-plane ICP of a
    sample of the design onto the design; a nearly symmetric plate fits itself almost as well
    turned.

    Parameters
    ----------
    design_points : (n, 3) float, mm
    """
    from mppf.registration.register import register_icp
    from mppf.registration.settings import RegisterOptions
    from mppf.registration.starts import principal_candidates
    from mppf.registration.target import build_target
    from mppf.registration.trust import plane_residuals, sample_index

    target = build_target(design_points, "the design")
    sample = target.points[sample_index(target.n_points, ASYMMETRY_POINTS, seed=3)]
    misfits = []
    for start in principal_candidates(target.frame, target.frame)[1:]:  # the first is no turn
        fit = register_icp(sample, target, RegisterOptions(method="plane", init=start, pin_outline=False,
                           max_points=ASYMMETRY_POINTS, max_iterations=30, check_starts=False))
        misfits.append(float(np.sqrt(np.mean(plane_residuals(target, sample, fit.tf) ** 2))))
    return min(misfits)


def needs_mark(design_points, residual_mm: float = 0.0) -> MarkNeed:
    """Whether scans of this design need the reference mark (:class:`MarkNeed`).

    Required when :func:`design_asymmetry_mm` is below :data:`SYMMETRY_FACTOR` times the
    larger of ``residual_mm`` (e.g. the largest RMS of the plate's compared cycles) and
    :data:`MARK_RESIDUAL_MM`: the comparison could then not tell the plate from its half turn
    (:func:`mppf.registration.scan_start.start_tie`).
    """
    residual = max(float(residual_mm), MARK_RESIDUAL_MM)
    asymmetry = design_asymmetry_mm(design_points)
    return MarkNeed(asymmetry < SYMMETRY_FACTOR * residual, asymmetry, residual)


class MarkedScanner:
    """A :class:`~mppf.core.scanner.Scanner` whose scans count as complete only with their mark (see the module).

    Parameters
    ----------
    scanner : Scanner
        Delivers the scan file.
    need : callable
        ``need() -> MarkNeed``, asked only when a scan came without a mark.
    plausible : callable
        ``plausible(path) -> bool``: whether the scan could be of this plate at all (readable, of
        its size: :func:`plausible_scan`); one that cannot is not waited on (the loop rejects it).
    settle_s : float
        Wait for a mark saved just after the scan, when the plate does not need one (s).
    timeout_s : float
        Longest wait for the mark of a plate that needs one (s).
    poll_s : float
        Interval between looks for the mark (s).
    """

    def __init__(self, scanner: Scanner, need: Callable[[], MarkNeed], plausible: Callable[[Path], bool], *,
                 settle_s: float, timeout_s: float, poll_s: float = 0.25):
        self.scanner, self.folder = scanner, scanner.folder
        self.need = need
        self.plausible = plausible
        self.settle_s = float(settle_s)
        self.timeout_s = float(timeout_s)
        self.poll_s = float(poll_s)

    def rescan(self, cycle: int, number: int, context: ScanContext) -> Path:
        """The scanner's rescan (placed by the first scan's mark: none is waited for)."""
        return self.scanner.rescan(cycle, number, context)

    def acquire(self, cycle: int, context: ScanContext) -> Path:
        """The scanner's scan file, once its mark is there (or known not to be needed)."""
        # 1. the scan file, complete as the scanner judges it (written, size steady)
        path = Path(self.scanner.acquire(cycle, context))
        reporter = context.reporter
        # 2. its mark, in the mark file or the header: then the scan is complete
        if _mark_now(path) is not None:
            reporter.info(f"cycle {cycle}: scan {path.name} with its reference mark ({_where(path)})")
            return path
        # 3. no mark yet: a scan that cannot be of this plate (unreadable, another size) is not waited on (the
        #    loop rejects it at once); a plate that needs the mark waits for it, any other a short settle time
        if not self.plausible(path):
            return path
        need = self.need()
        wait_s = self.timeout_s if need.required else self.settle_s
        if need.required:
            reporter.info(f"cycle {cycle}: waiting for the reference mark of scan {path}: save it as "
                          f"{mark_path(path)} (or a 'reference_mark_mm X Y Z' line in the scan's header); the scan "
                          f"is not compared without it, {need.describe()} (up to {wait_s:.0f} s)")
        if _wait_for_mark(path, wait_s, self.poll_s, reporter, f"waiting for the mark of scan {cycle}"):
            reporter.info(f"cycle {cycle}: reference mark of scan {path.name} came after the scan ({_where(path)})")
            return path
        # 4. none came
        if need.required:
            raise MarkMissing(
                f"no reference mark came for scan {path} of cycle {cycle} within {wait_s:.0f} s: "
                f"{need.describe()}, so the scan is not compared without its mark",
                hint=f"save the mark as {mark_path(path)} (or a 'reference_mark_mm X Y Z' header line) and run "
                     f"'mppf loop --resume --plate-id {context.plate_id}': the same scan is taken again")
        reporter.info(f"cycle {cycle}: no reference mark for scan {path.name} (looked for {mark_path(path).name} "
                      f"and its header for {wait_s:.0f} s): registered by the best fit; {need.describe()}")
        return path


def _mark_now(path: Path):
    """The scan's mark now, or None (a mark file still being written counts as none yet)."""
    try:
        return read_scan_mark(path)
    except InputError:
        return None


def plausible_scan(path, design_points, margin_mm: float = 0.0) -> bool:
    """Whether a scan file could be of the design's plate: it reads as points, and its length passes the
    comparison's size check (:func:`mppf.measure.checks.check_size`: not another plate, not metres read as mm).

    Parameters
    ----------
    path : path-like
        The scan file.
    design_points : (n, 3) float, mm
    margin_mm : float
        The trim margin the scanned plate still carries.
    """
    from mppf.core.errors import GeometryError
    from mppf.geometry.frame import fit_frame
    from mppf.geometry.read import read_points
    from mppf.measure.checks import check_size

    try:
        scan = read_points(path).points
        design = np.asarray(design_points, dtype=float)
        check_size(fit_frame(design).to_local(design)[:, :2], fit_frame(scan).to_local(scan), margin_mm)
    except (InputError, GeometryError):  # GeometryError is an InputError; both named for the reader
        return False
    return True


def _where(path: Path) -> str:
    return f"mark file {mark_path(path).name}" if mark_path(path).is_file() else "scan header"


def _wait_for_mark(path: Path, wait_s: float, poll_s: float, reporter: Reporter, task: str) -> bool:
    """Poll for the scan's mark up to ``wait_s``; True when it came. A mark file left unreadable raises InputError."""
    if wait_s <= 0:
        return False
    start = time.monotonic()
    reporter.start(task, total=wait_s)
    try:
        while time.monotonic() - start < wait_s:
            time.sleep(min(poll_s, max(wait_s - (time.monotonic() - start), 0.0)))
            if _mark_now(path) is not None:
                return True
            reporter.update(time.monotonic() - start)
    finally:
        reporter.finish()
    read_scan_mark(path)  # a mark file there but unreadable: say so (InputError), do not register without it
    return False
