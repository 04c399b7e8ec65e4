"""The uncertainty of a registration per degree of freedom, from the point-to-plane information of its pairs.

``docs/math-registration.md``, section 6. Lengths in mm, turns in degrees.
"""

from __future__ import annotations

import numpy as np

from mppf.registration.icp import UNOBSERVABLE
from mppf.registration.pairs import Pairs
from mppf.registration.target import RegistrationTarget


def uncertainty(target: RegistrationTarget, pairs: Pairs, sigma_mm: float | None = None) -> dict:
    """One-sigma uncertainty per degree of freedom from the point-to-plane information.

    In the target's plate frame (u, v in-plane, n normal): translations in mm, turns
    about the axes in degrees; None where the surface shape does not fix the
    degree of freedom (e.g. sliding along a cylinder). ``observability`` lists the
    normalised eigenvalues of the information matrix (turns scaled by the plate's
    RMS radius), ascending: values near 0 are nearly free directions. Directions below
    ``UNOBSERVABLE`` are held at their start by the ICP step: a degree of freedom lying
    mostly in them is reported as None, the others conditional on them. The noise is
    estimated from the normal residuals unless ``sigma_mm`` is given.
    """
    axes = target.frame.axes
    w = pairs.weight
    local = (pairs.moved - target.frame.origin) @ axes.T
    normal = pairs.normal @ axes.T
    centre = np.average(local, axis=0, weights=w)
    arm = local - centre
    radius = max(float(np.sqrt(np.average((arm[:, :2] ** 2).sum(axis=1), weights=w))), 1e-9)
    jac = np.hstack([normal, np.cross(arm, normal) / radius])
    hess = (jac * w[:, None]).T @ jac
    residual = np.einsum("ij,ij->i", pairs.moved - pairs.matched, pairs.normal)
    dof = max(float(w.sum()) - 6.0, 1.0)
    sigma2 = float((w * residual**2).sum() / dof) if sigma_mm is None else sigma_mm**2
    eigval, eigvec = np.linalg.eigh(hess)
    held = eigval <= UNOBSERVABLE * eigval[-1]  # directions the ICP step holds at their start
    # covariance of what is estimated (conditional on the held directions); a degree of
    # freedom that lies mostly in the held directions is not estimated at all
    inv_diag = (eigvec[:, ~held] ** 2 / eigval[~held]) @ np.ones((~held).sum())
    fixed = (eigvec[:, held] ** 2).sum(axis=1) < 0.5
    std = np.sqrt(sigma2 * inv_diag)
    std[3:] = np.degrees(std[3:] / radius)
    names = ("t_u_mm", "t_v_mm", "t_n_mm", "r_u_deg", "r_v_deg", "r_n_deg")
    out = {name: (float(s) if ok else None) for name, s, ok in zip(names, std, fixed)}
    out["noise_sigma_mm"] = float(np.sqrt(sigma2))
    out["observability"] = [float(v) for v in np.clip(eigval / eigval[-1], 0.0, None)]
    return out
