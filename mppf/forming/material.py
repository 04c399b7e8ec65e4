"""Plate material: the elastic and yield constants the planner and the correction use."""

from __future__ import annotations

from mppf.core.validate import check_number
from mppf.model.material import Material

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
