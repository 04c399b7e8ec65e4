"""Plate material: the elastic and yield constants the planner and the correction use (shared data: the
job's plate layout records it; :mod:`mppf.forming.material` re-exports it)."""

from __future__ import annotations

from dataclasses import dataclass

from mppf.core.validate import check_number, check_positive


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
        checked = {"youngs_modulus_mpa": check_positive("Young's modulus", self.youngs_modulus_mpa, unit="MPa"),
                   "poisson": check_number("Poisson's ratio", self.poisson, low=0.0, high=0.5, high_open=True),
                   "yield_stress_mpa": check_positive("the yield stress", self.yield_stress_mpa, unit="MPa")}
        for name, value in checked.items():
            object.__setattr__(self, name, float(value))

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
