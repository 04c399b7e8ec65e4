"""The one decision rule of an inspection: in tolerance, out of tolerance, or needs review.

``mppf compare``, the loop (:func:`mppf.loop.decide.decide`) and the reports all decide with
:func:`verdict` (``docs/compare.md``, "The decision"):

- **out of tolerance** when the form maximum (the plate's largest deviation, the scanner's
  point noise averaged out: :mod:`mppf.measure.form`) exceeds the tolerance, or the RMS of
  the measured points exceeds the RMS tolerance, or the plate is **badly formed** (most of
  it farther than the gross distance from its design, but its outline and shape say it is
  this plate: :mod:`mppf.measure.same_plate`; the loop stops there);
- else **needs review** when any point set aside as a scanner artefact
  (:mod:`mppf.measure.outliers`) lies beyond the tolerance (the inspection cannot be sure it
  was an artefact and not the plate) and no other scan of the plate re-measured its spot within
  the tolerance (*cleared*, :func:`mppf.measure.outliers.clear_by_rescans`; cleared points are
  reported, they do not decide; one another scan confirmed, measured so twice, never is),
  or when part of the net plate was not measured: an
  empty gap wider than the allowed gap (:mod:`mppf.measure.coverage`; the plate cannot be
  passed on what was not measured);
- else **in tolerance**.

Every headline quotes the figures that decided, "form max" labelled as such. Lengths in mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.defaults import RMS_TOLERANCE_MM, TOLERANCE_MM
from mppf.core.validate import check_positive

IN_TOLERANCE = "in_tolerance"
OUT_OF_TOLERANCE = "out_of_tolerance"
NEEDS_REVIEW = "needs_review"

REVIEW_ARTEFACTS = "artefacts"
REVIEW_UNCOVERED = "uncovered"
"""The causes of a "needs review" (:attr:`Verdict.review_causes`): set-aside points beyond the tolerance, areas not measured."""

EXIT_IN_TOLERANCE = 0
EXIT_OUT_OF_TOLERANCE = 5
EXIT_NEEDS_REVIEW = 6
EXIT_CODES = {IN_TOLERANCE: EXIT_IN_TOLERANCE, OUT_OF_TOLERANCE: EXIT_OUT_OF_TOLERANCE, NEEDS_REVIEW: EXIT_NEEDS_REVIEW}
"""Exit code of ``mppf compare`` and ``mppf loop`` per verdict: 0 in tolerance, 5 out of tolerance (the loop: not
brought into tolerance, whatever the ending), 6 needs review (README, "Exit codes")."""

LABELS = {IN_TOLERANCE: "IN tolerance", OUT_OF_TOLERANCE: "OUT of tolerance", NEEDS_REVIEW: "NEEDS REVIEW"}
"""How each kind is written in headlines."""


@dataclass(frozen=True)
class Limits:
    """The limits an inspection is judged by (mm)."""

    tolerance_mm: float = TOLERANCE_MM        # largest allowed |form deviation|
    rms_tolerance_mm: float = RMS_TOLERANCE_MM  # largest allowed RMS of the measured points' deviations

    def __post_init__(self):
        check_positive("tolerance", self.tolerance_mm, unit="mm")
        check_positive("RMS tolerance", self.rms_tolerance_mm, unit="mm")


@dataclass(frozen=True)
class Figures:
    """The figures a verdict is taken on (mm).

    Attributes
    ----------
    form_max_mm : float
        Largest absolute form deviation of the net plate.
    rms_mm : float
        RMS of the measured points' deviations (the net plate's inliers).
    set_aside : int
        Points set aside as scanner artefacts.
    set_aside_beyond : int
        How many of them lie beyond the tolerance, not cleared by a rescan (they decide).
    set_aside_max_mm : float
        Their largest absolute deviation (0 when none).
    gaps : tuple of str
        The areas of the net plate not measured (:class:`mppf.measure.coverage.Gap`), in
        words, the largest first (at most three named).
    n_gaps : int
        How many there are.
    allowed_gap_mm : float
        The allowed gap (NaN: coverage not judged).
    badly_formed : str
        Empty, or why a scan far from its design is this plate (badly formed: out of tolerance).
    set_aside_cleared : int
        Set-aside points beyond the tolerance another scan re-measured within it (reported only).
    cleared_by : str
        Which scans cleared them, in words ("cleared by rescan 1 (80)").
    confirmed_beyond : int
        Of ``set_aside_beyond``, those another scan confirmed (measured so twice: cleared only by a scan that shows a
        wall beside them, :func:`mppf.measure.outliers.clear_by_rescans`).
    """

    form_max_mm: float
    rms_mm: float
    set_aside: int = 0
    set_aside_beyond: int = 0
    set_aside_max_mm: float = 0.0
    gaps: tuple = ()
    n_gaps: int = 0
    allowed_gap_mm: float = float("nan")
    badly_formed: str = ""
    set_aside_cleared: int = 0
    cleared_by: str = ""
    confirmed_beyond: int = 0


@dataclass(frozen=True)
class Verdict:
    """The decision on one inspection.

    Attributes
    ----------
    kind : str
        :data:`IN_TOLERANCE`, :data:`OUT_OF_TOLERANCE` or :data:`NEEDS_REVIEW`.
    reasons : tuple of str
        The comparisons of figures with limits that decided, in words.
    figures : Figures
    limits : Limits
    """

    kind: str
    reasons: tuple
    figures: Figures
    limits: Limits

    @property
    def in_tolerance(self) -> bool:
        return self.kind == IN_TOLERANCE

    @property
    def badly_formed(self) -> bool:
        """Out of tolerance because the plate is far from its design (this plate, badly formed)."""
        return bool(self.figures.badly_formed)

    @property
    def review_causes(self) -> tuple[str, ...]:
        """Why the verdict needs review: :data:`REVIEW_ARTEFACTS`, :data:`REVIEW_UNCOVERED`, both, or () (no review)."""
        if self.kind != NEEDS_REVIEW:
            return ()
        f = self.figures
        causes = ((REVIEW_ARTEFACTS, bool(f.set_aside_beyond)), (REVIEW_UNCOVERED, bool(f.n_gaps)))
        return tuple(name for name, present in causes if present)

    @property
    def only_uncovered(self) -> bool:
        """Needs review only because areas of the net plate were not measured (the limits met, no artefact beyond
        the tolerance): measuring those areas again can decide it."""
        return self.review_causes == (REVIEW_UNCOVERED,)

    @property
    def only_rescannable(self) -> bool:
        """Needs review only because of areas not measured and / or set-aside points beyond the tolerance (the
        limits met, not badly formed): a rescan of those areas and spots can decide it."""
        return bool(self.review_causes) and set(self.review_causes) <= {REVIEW_ARTEFACTS, REVIEW_UNCOVERED}

    @property
    def exit_code(self) -> int:
        """The command's exit code for this verdict (:data:`EXIT_CODES`)."""
        return EXIT_CODES[self.kind]

    @property
    def label(self) -> str:
        """"IN tolerance", "OUT of tolerance" or "NEEDS REVIEW"."""
        return LABELS[self.kind]

    @property
    def headline(self) -> str:
        """The verdict and the figures that decided, e.g. "OUT of tolerance: form max 5.10 mm > 2.5 mm"."""
        return f"{self.label}: {'; '.join(self.reasons)}"

    def to_dict(self) -> dict:
        """JSON-able: kind, headline, reasons, the figures and the limits."""
        f, lim = self.figures, self.limits
        return {"kind": self.kind, "headline": self.headline, "reasons": list(self.reasons),
                "form_max_mm": f.form_max_mm, "rms_mm": f.rms_mm, "set_aside": f.set_aside,
                "set_aside_beyond_tolerance": f.set_aside_beyond, "set_aside_max_mm": f.set_aside_max_mm,
                "set_aside_cleared": f.set_aside_cleared, "confirmed_beyond_tolerance": f.confirmed_beyond,
                "uncovered_regions": f.n_gaps, "allowed_gap_mm": f.allowed_gap_mm, "badly_formed": self.badly_formed,
                "tolerance_mm": lim.tolerance_mm, "rms_tolerance_mm": lim.rms_tolerance_mm}


