"""The correction's through-thickness model: biaxial elastic-plastic bending with memory, point by point.

A point of the plate is bent to the loaded curvature ``k = (k_xx, k_yy, 2 k_xy)`` (1/mm,
the Hessian of the mid-surface height in press x, y with the twist doubled) and released.
Through the thickness (8 Gauss points on the upper half; bending keeps the state odd in z)
the layer strain ``e = z k - e_p`` is returned to the von Mises yield surface of plane
stress with linear isotropic hardening ``sy + H alpha`` (one backward-Euler step from the
point's plastic state, the closest-point projection solved in the basis that diagonalises
the elasticity and the yield function together), the moment is ``M = int s z dz``, and the
release is elastic::

    k_f = k - D^-1 M,        D = t^3 / 12 C   (plane-stress elasticity C)

This is the textbook moment-curvature law of a plate, biaxial: the two curvatures interact
through Poisson's ratio and the yield criterion (a plate held flat across a bend springs
back with an anticlastic curvature; a curvature added across a yielding bend springs back
elastically until the layers yield again), and it keeps the plastic strains, so pressing
less than before changes nothing and un-bending needs reverse bending (plastic memory).
It is the model the correction learns with (:mod:`mppf.correct.learned`); its yield stress and
hardening are fitted to the measured cycles (:mod:`mppf.correct.calibrate`), never given.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LAYERS = 8
"""Gauss points through the upper half thickness."""

RETURN_ITERATIONS = 40
"""Most Newton iterations of the scalar return mapping."""

_XI, _WEIGHT = np.polynomial.legendre.leggauss(LAYERS)
_XI, _WEIGHT = 0.5 * (_XI + 1.0), 0.5 * _WEIGHT  # on (0, 1): z = xi t / 2
_SQ2 = np.sqrt(2.0)
_YIELD_EIGEN = np.array([0.5, 1.5, 3.0])
"""Eigenvalues of the von Mises matrix in the basis ((xx + yy) / sqrt 2, (xx - yy) / sqrt 2, xy)."""


@dataclass(frozen=True, eq=False)
class BendingState:
    """The plastic state of n points: strain (n, layers, 3) (engineering shear) and alpha (n, layers)."""

    plastic_strain: np.ndarray
    alpha: np.ndarray

    @classmethod
    def virgin(cls, n: int) -> BendingState:
        """n points that never yielded."""
        return cls(np.zeros((n, LAYERS, 3)), np.zeros((n, LAYERS)))

    def take(self, index) -> BendingState:
        """The state of some points."""
        return BendingState(self.plastic_strain[index], self.alpha[index])


@dataclass(frozen=True)
class BendingLaw:
    """The through-thickness bending law of one plate.

    Attributes
    ----------
    thickness_mm : float
    youngs_modulus_mpa, poisson : float
    yield_stress_mpa : float
        Initial yield stress (the calibrated, effective one).
    hardening_mpa : float
        Linear hardening modulus H (MPa per unit equivalent plastic strain).
    """

    thickness_mm: float
    youngs_modulus_mpa: float = 206000.0
    poisson: float = 0.3
    yield_stress_mpa: float = 235.0
    hardening_mpa: float = 0.0

    @property
    def elastic_limit_per_mm(self) -> float:
        """Curvature of first yield in plane strain, ``2 sy' / (E' t)`` (1/mm)."""
        nu = self.poisson
        return 2.0 * (2.0 / np.sqrt(3.0)) * self.yield_stress_mpa * (1 - nu * nu) / (self.youngs_modulus_mpa
                                                                                  * self.thickness_mm)

    def moment(self, kappa, state: BendingState) -> tuple[np.ndarray, BendingState]:
        """Moments (n, 3) N mm/mm at loaded curvatures ``kappa`` (n, 3), and the new plastic state."""
        t, stiff = self.thickness_mm, self._stiffness()
        z = _XI * t / 2.0
        strain = z[None, :, None] * np.asarray(kappa, dtype=float)[:, None, :] - state.plastic_strain
        trial = stiff * _to_eigen(strain)
        flow0 = self.yield_stress_mpa + self.hardening_mpa * state.alpha
        yielding = np.sqrt(np.sum(_YIELD_EIGEN * trial**2, axis=-1)) > flow0 * (1.0 + 1e-12)
        dg = np.zeros(state.alpha.shape)
        dg[yielding] = self._return(trial[yielding], flow0[yielding], stiff)  # the elastic layers keep dg = 0
        stress = trial / (1.0 + dg[..., None] * _YIELD_EIGEN * stiff)
        sbar = np.sqrt(np.sum(_YIELD_EIGEN * stress**2, axis=-1))
        new = BendingState(state.plastic_strain + _from_eigen(dg[..., None] * _YIELD_EIGEN * stress),
                           state.alpha + dg * sbar)
        moment = (t * t / 2.0) * np.sum((_WEIGHT * _XI)[None, :, None] * _from_eigen(stress), axis=1)
        return moment, new

    def _stiffness(self) -> np.ndarray:
        """Plane-stress elasticity (3,) MPa in the eigen basis of :data:`_YIELD_EIGEN`."""
        e_mod, nu = self.youngs_modulus_mpa, self.poisson
        return np.array([e_mod / (1 - nu), e_mod / (1 + nu), e_mod / (2 * (1 + nu))])

    def _return(self, trial: np.ndarray, flow0: np.ndarray, stiff: np.ndarray) -> np.ndarray:
        """Plastic multipliers (m,) of the yielding layers: trial stresses (m, 3) MPa (eigen basis), flow (m,) MPa,
        the elasticity ``stiff`` (3,) MPa of :meth:`_stiffness`.

        Newton on the scalar consistency condition ``sbar(dg) = flow0 + H dg sbar(dg)``.
        """
        lam, hard = _YIELD_EIGEN, self.hardening_mpa
        dg = np.zeros(flow0.shape)
        lam2_stiff, trial2 = lam**2 * stiff, trial**2
        for _ in range(RETURN_ITERATIONS):
            q = 1.0 + dg[:, None] * lam * stiff
            sbar = np.sqrt(np.sum(lam * trial2 / q**2, axis=-1))
            dsbar = -np.sum(lam2_stiff * trial2 / q**3, axis=-1) / np.maximum(sbar, 1e-300)
            residual = sbar - flow0 - hard * dg * sbar
            step = -residual / (dsbar - hard * (sbar + dg * dsbar))
            dg = np.maximum(dg + step, 0.0)
            if np.max(np.abs(step) * stiff[0], initial=0.0) < 1e-10:
                break
        return dg

    def press(self, kappa, state: BendingState) -> tuple[np.ndarray, BendingState]:
        """Bend to ``kappa`` (n, 3) and release: the unloaded curvatures (n, 3) and the new state."""
        kappa = np.asarray(kappa, dtype=float)
        moment, new = self.moment(kappa, state)
        return kappa - moment @ self._flexibility().T, new

    def _flexibility(self) -> np.ndarray:
        """D^-1 (3, 3), mm/(N mm): the elastic release of a moment."""
        e_mod, nu, t = self.youngs_modulus_mpa, self.poisson, self.thickness_mm
        c = e_mod / (1 - nu * nu) * np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, 0.5 * (1 - nu)]])
        return np.linalg.inv(t**3 / 12.0 * c)


def _to_eigen(v: np.ndarray) -> np.ndarray:
    """Voigt (xx, yy, xy) -> ((xx + yy) / sqrt 2, (xx - yy) / sqrt 2, xy); its own inverse up to the swap."""
    return np.stack([(v[..., 0] + v[..., 1]) / _SQ2, (v[..., 0] - v[..., 1]) / _SQ2, v[..., 2]], axis=-1)


def _from_eigen(a: np.ndarray) -> np.ndarray:
    return np.stack([(a[..., 0] + a[..., 1]) / _SQ2, (a[..., 0] - a[..., 1]) / _SQ2, a[..., 2]], axis=-1)
