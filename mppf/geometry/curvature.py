"""Curvatures of a plate surface z = D(u, v) from its fundamental forms."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.geometry.surface import Surface
from mppf.geometry.surface_math import uv_arrays


@dataclass(frozen=True, eq=False)
class Curvatures:
    """Curvatures of z = D(u, v) from its fundamental forms (signs: + bends toward +w).

    Attributes
    ----------
    k1, k2 : (n,) float, 1/mm
        Principal curvatures, k1 >= k2 (positive: concave seen from +w).
    mean, gaussian : (n,) float
        Mean curvature (k1 + k2) / 2 (1/mm), Gaussian curvature k1 k2 (1/mm^2).
    dir1, dir2 : (n, 2) float
        Principal directions as unit (du, dv) in the parameter plane (the 3-D
        direction is du (1, 0, zu) + dv (0, 1, zv)).
    """

    k1: np.ndarray
    k2: np.ndarray
    mean: np.ndarray
    gaussian: np.ndarray
    dir1: np.ndarray
    dir2: np.ndarray


def _principal_direction(e, f, g, l_, m, n_, k) -> np.ndarray:
    """Unit (du, dv) solving (II - k I) d = 0, picking the better-conditioned row."""
    a, b = m - k * f, -(l_ - k * e)  # from row 1: (L - kE) du + (M - kF) dv = 0
    c, d = n_ - k * g, -(m - k * f)  # from row 2: (M - kF) du + (N - kG) dv = 0
    use_first = np.hypot(a, b) >= np.hypot(c, d)
    du = np.where(use_first, a, c)
    dv = np.where(use_first, b, d)
    norm = np.hypot(du, dv)
    umbilic = norm <= 1e-15 * (np.abs(l_) + np.abs(m) + np.abs(n_) + 1e-300)
    du = np.where(umbilic, 1.0, du)
    dv = np.where(umbilic, 0.0, dv)
    return np.column_stack([du, dv]) / np.hypot(du, dv)[:, None]


def curvatures(surface: Surface, u, v) -> Curvatures:
    """Principal, mean and Gaussian curvature at (u, v).

    First fundamental form E = 1 + zu^2, F = zu zv, G = 1 + zv^2; second form with
    the unit normal toward +w: L = zuu / W, M = zuv / W, N = zvv / W, W = sqrt(1 +
    zu^2 + zv^2). K = (LN - M^2) / (EG - F^2), H = (EN - 2FM + GL) / (2 (EG - F^2)),
    k1,2 = H +- sqrt(H^2 - K).

    Parameters
    ----------
    surface : Surface
    u, v : (n,) float, mm

    Returns
    -------
    Curvatures
    """
    u_arr, v_arr = uv_arrays(u, v)
    _, zu, zv, zuu, zuv, zvv = (x.ravel() for x in surface.derivatives(u_arr.ravel(), v_arr.ravel()))
    w = np.sqrt(1.0 + zu * zu + zv * zv)
    e, f, g = 1.0 + zu * zu, zu * zv, 1.0 + zv * zv
    l_, m, n_ = zuu / w, zuv / w, zvv / w
    det = e * g - f * f
    gaussian = (l_ * n_ - m * m) / det
    mean = (e * n_ - 2.0 * f * m + g * l_) / (2.0 * det)
    root = np.sqrt(np.maximum(mean * mean - gaussian, 0.0))
    k1, k2 = mean + root, mean - root
    return Curvatures(
        k1=k1, k2=k2, mean=mean, gaussian=gaussian,
        dir1=_principal_direction(e, f, g, l_, m, n_, k1),
        dir2=_principal_direction(e, f, g, l_, m, n_, k2),
    )


def principal_curvatures(surface: Surface, u, v) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(k1, k2, dir1): principal curvatures (1/mm, k1 >= k2) and the (n, 2) unit (du, dv) of k1.

    See :func:`curvatures` for mean and Gaussian curvature and the second direction.
    """
    c = curvatures(surface, u, v)
    return c.k1, c.k2, c.dir1
