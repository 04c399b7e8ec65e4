"""Plate material: the elastic and yield constants the planner and the correction use."""

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


DEFAULT_YIELD_UNCERTAINTY_PCT = 0.0
"""Declared scatter of the yield stress (+- %) the first press is planned for when the user gives none
(``--yield-uncertainty``). 0: the first press is planned for the nominal yield stress. Under-bending by
5-15 % (a mill certificate's scatter) was measured to cost more presses than it saves with the loop's
correction (benchmarks/results/2026-12-06-loop-first-press.md; docs/planning.md, "The first press
under-bends")."""

MAX_YIELD_UNCERTAINTY_PCT = 50.0
"""Declared yield scatter refused from here on (%): at 50 % the weakest plate of the range has half the
yield stress, a plan for it would hardly compensate springback at all."""


def check_yield_uncertainty(pct, name: str = "the yield-stress uncertainty (--yield-uncertainty)") -> float:
    """The declared yield-stress uncertainty (%) as a float in [0, :data:`MAX_YIELD_UNCERTAINTY_PCT`).

    Raises
    ------
    InputError
        Not a number, NaN, negative, or 50 % and more.
    """
    return float(check_number(name, pct, low=0.0, high=MAX_YIELD_UNCERTAINTY_PCT, high_open=True, unit="%",
                              hint="give the mill certificate's scatter of the yield stress in %, e.g. 10 "
                                   "(0: plan for the nominal yield stress)"))


def weakest_material(material: Material, uncertainty_pct: float) -> Material:
    """The weakest plate of the declared range: yield stress x (1 - ``uncertainty_pct`` / 100).

    It springs back least, so strokes planned for it under-bend every plate within the range
    (:func:`mppf.forming.springback.unloaded_curvature` grows as the yield stress falls).

    Parameters
    ----------
    material : Material
        The nominal material.
    uncertainty_pct : float
        Declared scatter of the yield stress, +- %, in [0, 50).

    Returns
    -------
    Material
        ``material`` with the lowered yield stress (the same object for 0 %).
    """
    pct = check_yield_uncertainty(uncertainty_pct)
    if pct == 0.0:
        return material
    return Material(material.youngs_modulus_mpa, material.poisson, material.yield_stress_mpa * (1.0 - pct / 100.0))
