"""Is it this plate? A badly formed plate is not a wrong plate.

After the registration, a scan of which fewer than half the points lie within the gross
distance of the design (:func:`mppf.measure.checks.gross_mm`) is either **another plate or
other units**, or **this plate, far out of tolerance** (a correction that went wrong, a job
cut short). The plate as cut tells them apart (``docs/compare.md``, "Another plate, or this
plate badly formed"). It is this plate when all of these hold:

1. **Outline:** the scan's extent along the design's u and v axes (the 0.5 - 99.5 %
   quantiles of its points' foot points) is within :data:`EXTENT_RATIO` of the design's
   (grown by the trim margin): the cut plate does not change size when it is formed wrong;
2. **Shape:** the scan's heights over the design plane correlate with the design's (both
   without their best plane; correlation at least :data:`MIN_CORRELATION`), when the
   design is curved at all (height RMS at least :data:`CURVED_MM`): a wrongly formed plate
   is still bent the design's way, over or under;
3. **Point count** (when an expected count is given, e.g. the previous cycle's scan): within
   :data:`COUNT_RATIO` of it.

The scale check before the registration (:func:`mppf.measure.checks.check_size`) has already
refused a scan in other units (1000 or 25.4 times off). Lengths in mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.grid import without_plane

EXTENT_RATIO = (0.85, 1.05)
"""Accepted range of the scan's extent over the design's, along u and along v."""

MIN_CORRELATION = 0.5
"""Smallest correlation of the scan's heights with the design's (both without their best plane)."""

CURVED_MM = 5.0
"""A design whose heights scatter less than this (RMS, without the best plane) is flat: no shape evidence."""

COUNT_RATIO = (0.5, 2.0)
"""Accepted range of the scan's point count over the expected one."""

QUANTILE = 0.005
"""The scan's extent is between these quantiles of its foot points (a stray point does not widen it)."""

SAMPLE = 20000
"""Points (a seeded sample) the shape correlation is computed on."""


@dataclass(frozen=True)
class Evidence:
    """What says whether a scan far from its design is of this plate.

    Attributes
    ----------
    within_pct : float
        Percent of the scan's points within ``gross_mm`` of the design.
    gross_mm : float
    extent_mm, design_extent_mm : tuple of 2 float
        The scan's and the design's (grown by the margin) extents along u and v.
    correlation : float or None
        Of the heights; None for a flat design.
    points : int
    expected_points : int or None
    """

    within_pct: float
    gross_mm: float
    extent_mm: tuple
    design_extent_mm: tuple
    correlation: float | None
    points: int
    expected_points: int | None = None

    @property
    def outline_matches(self) -> bool:
        ratio = np.asarray(self.extent_mm) / np.maximum(np.asarray(self.design_extent_mm), 1e-9)
        return bool(np.all((ratio >= EXTENT_RATIO[0]) & (ratio <= EXTENT_RATIO[1])))

    @property
    def shape_matches(self) -> bool:
        return self.correlation is None or self.correlation >= MIN_CORRELATION

    @property
    def count_matches(self) -> bool:
        if not self.expected_points:
            return True
        ratio = self.points / self.expected_points
        return COUNT_RATIO[0] <= ratio <= COUNT_RATIO[1]

    @property
    def same_plate(self) -> bool:
        """Outline, shape and point count all say: this plate."""
        return self.outline_matches and self.shape_matches and self.count_matches

    def describe(self) -> str:
        """The evidence in words."""
        (su, sv), (du, dv) = self.extent_mm, self.design_extent_mm
        shape = ("the design is flat (no shape evidence)" if self.correlation is None
                 else f"shape correlation with the design {self.correlation:.2f} (at least {MIN_CORRELATION:g})")
        text = (f"only {self.within_pct:.0f} % of the points lie within {self.gross_mm:.0f} mm of the design; "
                f"the scan's outline is {su:.0f} x {sv:.0f} mm against the design's {du:.0f} x {dv:.0f} mm "
                f"({'matches' if self.outline_matches else 'does not match'}), {shape}")
        if self.expected_points:
            text += f", {self.points} points against {self.expected_points} expected"
        return text

    def to_dict(self) -> dict:
        return {"within_pct": self.within_pct, "gross_mm": self.gross_mm, "extent_mm": list(self.extent_mm),
                "design_extent_mm": list(self.design_extent_mm), "correlation": self.correlation,
                "points": self.points, "expected_points": self.expected_points, "same_plate": self.same_plate}


def evidence(dev, skin, near: np.ndarray, gross_mm: float, expected_points: int | None = None) -> Evidence:
    """The evidence (see the module docstring) of a scan's deviations.

    Parameters
    ----------
    dev : mppf.measure.deviations.Deviation
    skin : mppf.measure.deviations.DesignSkin
    near : (n,) bool
        The points within ``gross_mm`` of the design.
    gross_mm : float
    expected_points : int, optional
    """
    ok = ~dev.outside
    uv = dev.uv[ok]
    extent = tuple(float(v) for v in np.quantile(uv, 1 - QUANTILE, axis=0) - np.quantile(uv, QUANTILE, axis=0))
    design_extent = tuple(float(v) for v in np.ptp(skin.grown, axis=0))
    return Evidence(100.0 * float(near.mean()), float(gross_mm), extent, design_extent,
                    _correlation(dev, skin, ok), int(dev.deviation_mm.shape[0]), expected_points)


def _correlation(dev, skin, ok: np.ndarray) -> float | None:
    """Correlation of the scan's heights in the design frame with the design's at the same (u, v), both without
    their best plane; None when the design is flat."""
    rows = np.flatnonzero(ok)
    if rows.size > SAMPLE:
        rows = np.sort(np.random.default_rng(0).choice(rows, SAMPLE, replace=False))
    uv = dev.uv[rows]
    measured = skin.frame.to_local(dev.moved[rows])[:, 2]
    design = skin.fitted.surface.evaluate(uv[:, 0], uv[:, 1])
    design = without_plane(uv[:, 0], uv[:, 1], design)
    if float(np.sqrt(np.mean(design**2))) < CURVED_MM:
        return None
    measured = without_plane(uv[:, 0], uv[:, 1], measured)
    scale = float(np.sqrt(np.sum(design**2) * np.sum(measured**2)))
    return float(np.sum(design * measured) / scale) if scale > 0 else 0.0
