"""Plate surfaces z = D(u, v) in the plate's local frame: the protocol and the one-call fit.

Both kinds implement the :class:`Surface` protocol: vectorized values, first and
second derivatives and unit normals, the fitted bounds and the fit residual. Both
evaluate smoothly a little outside their bounds (the planner extends a plate over its
trim allowance). The mathematics is in ``docs/math-surfaces.md``.

- :class:`mppf.geometry.polynomial.PolynomialSurface`: paper eq. (1.1), z = sum a_ij
  s^i t^j for i, j <= k, on centred and scaled coordinates s, t in [-1, 1], solved by
  least squares (QR with column pivoting, never the normal equations of eq. 1.2).
- :class:`mppf.geometry.spline.SplineSurface`: a bicubic least-squares (fixed knots) or
  smoothing B-spline (scipy FITPACK), extended beyond its bounds by its first-order
  Taylor expansion.

:func:`fit_plate` is the one-call entry: frame, height-field check, fit, residual.
Curvatures are in :mod:`mppf.geometry.curvature`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from mppf.core.errors import InputError
from mppf.core.transform import as_points
from mppf.geometry.check import check_plate
from mppf.geometry.frame import LocalFrame, check_height_field, fit_frame
from mppf.geometry.polynomial import DEGREES, fit_polynomial
from mppf.geometry.spline import fit_spline
from mppf.geometry.surface_math import Bounds, residual_stats

KINDS = ("poly", "spline")


@runtime_checkable
class Surface(Protocol):
    """A height field z = D(u, v) in a plate's local frame (all lengths mm).

    Attributes
    ----------
    bounds : ((umin, umax), (vmin, vmax))
        The (u, v) range of the fitted points.
    rms_mm, max_abs_mm : float
        RMS and largest absolute vertical residual of the fit.
    kind : str
        ``"poly"`` or ``"spline"``.
    degree : int
        Polynomial degree k of (k, k), or 3 for the bicubic spline.
    """

    bounds: Bounds
    rms_mm: float
    max_abs_mm: float
    kind: str
    degree: int

    def evaluate(self, u, v) -> np.ndarray:
        """Heights z (mm) at (u, v), arrays of one shape; same shape out."""

    def derivatives(self, u, v) -> tuple[np.ndarray, ...]:
        """(z, zu, zv, zuu, zuv, zvv) at (u, v)."""

    def normals(self, u, v) -> np.ndarray:
        """Unit normals (..., 3) toward +w: (-zu, -zv, 1) / norm."""


@dataclass(frozen=True, eq=False)
class FittedPlate:
    """A plate's local frame and its fitted surface.

    Attributes
    ----------
    frame : LocalFrame
        Best-fit-plane frame; the surface lives in its (u, v, w) coordinates.
    surface : Surface
    residual_mm : (n,) float
        Signed vertical residual w - D(u, v) of each input point.
    rms_mm, max_abs_mm : float
    degree : int
    kind : str
    """

    frame: LocalFrame
    surface: Surface
    residual_mm: np.ndarray
    rms_mm: float
    max_abs_mm: float
    degree: int
    kind: str

    @property
    def n_points(self) -> int:
        """Number of points fitted."""
        return int(self.residual_mm.shape[0])


def fit_plate(points, degree: int | str = 3, kind: str = "poly", smoothing: float | None = None,
              *, faces=None, source: str = "points") -> FittedPlate:
    """Frame, height-field check and surface fit of a plate in one call.

    Parameters
    ----------
    points : (n, 3) float, mm, world (e.g. hull) coordinates
    degree : {2, 3, 4, "auto"}
        Polynomial degree (ignored for splines, which are bicubic).
    kind : {"poly", "spline"}
    smoothing : float, optional
        Spline target RMS in mm (see :func:`fit_spline`).
    faces : (m, 3) int, optional
        Mesh triangles, for an exact fold-over check.
    source : str
        Name for messages (the file name).

    Returns
    -------
    FittedPlate

    Raises
    ------
    InputError
        Unknown kind or degree, or smoothing for a polynomial.
    GeometryError
        Too few, coincident or collinear points; a plate that folds over in its frame.
    """
    if kind not in KINDS:
        raise InputError(f"surface kind must be one of {KINDS}, got {kind!r}")
    if kind == "poly" and smoothing is not None:
        raise InputError(f"smoothing ({smoothing} mm) applies to the spline surface only",
                         hint="use kind 'spline' or leave smoothing out")
    if kind == "poly" and degree not in DEGREES and degree != "auto":
        raise InputError(f"polynomial degree must be one of {DEGREES} or 'auto', got {degree!r}")
    min_points = 16 if kind == "spline" or degree == "auto" else (degree + 1) ** 2
    pts = check_plate(as_points(points, name=source), min_points, source)
    frame = fit_frame(pts)
    check_height_field(frame, pts, faces, source=source)
    u, v, w = frame.to_local(pts).T
    if kind == "poly":
        surface = fit_polynomial(u, v, w, degree=degree)
    else:
        surface = fit_spline(u, v, w, smoothing=smoothing)
    residual = w - surface.evaluate(u, v)
    rms, max_abs = residual_stats(residual)
    return FittedPlate(frame=frame, surface=surface, residual_mm=residual, rms_mm=rms, max_abs_mm=max_abs,
                       degree=surface.degree, kind=surface.kind)
