"""Plate material: the elastic and yield constants the planner and the correction use."""

from __future__ import annotations

from dataclasses import dataclass

from mppf.core.errors import InputError


@dataclass(frozen=True)
class Material:
    """Plate material.

    Attributes
    ----------
    youngs_modulus_mpa : float
        E in N/mm^2 (steel: 206000).
    poisson : float
        Poisson's ratio (steel: 0.3).
    yield_stress_mpa : float
        sy in N/mm^2 (mild steel: 235; AH36: 355).
    """

    youngs_modulus_mpa: float = 206000.0
    poisson: float = 0.3
    yield_stress_mpa: float = 235.0

    def __post_init__(self):
        if not self.youngs_modulus_mpa > 0:
            raise InputError(f"Young's modulus must be positive, got {self.youngs_modulus_mpa} MPa")
        if not 0 <= self.poisson < 0.5:
            raise InputError(f"Poisson's ratio must be in [0, 0.5), got {self.poisson}")
        if not self.yield_stress_mpa > 0:
            raise InputError(f"yield stress must be positive, got {self.yield_stress_mpa} MPa")

    @property
    def plane_strain_modulus_mpa(self) -> float:
        """E' = E / (1 - nu^2)."""
        return self.youngs_modulus_mpa / (1.0 - self.poisson**2)

    @property
    def plane_strain_yield_mpa(self) -> float:
        """sy' = 1.155 sy."""
        return 1.155 * self.yield_stress_mpa


MATERIALS = {
    "steel": Material(youngs_modulus_mpa=206000.0, poisson=0.3, yield_stress_mpa=235.0),
    "ah36": Material(youngs_modulus_mpa=206000.0, poisson=0.3, yield_stress_mpa=355.0),
}
"""Named nominal materials (``--material``): mild shipbuilding steel and AH36 high-strength steel."""
