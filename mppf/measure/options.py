"""The options of a comparison (:func:`mppf.measure.compare.compare`): one frozen object, checked once.

It lives beside the comparison, not in :mod:`mppf.model`: its defaults are the measure stage's
(:data:`mppf.measure.coverage.GAP_MM`, ...) and its checks the registration's (the rotation hint,
the reference mark, a known start). ``mppf compare`` and the loop build it from the job with
:func:`mppf.measure.job_options.job_compare_options`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mppf.core.defaults import RMS_TOLERANCE_MM, TOLERANCE_MM
from mppf.core.errors import InputError
from mppf.core.validate import check_number, check_positive
from mppf.measure.coverage import GAP_MM, MAX_GAP_MM, check_gaps
from mppf.registration.scan_start import as_mark, as_rotation, known_start

BINS = 30
"""Default histogram bin count (symmetric about 0)."""


@dataclass(frozen=True, eq=False)
class CompareOptions:
    """How a scan is judged against its design. Lengths in mm. Checked once, at construction.

    Attributes
    ----------
    tolerance_mm : float
        Allowed absolute form deviation (> 0). Default
        :data:`mppf.core.defaults.TOLERANCE_MM` (2.5 mm).
    rms_tolerance_mm : float
        Allowed RMS of the measured points' deviations (> 0; the decision rule:
        :func:`mppf.measure.decision.verdict`). Default
        :data:`mppf.core.defaults.RMS_TOLERANCE_MM` (1 mm).
    offset_mm : float
        The skin that was measured, as a normal offset of the design: ``+t/2`` top skin,
        ``0`` mid-surface (the default), ``-t/2`` bottom skin ("top" = +normal side).
    design_faces : (k, 3) int, optional
        Design mesh triangles (a stricter fold-over check of the design).
    punch_xy_mm : (rows, cols, 2) float, optional
        Punch axis positions (x, y) in press coordinates; needs ``tf_press_design``.
    tf_press_design : (4, 4) float, optional
        Maps design into press coordinates (the job's); also orients the normal up.
    bins : int or (b + 1,) float
        Histogram bins: a count (symmetric about 0) or the edges in mm. Default :data:`BINS`.
    punch_radius_mm : float, optional
        Radius around a punch axis whose points give its deviation (> 0; default: 0.45 of
        the punch pitch).
    rotation_hint : (3, 3) or (4, 4) float, optional
        Rough rotation from measured into design coordinates (within about 45 deg); breaks
        a tie of the best two starts only (:func:`mppf.registration.scan_start.choose_start`).
    reference_mark : pair of (3,) float, optional
        ``(measured_xyz, design_xyz)`` of the plate's reference-corner mark: settles the
        half turns of nearly symmetric plates (``docs/compare.md``, "Which way round").
    fit_outline : bool, optional
        Fit the in-plane pose by the outline and the out-of-plane pose by the deviations
        after the ICP (:func:`mppf.registration.outline_fit.refit_outline`). Default (None):
        on when ``punch_xy_mm`` is given, off otherwise (:attr:`outline_fitted`).
    margin_mm : float
        Width (>= 0) of the trim margin the scanned plate still carries around the design's
        outline; its points are measured but left out of every statistic. Default 0.
    punch_label_base : int
        How punches are named in notes: row and column counted from this (the press file's
        ``label_base``). Default 1.
    gap_mm, max_gap_mm : float
        The smallest and the largest allowed gap in the measurement (mm across, > 0,
        ``gap_mm <= max_gap_mm``; :mod:`mppf.measure.coverage`). Defaults
        :data:`~mppf.measure.coverage.GAP_MM`, :data:`~mppf.measure.coverage.MAX_GAP_MM`.
    expected_points : int, optional
        How many points a scan of this plate has (the loop: the previous cycle's); evidence
        that a scan far from its design is this plate, badly formed (:mod:`mppf.measure.same_plate`).
    scan_index : (n,) int, optional
        For a union of scans in one frame: the scan each measured point came from (0 the
        first); a set-aside point another scan re-measured within the tolerance is cleared.
    start_from : Comparison or (4, 4) float, optional
        A start already known (a comparison of a scan in the same frame, or its transform
        measured -> design): the choice of a start is skipped.

    Raises
    ------
    InputError
        A value out of range or of the wrong shape: the message names the option, the value
        seen and what to give.
    """

    tolerance_mm: float = TOLERANCE_MM
    rms_tolerance_mm: float = RMS_TOLERANCE_MM
    offset_mm: float = 0.0
    design_faces: np.ndarray | None = None
    punch_xy_mm: np.ndarray | None = None
    tf_press_design: np.ndarray | None = None
    bins: int | np.ndarray = BINS
    punch_radius_mm: float | None = None
    rotation_hint: np.ndarray | None = None
    reference_mark: tuple | None = None
    fit_outline: bool | None = None
    margin_mm: float = 0.0
    punch_label_base: int = 1
    gap_mm: float = GAP_MM
    max_gap_mm: float = MAX_GAP_MM
    expected_points: int | None = None
    scan_index: np.ndarray | None = None
    start_from: object = field(default=None, repr=False)

    def __post_init__(self):
        put = lambda name, value: object.__setattr__(self, name, value)
        put("tolerance_mm", float(check_positive("tolerance", self.tolerance_mm, unit="mm")))
        put("rms_tolerance_mm", float(check_positive("RMS tolerance", self.rms_tolerance_mm, unit="mm")))
        put("offset_mm", float(check_number("skin offset", self.offset_mm, unit="mm")))
        put("margin_mm", float(check_number(
            "trim margin", self.margin_mm, low=0.0, unit="mm",
            hint="give the width of the excess band around the design outline, 0 for a net plate")))
        gap_mm, max_gap_mm = check_gaps(self.gap_mm, self.max_gap_mm)
        put("gap_mm", gap_mm)
        put("max_gap_mm", max_gap_mm)
        put("punch_label_base", int(check_number("punch label base", self.punch_label_base, integer=True,
                                                 hint="give the press file's label_base (0 or 1)")))
        if self.punch_radius_mm is not None:
            put("punch_radius_mm", float(check_positive("punch radius", self.punch_radius_mm, unit="mm")))
        if self.expected_points is not None:
            put("expected_points", int(check_number("expected point count", self.expected_points, low=1,
                                                    integer=True, hint="give the point count of an earlier scan")))
        self._check_press()
        self._check_start()

    def _check_press(self) -> None:
        """The punch grid and the press pose: shapes, and no grid without the pose."""
        if self.tf_press_design is not None:
            tf = np.asarray(self.tf_press_design, dtype=float)
            if tf.shape != (4, 4) or not np.all(np.isfinite(tf)):
                raise InputError(f"tf_press_design must be a finite 4x4 transform, got shape {tf.shape}",
                                 hint="pass the job's tf_press_design (design -> press)")
            object.__setattr__(self, "tf_press_design", tf)
        if self.punch_xy_mm is not None:
            grid = np.asarray(self.punch_xy_mm, dtype=float)
            if grid.ndim != 3 or grid.shape[2] != 2:
                raise InputError(f"punch positions must have shape (rows, cols, 2), got {grid.shape}",
                                 hint="pass the job's punch grid (x, y of every punch axis, mm)")
            if self.tf_press_design is None:
                raise InputError("punch deviations need tf_press_design (design -> press)",
                                 hint="pass the job's tf_press_design")
            object.__setattr__(self, "punch_xy_mm", grid)
        bins = np.asarray(self.bins)
        if bins.ndim == 0:
            check_number("histogram bins", self.bins, low=1, integer=True, hint="give a bin count, e.g. 30")
        elif bins.ndim != 1 or bins.size < 2 or not np.all(np.diff(bins.astype(float)) > 0):
            raise InputError(f"histogram bin edges must be increasing, at least 2, got {bins!r}",
                             hint="give a bin count or increasing edges in mm")

    def _check_start(self) -> None:
        """The rotation hint, the reference mark, the known start and the scan index: shapes and finite."""
        if self.rotation_hint is not None:
            as_rotation(self.rotation_hint)
        if self.reference_mark is not None:
            as_mark(self.reference_mark)
        if self.start_from is not None:
            known_start(self.start_from)
        if self.scan_index is not None:
            index = np.asarray(self.scan_index)
            if index.ndim != 1 or not np.issubdtype(index.dtype, np.integer) or (index.size and index.min() < 0):
                raise InputError(f"scan_index must be (n,) whole numbers >= 0, got shape {index.shape}, "
                                 f"type {index.dtype}", hint="give the scan (0, 1, ...) of every measured point")

    @property
    def outline_fitted(self) -> bool:
        """Whether the outline fit runs: ``fit_outline``, or by default whether punch positions are given."""
        return self.punch_xy_mm is not None if self.fit_outline is None else bool(self.fit_outline)