def within_limits(form_max_mm: float, rms_mm: float, limits: Limits) -> bool:
    """Whether the form maximum and the RMS are both within their limits (the measured part of the rule)."""
    return form_max_mm <= limits.tolerance_mm and rms_mm <= limits.rms_tolerance_mm


def verdict(figures: Figures, limits: Limits) -> Verdict:
    """The decision on an inspection (see the module docstring)."""
    f, lim = figures, limits
    form_ok = f.form_max_mm <= lim.tolerance_mm
    rms_ok = f.rms_mm <= lim.rms_tolerance_mm
    form = f"form max {f.form_max_mm:.2f} mm {'<=' if form_ok else '>'} {lim.tolerance_mm:g} mm"
    rms = f"RMS {f.rms_mm:.2f} mm {'<=' if rms_ok else '>'} {lim.rms_tolerance_mm:g} mm"
    if not within_limits(f.form_max_mm, f.rms_mm, lim) or f.badly_formed:
        failed = [text for text, ok in ((form, form_ok), (rms, rms_ok)) if not ok]
        if f.badly_formed:
            failed.insert(0, f"badly formed: {f.badly_formed}")
        return Verdict(OUT_OF_TOLERANCE, tuple(failed), f, lim)
    review = []
    cleared = f"; {f.set_aside_cleared} more {f.cleared_by or 'cleared by a rescan'}" if f.set_aside_cleared else ""
    if f.set_aside_beyond:
        review.append(f"{f.set_aside_beyond} of {f.set_aside} point(s) set aside as scanner artefacts lie beyond "
                      f"{lim.tolerance_mm:g} mm (largest |deviation| {f.set_aside_max_mm:.2f} mm): check them{cleared}")
    if f.confirmed_beyond:
        review.append(f"{f.confirmed_beyond} of them measured so by two scans (confirmed, not cleared): check the "
                      "plate there")
    if f.n_gaps:
        more = f"; and {f.n_gaps - len(f.gaps)} more" if f.n_gaps > len(f.gaps) else ""
        review.append(f"{f.n_gaps} area(s) of the net plate not measured (gaps wider than {f.allowed_gap_mm:.0f} mm): "
                      f"{'; '.join(f.gaps)}{more}: measure them")
    if review:
        return Verdict(NEEDS_REVIEW, (*review, form, rms), f, lim)
    aside = ("no point set aside" if not f.set_aside
             else f"{f.set_aside} point(s) set aside, none beyond {lim.tolerance_mm:g} mm")
    if f.set_aside_cleared:
        aside = (f"{f.set_aside} point(s) set aside, {f.set_aside_cleared} beyond {lim.tolerance_mm:g} mm "
                 f"{f.cleared_by or 'cleared by a rescan'} (re-measured within the tolerance)")
    reasons = (form, rms, aside)
    if np.isfinite(f.allowed_gap_mm):
        reasons += (f"the whole net plate measured (no gap wider than {f.allowed_gap_mm:.0f} mm)",)
    return Verdict(IN_TOLERANCE, reasons, f, lim)
