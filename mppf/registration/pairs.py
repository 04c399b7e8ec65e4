"""Matched pairs of an ICP iteration and their weights (trimmed, Huber, Tukey).

:func:`mppf.registration.icp.match` forms the pairs of the moved source and the fixed target;
:func:`pair_weights` weights them. Lengths in mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.defaults import MAD_SCALE

HUBER_K = 1.345
"""Huber threshold in robust scales (95 % efficiency for Gaussian residuals)."""

TUKEY_C = 4.685
"""Tukey biweight cut-off in robust scales (95 % efficiency for Gaussian residuals)."""


@dataclass(frozen=True, eq=False)
class Pairs:
    """Matched pairs at one transform: n source points and their closest target points.

    Attributes
    ----------
    moved, matched : (n, 3) float, mm
        The moved source points and their closest target points.
    index : (n,) int
        The matched target points' indices.
    distance, residual : (n,) float, mm
        Closest-point distance; the residual of the metric (the distance, or along the normal).
    weight : (n,) float
        Pair weights in [0, 1] (:func:`pair_weights`).
    normal : (n, 3) float or None
        Target normals at the matched points (plane metric, or when asked for).
    """

    moved: np.ndarray
    matched: np.ndarray
    index: np.ndarray
    distance: np.ndarray
    residual: np.ndarray
    weight: np.ndarray
    normal: np.ndarray | None

    @property
    def mse(self) -> float:
        """Weighted mean squared residual, mm^2."""
        return float(np.average(self.residual**2, weights=self.weight))

    @property
    def rms_mm(self) -> float:
        """Weighted RMS residual, mm."""
        return float(np.sqrt(self.mse))

    @property
    def inlier_fraction(self) -> float:
        """Fraction of pairs with a non-zero weight."""
        return float(np.count_nonzero(self.weight) / self.weight.size)


def pair_weights(residual: np.ndarray, trim_fraction, robust) -> np.ndarray:
    """Weights of pairs: trimmed (worst fraction dropped) and/or robust (Huber, Tukey).

    The robust scale is 1.4826 times the median absolute residual of the kept pairs.
    """
    a = np.abs(residual)
    w = np.ones_like(a)
    if trim_fraction:
        keep = max(3, int(np.ceil((1.0 - trim_fraction) * a.size)))
        if keep < a.size:
            cutoff = np.partition(a, keep - 1)[keep - 1]
            w[a > cutoff] = 0.0
    if robust:
        scale = MAD_SCALE * float(np.median(a[w > 0]))
        scale = max(scale, 1e-9 * (1.0 + float(a.max())))
        if robust == "huber":
            c = HUBER_K * scale
            w *= np.where(a <= c, 1.0, c / np.maximum(a, c))
        else:
            c = TUKEY_C * scale
            w *= np.where(a < c, (1.0 - (a / c) ** 2) ** 2, 0.0)
    return w
