"""The numerical and model-mismatch settings of the simulated steel plate.

:class:`PlateOptions` is what :class:`~mppf.sim.plate.plate.SteelPlate` takes beyond the
press, the outline and the physical plate; each field is checked when it is built, and
its plain-value form (:meth:`PlateOptions.to_dict`) is saved with the plate's state.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

from mppf.core.errors import InputError
from mppf.core.validate import check_number, check_positive
from mppf.sim.plate.through_thickness import LAYERS

GRID_SPACING_MM = 50.0
"""Default cell size of the plate grid."""

LOAD_INCREMENTS = 2
"""Default sub-increments of the tip path of one press step."""


@dataclass(frozen=True)
class PlateOptions:
    """How the steel plate is computed, and how it departs from the model (checked when built).

    Attributes
    ----------
    grid_spacing_mm : float
        Cell size of the plate grid, mm.
    layers : int
        Gauss points through the half thickness (2 to 64).
    load_increments, unload_increments : int
        Sub-increments of loading (tip path) and unloading (1 to 1000).
    springback : bool
        False: the formed shape is the loaded one (the plate stays as held).
    cylindrical : bool
        Plane-strain kinematics w(u) (closed-form checks of wide plates).
    edge_yield_factor : float
        Factor on the yield stress at the plate's edges (0.05 to 20), fading to 1 over
        ``edge_band_mm`` (model mismatch, :mod:`mppf.sim.plate.mismatch`).
    edge_band_mm : float
        Width of that band, mm.
    response_factor : float
        Every permanent shape change after the first ``response_after_steps`` steps is, as the
        scanner sees it, this times the one the plate equations give (0.05 to 20; model
        mismatch: a plate answering more or less than modelled; 0 steps: the whole shape
        about the flat plate).
    response_after_steps : int
        Steps pressed as modelled before the response factor applies.
    """

    grid_spacing_mm: float = GRID_SPACING_MM
    layers: int = LAYERS
    load_increments: int = LOAD_INCREMENTS
    unload_increments: int = 1
    springback: bool = True
    cylindrical: bool = False
    edge_yield_factor: float = 1.0
    edge_band_mm: float = 150.0
    response_factor: float = 1.0
    response_after_steps: int = 0

    def __post_init__(self):
        checked = {
            "grid_spacing_mm": check_positive("grid spacing", self.grid_spacing_mm, unit="mm"),
            "layers": check_number("layers", self.layers, low=2, high=64, integer=True),
            "load_increments": check_number("load increments", self.load_increments, low=1, high=1000,
                                            integer=True),
            "unload_increments": check_number("unload increments", self.unload_increments, low=1, high=1000,
                                              integer=True),
            "springback": bool(self.springback), "cylindrical": bool(self.cylindrical),
            "edge_yield_factor": check_number("edge yield factor", self.edge_yield_factor, low=0.05, high=20.0),
            "edge_band_mm": check_number("edge band", self.edge_band_mm, low=0.0, unit="mm"),
            "response_factor": check_number("response factor", self.response_factor, low=0.05, high=20.0),
            "response_after_steps": check_number("steps before the response factor", self.response_after_steps,
                                                 low=0, integer=True),
        }
        for name, value in checked.items():
            object.__setattr__(self, name, value)

    @classmethod
    def of(cls, options: dict) -> PlateOptions:
        """The options of keyword arguments; :class:`InputError` naming an unknown one."""
        known = [f.name for f in fields(cls)]
        unknown = set(options) - set(known)
        if unknown:
            raise InputError(f"unknown plate option(s) {', '.join(sorted(unknown))}", hint=f"use {', '.join(known)}")
        return cls(**options)

    def to_dict(self) -> dict:
        """The options as plain values (JSON), field by field."""
        return asdict(self)
