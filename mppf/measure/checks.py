"""Checks of a comparison's inputs and results: point count, size, match, usable points (GeometryError).

The options are checked when they are built (:class:`mppf.measure.options.CompareOptions`)."""

from __future__ import annotations

import numpy as np

from mppf.core.errors import GeometryError
from mppf.registration.register import Registration

MIN_POINTS = 30
"""Fewest measured points a comparison accepts."""

SIZE_RATIO = (0.3, 1.3)
"""Accepted range of the scan's length (largest in-plane extent) over the design's."""

MATCH_FRACTION = 0.5
"""At least this fraction of the measured points must lie near the design (else: wrong plate)."""


def check_points(measured: np.ndarray) -> None:
    """Raise GeometryError when the scan has fewer than :data:`MIN_POINTS` points."""
    if measured.shape[0] < MIN_POINTS:
        raise GeometryError(f"the scan has {measured.shape[0]} point(s), a comparison needs at least {MIN_POINTS}",
                            hint="check the scan export")


def check_usable(inlier, outlier, dev) -> None:
    """Raise GeometryError when too few measured points are left for the statistics."""
    if inlier.sum() < MIN_POINTS:
        raise GeometryError(f"only {int(inlier.sum())} of {len(inlier)} measured points are usable "
                            f"({int(outlier.sum())} outliers, {int(dev.outside.sum())} outside the design, "
                            f"{int(dev.in_margin.sum())} in the trim margin)",
                            hint="check the scan: it should cover most of the plate")


def check_size(uv_design: np.ndarray, measured_local: np.ndarray, margin_mm: float = 0.0) -> None:
    """Raise GeometryError when the scan's length is out of proportion with the design's.

    ``measured_local`` are the scan's points in its own frame. A scan that still carries
    its trim margin may be up to ``SIZE_RATIO[1]`` times the design's length plus twice the
    margin.
    """
    design_mm = float(np.ptp(uv_design[:, 0]))
    scan_mm = float(np.ptp(measured_local[:, 0]))
    if not SIZE_RATIO[0] * design_mm <= scan_mm <= SIZE_RATIO[1] * (design_mm + 2.0 * margin_mm):
        raise GeometryError(
            f"the scan is {scan_mm:.3g} mm long, the design {design_mm:.0f} mm: not the same plate{_units(scan_mm, design_mm)}",
            hint="check the files and the --units (a scan in metres read as millimetres is 1000 times too small)")


def _units(scan_mm: float, design_mm: float) -> str:
    """"; 1000 times smaller: a scan in metres read as millimetres?" when the lengths differ by a unit's factor."""
    if scan_mm <= 0 or design_mm <= 0:
        return ""
    ratio = design_mm / scan_mm
    for name, factor in (("metres", 1000.0), ("centimetres", 10.0), ("inches", 25.4)):
        for shown, wrong in ((ratio, f"a scan in {name} read as millimetres"),
                             (1.0 / ratio, f"a scan in millimetres read as {name}")):
            if abs(np.log(shown / factor)) < np.log(1.15):
                return f" ({factor:g} times {'smaller' if shown is ratio else 'larger'}: {wrong}? other units)"
    return ""


def gross_mm(tolerance_mm: float, depth_mm: float) -> float:
    """The gross distance: ``max(10 tolerance, 25 mm, depth / 4)`` (a plate within it of its design is near it)."""
    return max(10.0 * tolerance_mm, 25.0, 0.25 * depth_mm)


def check_match(dev, skin, tolerance_mm: float, reg: Registration, expected_points: int | None = None):
    """Raise GeometryError when the scan is evidently of another plate (or in other units, or did not register);
    return the :class:`~mppf.measure.same_plate.Evidence` when it is this plate badly formed, None when it is near
    its design.

    Another plate: more than half of the scan lies beyond the design's edge; or more than
    half lies farther from the design than :func:`gross_mm` and its outline, shape or point
    count says it is not this plate (:mod:`mppf.measure.same_plate`). When they say it is,
    the plate is **badly formed**: judged (out of tolerance), not refused.
    """
    from mppf.measure.same_plate import evidence

    deviation, outside = dev.deviation_mm, dev.outside
    if outside.mean() > 1.0 - MATCH_FRACTION:
        raise GeometryError(
            f"the scan does not match the design: {100 * outside.mean():.0f} % of the measured points lie "
            "outside the design plate after registration",
            hint="check that the scan and the design are of the same plate (and the --units)")
    gross = gross_mm(tolerance_mm, float(np.ptp(skin.design_local[:, 2])))
    near = np.abs(np.where(outside, np.inf, deviation)) <= gross
    if near.sum() >= MATCH_FRACTION * deviation.shape[0]:
        return None
    found = evidence(dev, skin, near, gross, expected_points)
    if not found.same_plate:
        raise GeometryError(
            f"the scan does not match the design: {found.describe()} (registration RMS {reg.rms_mm:.1f} mm): "
            "another plate, or other units",
            hint="check that the scan and the design are of the same plate (and the --units)")
    return found
