"""The plate model: from punch tips to the plate's shape after springback.

One model of how a plate takes the shape of the punches, used by the planner to
pre-compensate springback (:mod:`mppf.forming.precompensate`, with the NOMINAL material) and by
:mod:`mppf.sim.forming` (with a plate's TRUE, scattered material), the quick formed plate the tests
of the scanner and the comparison sample; the dry runs press the steel or the FE plate
(:class:`mppf.sim.simulated_plate.SimulatedPlate`). The math is in ``docs/compare.md``, section "The simulated plate".

1. **Contact.** At every active punch pair the plate's mid-surface passes midway between
   the lower ball (top at ``lower_mm``) and the upper ball (bottom at ``upper_mm``):
   ``z = (lower + upper) / 2`` on the punch axis (the ball-slope terms cancel in the mean).
2. **Loaded surface** (:func:`loaded_surface`). A thin-plate spline through those
   mid-surface heights: the shape of least bending energy through the contact points,
   which is what an elastic plate held at points takes (in 1-D: the natural cubic
   spline, straight beyond the outer supports).
3. **Springback** (:func:`spring_back`). The loaded surface's curvature tensor (the
   Hessian of its deviation from its best-fit plane, small slopes) has each principal
   curvature ``k_i`` scaled by ``R_i/R_f = 4x^3 - 3x + 1``, ``x = R_i sy'/(E' t)``
   (:func:`mppf.forming.springback.springback_ratio`); the scaled tensor field is integrated back
   to heights (:func:`mppf.core.grid.integrate_hessian`). The unloaded plate keeps the
   loaded plate's best-fit plane.
"""

from __future__ import annotations

import numpy as np

from mppf.core.grid import best_plane, from_principal, hessian, integrate_hessian, plane_values, principal, tps_fill
from mppf.core.polygon import contains
from mppf.model.material import Material
from mppf.forming.springback import springback_ratio

RBF_SMOOTHING = 1e-3
"""Smoothing of the thin-plate spline through the contact heights (0 = interpolate exactly)."""


def grid_axes(outline_xy_mm, spacing_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """x and y axes (mm) of a regular grid covering a polygon with two spacings to spare.

    Parameters
    ----------
    outline_xy_mm : (k, 2) float
    spacing_mm : float

    Returns
    -------
    x_mm : (nx,) float
    y_mm : (ny,) float
    """
    outline = np.asarray(outline_xy_mm, dtype=float)
    lo = outline.min(axis=0) - 2 * spacing_mm
    hi = outline.max(axis=0) + 2 * spacing_mm
    nx = max(int(np.ceil((hi[0] - lo[0]) / spacing_mm)) + 1, 6)
    ny = max(int(np.ceil((hi[1] - lo[1]) / spacing_mm)) + 1, 6)
    return np.linspace(lo[0], hi[0], nx), np.linspace(lo[1], hi[1], ny)


def loaded_surface(xy_contact_mm, z_contact_mm, x_mm, y_mm) -> np.ndarray:
    """Loaded mid-surface heights on a grid: a thin-plate spline through the contact points.

    Parameters
    ----------
    xy_contact_mm : (m, 2) float
        Punch axes holding the plate (press x, y), m >= 3 not in one line.
    z_contact_mm : (m,) float
        Mid-surface height at each axis, ``(lower + upper) / 2``.
    x_mm : (nx,) float
    y_mm : (ny,) float
        Grid axes.

    Returns
    -------
    (ny, nx) float
        Heights, mm.
    """
    gx, gy = np.meshgrid(x_mm, y_mm)
    return tps_fill(xy_contact_mm, z_contact_mm, np.column_stack([gx.ravel(), gy.ravel()]),
                    smoothing=RBF_SMOOTHING).reshape(gx.shape)


def spring_back(x_mm, y_mm, loaded_mm, thickness_mm: float, material: Material,
                outline_xy_mm) -> tuple[np.ndarray, float]:
    """Unloaded heights: the principal curvatures scaled by the springback ratio, re-integrated.

    Parameters
    ----------
    x_mm : (nx,) float
    y_mm : (ny,) float
        Regular grid axes (mm).
    loaded_mm : (ny, nx) float
        Loaded mid-surface heights.
    thickness_mm : float
    material : Material
    outline_xy_mm : (k, 2) float
        The plate's outline; the best-fit planes are taken over it.

    Returns
    -------
    unloaded_mm : (ny, nx) float
        Mid-surface heights after springback.
    mean_ratio : float
        Mean ratio R_i/R_f of the main (largest) curvature over the bent part of the plate.
    """
    gx, gy = np.meshgrid(x_mm, y_mm)
    inside = contains(outline_xy_mm, np.column_stack([gx.ravel(), gy.ravel()]), tolerance_mm=1e-6)
    weight = np.where(inside, 1.0, 1e-3)
    base = plane_values(best_plane(gx, gy, loaded_mm, weight), gx, gy)
    w = loaded_mm - base
    hx = x_mm[1] - x_mm[0]
    hy = y_mm[1] - y_mm[0]
    # curvature tensor (Hessian, small slopes) and its principal decomposition
    kappa, vec = principal(*hessian(w, hx, hy))
    ratio = springback_ratio(np.where(kappa == 0, np.inf, 1.0 / np.where(kappa == 0, 1.0, kappa)),
                             thickness_mm, material)
    scaled = from_principal(kappa * ratio, vec)
    w_unloaded = integrate_hessian(scaled[..., 0, 0], scaled[..., 0, 1], scaled[..., 1, 1], hx, hy)
    # keep the loaded plate's best-fit plane (the unloaded plate rests there)
    w_unloaded -= plane_values(best_plane(gx, gy, w_unloaded, weight), gx, gy)
    main = np.argmax(np.abs(kappa), axis=-1)[..., None]
    main_ratio = np.take_along_axis(ratio, main, axis=-1)[..., 0]
    bent = inside.reshape(gx.shape) & (np.abs(kappa).max(axis=-1) > 1e-9)
    mean_ratio = float(main_ratio[bent].mean()) if bent.any() else 1.0
    return base + w_unloaded, mean_ratio
