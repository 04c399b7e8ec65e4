"""Elastic-plastic springback of a bent plate (pure bending, plane strain).

For a plate of thickness ``t`` bent to radius ``R_i`` (loaded), the radius after
unloading ``R_f`` satisfies

    R_i / R_f = 4 x^3 - 3 x + 1,   x = R_i * sy' / (E' * t),

with plane-strain modulus ``E' = E / (1 - nu^2)`` and yield stress ``sy' = 1.155 sy``.
It holds for ``x <= 1/2``, i.e. while the outer fibres yield (strain t / (2 R_i) at
least sy'/E'); at ``x = 1/2`` the ratio is 0 with zero slope, and for ``x >= 1/2`` the
bend is purely elastic and springs back completely (ratio 0). In curvatures, with
``c = sy' / (E' t)``: ``kappa_f = kappa_i - 3 c + 4 c^3 / kappa_i^2`` for
``kappa_i >= 2 c``. See docs/planning.md.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from mppf.model.material import Material

#: x = R sy' / (E' t) at which the outer fibres just reach yield: below it the
#: plate is elastic-plastic through its thickness, above it purely elastic (full springback).
ELASTIC_LIMIT_X = 0.5


def springback_ratio(loaded_radius_mm, thickness_mm: float, material: Material) -> np.ndarray:
    """R_i / R_f for loaded radii R_i (any sign; infinite = flat).

    Parameters
    ----------
    loaded_radius_mm : (...) float
        Radius while loaded; the sign is the bending direction; inf for flat.
    thickness_mm : float
    material : Material

    Returns
    -------
    (...) float
        Ratio in [0, 1]: 1 = no springback, 0 = springs back flat (x >= 1/2).
    """
    radius = np.abs(np.asarray(loaded_radius_mm, dtype=float))
    x = radius * material.plane_strain_yield_mpa / (material.plane_strain_modulus_mpa * thickness_mm)
    xc = np.minimum(x, ELASTIC_LIMIT_X)
    ratio = 4.0 * xc**3 - 3.0 * xc + 1.0
    return np.where(x >= ELASTIC_LIMIT_X, 0.0, np.clip(ratio, 0.0, 1.0))


def unloaded_curvature(loaded_curvature_per_mm, thickness_mm: float, material: Material) -> np.ndarray:
    """Curvature after springback, kappa_f = kappa_i * (R_i / R_f), sign kept.

    Parameters
    ----------
    loaded_curvature_per_mm : (...) float
        Curvature 1/R_i while loaded (signed, 1/mm).
    """
    kappa = np.asarray(loaded_curvature_per_mm, dtype=float)
    safe = np.where(kappa == 0.0, 1.0, kappa)
    radius = np.where(kappa == 0.0, np.inf, 1.0 / safe)
    return kappa * springback_ratio(radius, thickness_mm, material)


def loaded_curvature(target_curvature_per_mm, thickness_mm: float, material: Material) -> np.ndarray:
    """Curvature to bend to so that the plate springs back to the target (pre-compensation).

    Solves kappa_i * ratio(1/kappa_i) = kappa_f for each entry (the over-bend).

    Any non-zero target can be reached: the final curvature rises monotonically from 0
    (at the elastic limit, kappa_i = 2 c) and approaches kappa_i - 3 c for sharp bends.
    """
    target = np.asarray(target_curvature_per_mm, dtype=float)
    out = np.zeros_like(target)
    # kappa_i at x = 1/2 is the elastic limit: below it everything springs back.
    kappa_limit = material.plane_strain_yield_mpa / (
        ELASTIC_LIMIT_X * material.plane_strain_modulus_mpa * thickness_mm
    )

    def final(k):
        return k * springback_ratio(1.0 / k, thickness_mm, material)

    flat = target.reshape(-1)
    res = out.reshape(-1)
    for i, kf in enumerate(flat):
        if kf == 0.0:
            continue
        mag = abs(kf)
        hi = max(2.0 * mag, 2.0 * kappa_limit)
        while final(hi) < mag:
            hi *= 2.0
        lo = kappa_limit
        if final(lo) > mag:
            lo = mag
        res[i] = np.sign(kf) * brentq(lambda k: final(k) - mag, lo, hi, xtol=1e-15, rtol=1e-12)
    return res.reshape(target.shape)
