"""The steel of the simulated plate: elasticity, Hill 1948 yield, isotropic strain hardening.

Plane stress, in the plate's grid frame (u along the plate's long edge, v across it).
Vectors are Voigt vectors: stress ``(s_uu, s_vv, s_uv)`` in MPa, strain
``(e_uu, e_vv, g_uv)`` with the engineering shear ``g_uv = 2 e_uv``.

Yield (Hill 1948, plane stress, in the material axes 1 = rolling direction, 2 = across)::

    f(s) = sqrt(s^T P s) - sy(alpha) <= 0,
    s^T P s = (G + H) s11^2 - 2 H s11 s22 + (F + H) s22^2 + 2 N s12^2

with ``G + H = 1`` (the reference stress is the yield stress along the rolling
direction), ``H = G = 1/2``, ``F + H = 1 / r90^2`` (``r90`` = yield across / along the
rolling direction) and ``N`` such that the 45-degree yield stress is the mean of the two.
``r90 = 1`` gives von Mises (``F = G = H = 1/2``, ``N = 3/2``). ``P`` is rotated into the
grid frame by the rolling angle.

Hardening (isotropic, in the equivalent plastic strain ``alpha``)::

    sy(alpha) = f_y * sy0 * (1 + alpha / e0)^n + H_lin * alpha

(Swift with a linear term; ``n = 0`` gives linear hardening, ``n = 0, H_lin = 0``
elastic-perfectly-plastic). ``f_y`` is the local yield factor of the plate's scatter.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from mppf.core.validate import check_number, check_positive

STEEL_DENSITY_KG_MM3 = 7.85e-6
"""Density of steel, kg/mm^3."""

GRAVITY_MM_S2 = 9810.0
"""Standard gravity, mm/s^2."""


@dataclass(frozen=True)
class PlateSteel:
    """Constants of a plate steel (nominal or one plate's true values).

    Attributes
    ----------
    youngs_modulus_mpa : float
        E, MPa.
    poisson : float
        Poisson's ratio.
    yield_stress_mpa : float
        Initial uniaxial yield stress along the rolling direction, MPa.
    swift_exponent : float
        n of the Swift term (0: no Swift hardening).
    swift_strain : float
        e0 of the Swift term (equivalent plastic strain, > 0).
    linear_hardening_mpa : float
        H_lin, slope of the linear hardening term, MPa.
    transverse_yield_ratio : float
        Yield stress across the rolling direction / along it (Hill 48); 1 = von Mises.
    rolling_angle_deg : float
        Rolling direction, counter-clockwise from the plate's long edge (grid u axis), degrees.
    density_kg_mm3 : float
        Density (the plate's weight while it lies on the punches), kg/mm^3.
    """

    youngs_modulus_mpa: float = 206000.0
    poisson: float = 0.3
    yield_stress_mpa: float = 235.0
    swift_exponent: float = 0.1
    swift_strain: float = 0.01
    linear_hardening_mpa: float = 0.0
    transverse_yield_ratio: float = 1.05
    rolling_angle_deg: float = 0.0
    density_kg_mm3: float = STEEL_DENSITY_KG_MM3

    def __post_init__(self):
        check_positive("Young's modulus", self.youngs_modulus_mpa, unit="MPa")
        check_number("Poisson's ratio", self.poisson, low=0.0, high=0.5, high_open=True)
        check_positive("yield stress", self.yield_stress_mpa, unit="MPa")
        check_number("Swift exponent", self.swift_exponent, low=0.0, high=1.0)
        check_positive("Swift strain", self.swift_strain)
        check_number("linear hardening", self.linear_hardening_mpa, low=0.0, unit="MPa")
        check_number("transverse yield ratio", self.transverse_yield_ratio, low=0.7, high=1.4)
        check_number("rolling angle", self.rolling_angle_deg, low=-360.0, high=360.0, unit="deg")
        check_number("density", self.density_kg_mm3, low=0.0, unit="kg/mm^3")

    @classmethod
    def from_material(cls, material, **changes) -> PlateSteel:
        """The steel with E, nu and the yield stress of a :class:`mppf.model.material.Material`.

        Parameters
        ----------
        material : Material
        **changes
            Further attributes to set (``swift_exponent=0``...).
        """
        base = cls(youngs_modulus_mpa=material.youngs_modulus_mpa, poisson=material.poisson,
                   yield_stress_mpa=material.yield_stress_mpa)
        return replace(base, **changes)

    @property
    def plane_strain_modulus_mpa(self) -> float:
        """E' = E / (1 - nu^2), MPa."""
        return self.youngs_modulus_mpa / (1.0 - self.poisson**2)

    def elastic_matrix(self) -> np.ndarray:
        """Plane-stress elasticity (3, 3), MPa: stress = C @ (e_uu, e_vv, g_uv)."""
        e, nu = self.youngs_modulus_mpa, self.poisson
        return e / (1.0 - nu * nu) * np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, 0.5 * (1.0 - nu)]])

    def hill_matrix(self) -> np.ndarray:
        """Hill 48 matrix P (3, 3) in the grid frame: equivalent stress^2 = s^T P s."""
        r90 = self.transverse_yield_ratio
        h = g = 0.5
        f = 1.0 / r90**2 - h
        r45 = 0.5 * (1.0 + r90)
        n = 0.5 * (4.0 / r45**2 - f - g)
        p_material = np.array([[g + h, -h, 0.0], [-h, f + h, 0.0], [0.0, 0.0, 2.0 * n]])
        a = np.radians(self.rolling_angle_deg)
        c, s = np.cos(a), np.sin(a)
        # stress in the material axes = t @ stress in the grid frame (tensor shear)
        t = np.array([[c * c, s * s, 2 * c * s], [s * s, c * c, -2 * c * s], [-c * s, c * s, c * c - s * s]])
        return t.T @ p_material @ t

    def flow_stress_mpa(self, alpha, yield_factor) -> tuple[np.ndarray, np.ndarray]:
        """Yield stress and its slope at equivalent plastic strains ``alpha``.

        Parameters
        ----------
        alpha : (...) float
            Equivalent plastic strain (>= 0).
        yield_factor : (...) float, broadcastable
            Local factor on the initial yield stress (scatter).

        Returns
        -------
        stress_mpa, slope_mpa : (...) float
        """
        sy0 = self.yield_stress_mpa * np.asarray(yield_factor, dtype=float)
        n, e0 = self.swift_exponent, self.swift_strain
        base = 1.0 + np.asarray(alpha, dtype=float) / e0
        swift = base**n
        stress = sy0 * swift + self.linear_hardening_mpa * alpha
        slope = sy0 * n / e0 * swift / base + self.linear_hardening_mpa
        return stress, slope
