"""Statistics of the inlier deviations: RMS, largest, mean, spread, share within the tolerance, histogram."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import InputError
from mppf.core.validate import check_number


@dataclass(frozen=True, eq=False)
class Statistics:
    """Statistics of deviations (mm) against a tolerance (see :class:`mppf.measure.result.Comparison`)."""

    rms_mm: float
    max_abs_mm: float
    mean_mm: float
    std_mm: float
    within_tolerance_pct: float
    histogram_edges_mm: np.ndarray
    histogram_counts: np.ndarray


def statistics(deviation_mm: np.ndarray, tolerance_mm: float, bins) -> Statistics:
    """Statistics and histogram of deviations (the inliers').

    Parameters
    ----------
    deviation_mm : (k,) float, k >= 1
    tolerance_mm : float
    bins : int or (b + 1,) float
        A count of bins (symmetric about 0, covering the largest deviation and the
        tolerance) or the edges in mm; deviations beyond the edges fall in the end bins.
    """
    d = np.asarray(deviation_mm, dtype=float)
    edges = bin_edges(d, tolerance_mm, bins)
    counts, _ = np.histogram(np.clip(d, edges[0], edges[-1]), bins=edges)
    return Statistics(
        rms_mm=float(np.sqrt(np.mean(d**2))),
        max_abs_mm=float(np.max(np.abs(d))),
        mean_mm=float(np.mean(d)),
        std_mm=float(np.std(d)),
        within_tolerance_pct=float(100.0 * np.mean(np.abs(d) <= tolerance_mm)),
        histogram_edges_mm=edges,
        histogram_counts=counts,
    )


def bin_edges(d: np.ndarray, tolerance_mm: float, bins) -> np.ndarray:
    """Histogram edges (b + 1,) in mm: ``bins`` itself, or that many bins symmetric about 0.

    Raises
    ------
    InputError
        A count below 1, or edges that are not an increasing 1-D array of at least 2 values.
    """
    if np.ndim(bins) == 0:
        count = check_number("histogram bins", bins, low=1, integer=True)
        half = max(float(np.max(np.abs(d))) if d.size else 0.0, tolerance_mm) * 1.05
        return np.linspace(-half, half, count + 1)
    edges = np.asarray(bins, dtype=float)
    if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0):
        raise InputError("histogram edges must be an increasing 1-D array of at least 2 values")
    return edges
