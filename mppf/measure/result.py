"""The result of a comparison of a scanned plate with its design: statistics, deviations, registration."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mppf.core.transform import tf_to_list
from mppf.geometry.frame import LocalFrame
from mppf.measure.coverage import Coverage
from mppf.measure.decision import Verdict
from mppf.measure.same_plate import Evidence
from mppf.measure.outliers import SetAside
from mppf.registration.register import Registration


@dataclass(frozen=True, eq=False)
class Comparison:
    """The result of :func:`mppf.measure.compare.compare`. Lengths in mm.

    Attributes
    ----------
    rms_mm, max_abs_mm, mean_mm, std_mm : float
        Statistics of the inlier deviations, point by point (scanner noise included).
    form_rms_mm, form_max_abs_mm : float
        The same of the form deviation ("form max"): the plate's deviation with the
        scanner's point noise averaged out by local fits whose scale follows the point
        spacing and the noise (:mod:`mppf.measure.form`); the form max includes extremes
        between points. The decision (:attr:`verdict`) uses the form max: a smooth steel
        plate has no 1 mm bumps 20 mm wide, its scan has (0.3 mm noise gives about +-1.2 mm
        extremes over 15 000 points).
    within_tolerance_pct : float
        Percent of ALL measured points of the net plate (set-aside ones included, outside
        and margin points not) with ``|deviation| <= tolerance_mm``.
    tolerance_mm, offset_mm : float
        As given.
    histogram_edges_mm : (b + 1,) float
    histogram_counts : (b,) int
        Histogram of the inlier deviations.
    transform : (4, 4) float
        Maps measured coordinates into design coordinates.
    registration : Registration
        The ICP report.
    deviation_mm : (n,) float
        Signed normal deviation of every measured point (NaN where the foot point search
        failed).
    inlier : (n,) bool
        Points used in the statistics.
    is_outlier : (n,) bool
        Points set aside as certain scanner artefacts (:mod:`mppf.measure.outliers`).
    is_outside : (n,) bool
        Points whose foot point is outside the design plate (or did not converge).
    measured_in_design : (n, 3) float
        The measured points moved into design coordinates.
    measured_uv_mm : (n, 2) float
        Their foot points' (u, v) in the design's local frame (for maps).
    design_frame : LocalFrame
        The design's local frame (u, v, n rows, as :func:`mppf.geometry.frame.fit_frame` gives it).
    normal_sign : float
        +1 when positive deviations lie on the frame's +n side, -1 when on its -n side
        (the normal was turned to point up in press coordinates).
    design_uv_mm : (m, 2) float
        The design points in that frame (for the outline of maps).
    design_fit_rms_mm : float
        RMS residual of the surface fitted to the design points.
    form_deviation_mm : (n,) float
        The form deviation of every inlier and of every trim-margin point that is not an
        outlier (NaN elsewhere; the margin points' are not in the form statistics).
    punch_deviation_mm : (rows, cols) float or None
        Deviation of the plate at each punch along press z (the stroke direction):
        positive = plate above the design. NaN where the punch is off the plate.
    punch_normal_deviation_mm : (rows, cols) float or None
        The same along the design normal.
    punch_interpolated : (rows, cols) bool or None
        Punches without measured points nearby (occlusion) whose value is interpolated.
    punch_edge_mm : (rows, cols) float or None
        The net plate's measured edge beyond each outer-row punch, along press z
        (:func:`mppf.measure.punches.edge_deviations`); NaN elsewhere. The learned correction
        balances the outer rows against it.
    notes : list of str
    margin_mm : float
        Width of the trim margin (excess band around the design outline), as given.
    in_margin : (n,) bool
        Points whose foot point lies in the trim margin: beyond the design's convex
        outline, within the outline grown by ``margin_mm``. Measured, used for the punch
        deviations, not in the statistics (nor in ``inlier`` or ``is_outside``). All False
        when ``margin_mm`` is 0; default (None given): all False.
    rms_tolerance_mm : float
        The RMS limit of the decision.
    verdict : Verdict or None
        The decision (:func:`mppf.measure.decision.verdict`): kind, headline, figures.
    set_aside : SetAside or None
        The set-aside points as reported (count, largest, where, nearest punch).
    form : dict
        The form deviation's smoothing as used (:meth:`mppf.measure.form.FormField.to_dict`).
    punch_label_base : int
        Punch rows and columns are named from this (1 by default).
    coverage : Coverage or None
        What of the net plate was not measured (:mod:`mppf.measure.coverage`).
    plate_evidence : Evidence or None
        Set when the plate is badly formed: the evidence that a scan far from its design is
        this plate (:mod:`mppf.measure.same_plate`).
    is_cleared : (n,) bool or None
        Set-aside points beyond the tolerance that another scan of the union re-measured within it
        (:func:`mppf.measure.outliers.clear_by_rescans`); default (None given): all False.
    """

    rms_mm: float
    max_abs_mm: float
    mean_mm: float
    std_mm: float
    within_tolerance_pct: float
    tolerance_mm: float
    offset_mm: float
    histogram_edges_mm: np.ndarray
    histogram_counts: np.ndarray
    transform: np.ndarray
    registration: Registration
    deviation_mm: np.ndarray
    inlier: np.ndarray
    is_outlier: np.ndarray
    is_outside: np.ndarray
    measured_in_design: np.ndarray
    measured_uv_mm: np.ndarray
    design_frame: LocalFrame
    normal_sign: float
    design_uv_mm: np.ndarray
    design_fit_rms_mm: float
    form_rms_mm: float = float("nan")
    form_max_abs_mm: float = float("nan")
    form_deviation_mm: np.ndarray | None = None
    punch_deviation_mm: np.ndarray | None = None
    punch_normal_deviation_mm: np.ndarray | None = None
    punch_interpolated: np.ndarray | None = None
    punch_edge_mm: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)
    margin_mm: float = 0.0
    in_margin: np.ndarray | None = None
    rms_tolerance_mm: float = float("nan")
    verdict: Verdict | None = None
    set_aside: SetAside | None = None
    form: dict = field(default_factory=dict)
    punch_label_base: int = 1
    coverage: Coverage | None = None
    plate_evidence: Evidence | None = None
    is_cleared: np.ndarray | None = None

    def __post_init__(self):
        for name in ("in_margin", "is_cleared"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, np.zeros(self.deviation_mm.shape[0], dtype=bool))

    @property
    def n_points(self) -> int:
        """Number of measured points."""
        return int(self.deviation_mm.shape[0])

    @property
    def n_inliers(self) -> int:
        """Points in the statistics."""
        return int(self.inlier.sum())

    @property
    def in_tolerance(self) -> bool:
        """The verdict is "in tolerance" (form max, RMS and set-aside points: :attr:`verdict`)."""
        if self.verdict is None:
            return bool(self.form_max_abs_mm <= self.tolerance_mm)
        return self.verdict.in_tolerance

    @property
    def headline(self) -> str:
        """The verdict and the figures that decided it."""
        if self.verdict is None:
            return f"form max {self.form_max_abs_mm:.2f} mm (tolerance {self.tolerance_mm:g} mm)"
        return self.verdict.headline

    def to_dict(self) -> dict:
        """JSON-able summary: statistics, transform (4x4 lists), histogram, registration, punches."""
        doc = {
            "rms_mm": self.rms_mm,
            "max_abs_mm": self.max_abs_mm,
            "mean_mm": self.mean_mm,
            "std_mm": self.std_mm,
            "within_tolerance_pct": self.within_tolerance_pct,
            "form_rms_mm": self.form_rms_mm,
            "form_max_abs_mm": self.form_max_abs_mm,
            "tolerance_mm": self.tolerance_mm,
            "offset_mm": self.offset_mm,
            "in_tolerance": self.in_tolerance,
            "verdict": None if self.verdict is None else self.verdict.to_dict(),
            "headline": self.headline,
            "rms_tolerance_mm": self.rms_tolerance_mm,
            "set_aside": None if self.set_aside is None else self.set_aside.to_dict(),
            "form": self.form,
            "punch_label_base": self.punch_label_base,
            "coverage": None if self.coverage is None else self.coverage.to_dict(),
            "badly_formed": None if self.plate_evidence is None else self.plate_evidence.to_dict(),
            "n_points": self.n_points,
            "n_inliers": self.n_inliers,
            "n_outliers": int(self.is_outlier.sum()),
            "n_outside": int(self.is_outside.sum()),
            "margin_mm": self.margin_mm,
            "n_margin": int(self.in_margin.sum()),
            "inlier_fraction": self.n_inliers / max(self.n_points, 1),
            "transform": tf_to_list(self.transform),
            "histogram": {"edges_mm": self.histogram_edges_mm.tolist(), "counts": self.histogram_counts.tolist()},
            "design_fit_rms_mm": self.design_fit_rms_mm,
            "registration": self.registration.to_dict(),
            "notes": list(self.notes),
        }
        if self.punch_deviation_mm is not None:
            doc["punch_deviation_mm"] = _nan_to_none(self.punch_deviation_mm)
            doc["punch_normal_deviation_mm"] = _nan_to_none(self.punch_normal_deviation_mm)
            doc["punch_interpolated"] = self.punch_interpolated.tolist()
        if self.punch_edge_mm is not None:
            doc["punch_edge_mm"] = _nan_to_none(self.punch_edge_mm)
        return doc


def _nan_to_none(grid: np.ndarray) -> list:
    return [[None if not np.isfinite(v) else float(v) for v in row] for row in grid]
