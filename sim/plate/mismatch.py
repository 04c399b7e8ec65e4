"""A simulated plate that answers differently from the planner's model: model mismatch by factors.

The loop's correction is meant for plates nobody modelled. To judge it on physics it has not
seen, the steel plate of :mod:`mppf.sim.plate` can be made to differ from the nominal plate the
planner and the correction assume, one effect at a time or together, each by a factor:

- ``yield_factor``: the yield stress (the elastic-limit curvature moves with it; near the
  elastic limit a few per cent change the formed shape by centimetres);
- ``hardening_factor``: the Swift exponent and the linear hardening slope;
- ``compliance_factor``: the press frame's and the punches' give;
- ``anisotropy_factor``: the departure of the transverse yield ratio from 1
  (``r90 = 1 + f (r90 - 1)``);
- ``edge_factor``: the yield stress in a band of ``edge_band_mm`` along the plate's edges (an
  edge that resists bending more or less than the interior: flame-cut hardening, a rolled
  edge);
- ``response_factor``: the permanent shape change of every press step after the first
  ``response_after_steps`` (the first cycle's: then the first press is as modelled and every
  correction moves the plate ``f`` times what the model predicts, mode by mode alike; 0: the
  whole shape about the flat plate).

:func:`mismatched_parts` turns a :class:`Mismatch` into the steel, the compliance and the
plate options of :class:`mppf.sim.plate.plate.SteelPlate`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from mppf.core.validate import check_number
from mppf.sim.plate.contact import Compliance
from mppf.sim.plate.material import PlateSteel

FACTOR_RANGE = (0.05, 20.0)
"""Accepted range of each factor."""

EDGE_BAND_MM = 150.0
"""Default width of the edge band of ``edge_factor`` (mm)."""


@dataclass(frozen=True)
class Mismatch:
    """Factors by which the simulated plate differs from the nominal one (1: as nominal).

    Attributes
    ----------
    yield_factor, hardening_factor, compliance_factor, anisotropy_factor, edge_factor, response_factor : float
        See the module docstring.
    edge_band_mm : float
        Width of the edge band of ``edge_factor`` (mm).
    response_after_steps : int
        Steps pressed as modelled before ``response_factor`` applies.
    """

    yield_factor: float = 1.0
    hardening_factor: float = 1.0
    compliance_factor: float = 1.0
    anisotropy_factor: float = 1.0
    edge_factor: float = 1.0
    response_factor: float = 1.0
    edge_band_mm: float = EDGE_BAND_MM
    response_after_steps: int = 0

    def __post_init__(self):
        low, high = FACTOR_RANGE
        for name, value in asdict(self).items():
            if name == "response_after_steps":
                check_number("steps before the response factor", value, low=0, integer=True)
            elif name == "edge_band_mm":
                check_number("edge band", value, low=0.0, unit="mm")
            else:  # anisotropy 0: an isotropic plate
                check_number(f"mismatch {name}", value, low=0.0 if name == "anisotropy_factor" else low, high=high)

    @classmethod
    def named(cls, name: str, factor: float, **options) -> Mismatch:
        """One effect off by ``factor``: name is yield, hardening, compliance, anisotropy, edge or response."""
        return cls(**{f"{name}_factor": factor}, **options)

    @property
    def label(self) -> str:
        """Short text of the factors that are not 1 ("nominal" when none)."""
        parts = [f"{k.removesuffix('_factor')} x{v:g}" for k, v in asdict(self).items()
                 if k.endswith("_factor") and v != 1.0]
        return ", ".join(parts) or "nominal"


def mismatched_parts(steel: PlateSteel, compliance: Compliance, mismatch: Mismatch):
    """The steel, the compliance and the plate options of a plate off by ``mismatch``.

    Parameters
    ----------
    steel : PlateSteel
        The steel before the mismatch.
    compliance : Compliance
    mismatch : Mismatch

    Returns
    -------
    steel : PlateSteel
    compliance : Compliance
    options : dict
        ``edge_yield_factor``, ``edge_band_mm``, ``response_factor`` and ``response_after_steps`` for
        :class:`mppf.sim.plate.plate.SteelPlate`.
    """
    m = mismatch
    steel = replace(steel, yield_stress_mpa=steel.yield_stress_mpa * m.yield_factor,
                    swift_exponent=min(1.0, steel.swift_exponent * m.hardening_factor),
                    linear_hardening_mpa=steel.linear_hardening_mpa * m.hardening_factor,
                    transverse_yield_ratio=1.0 + m.anisotropy_factor * (steel.transverse_yield_ratio - 1.0))
    compliance = Compliance(min(100.0, compliance.frame_mm_per_mn * m.compliance_factor),
                            min(1.0, compliance.punch_mm_per_kn * m.compliance_factor))
    options = {"edge_yield_factor": m.edge_factor, "edge_band_mm": m.edge_band_mm,
               "response_factor": m.response_factor, "response_after_steps": m.response_after_steps}
    return steel, compliance, options


def edge_field(uv_mm, size_mm, factor: float, band_mm: float) -> np.ndarray:
    """Yield factor (n,) of the edge band: ``factor`` at the edge, 1 beyond ``band_mm``, linear between.

    Parameters
    ----------
    uv_mm : (n, 2) float
        Points in the plate frame (origin at the centre of its bounding rectangle), mm.
    size_mm : (2,) float
        Length and width of that rectangle, mm.
    factor : float
    band_mm : float
    """
    uv = np.asarray(uv_mm, dtype=float).reshape(-1, 2)
    if factor == 1.0 or band_mm <= 0.0:
        return np.ones(len(uv))
    inside = np.min(0.5 * np.asarray(size_mm, dtype=float) - np.abs(uv), axis=1)
    share = np.clip(inside / band_mm, 0.0, 1.0)
    return factor + (1.0 - factor) * share
