"""One physical plate: seeded plate-to-plate and smooth spatial scatter of its steel.

A plate is drawn from the nominal steel and thickness with one seed:

- plate to plate: the initial yield stress, the hardening (both hardening terms scaled
  together), the transverse yield ratio and the mean thickness scatter as independent
  normal numbers truncated at 2 standard deviations;
- over the plate: the yield stress and the thickness vary smoothly by a sum of
  ``field_modes`` random Fourier modes ``sum_k a cos(k_k . (u, v) + phi_k)`` with
  wavelengths between ``shortest_wavelength_mm`` and ``longest_wavelength_mm``, random
  directions and phases, and ``a = rms sqrt(2 / modes)`` (so the RMS over a large plate is
  ``rms``). The fields are functions of the plate's own coordinates (u, v) (mm from the
  centre of the plate frame, :func:`mppf.sim.plate.grid.plate_frame`).

The same seed gives the same plate.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from mppf.core.validate import check_number, check_positive
from mppf.sim.plate.material import PlateSteel


@dataclass(frozen=True)
class Scatter:
    """Scatter of a plate's properties (relative standard deviations or RMS values).

    Attributes
    ----------
    yield_plate, hardening_plate, thickness_plate, anisotropy_plate : float
        Plate-to-plate standard deviation of the initial yield stress, the hardening, the
        mean thickness and the transverse yield ratio (relative).
    yield_field, thickness_field : float
        RMS of the smooth variation over the plate (relative).
    field_modes : int
        Fourier modes per field.
    shortest_wavelength_mm, longest_wavelength_mm : float
        Wavelength range of the modes.
    """

    yield_plate: float = 0.05
    hardening_plate: float = 0.15
    thickness_plate: float = 0.01
    anisotropy_plate: float = 0.01
    yield_field: float = 0.03
    thickness_field: float = 0.015
    field_modes: int = 6
    shortest_wavelength_mm: float = 1500.0
    longest_wavelength_mm: float = 6000.0

    def __post_init__(self):
        for name in ("yield_plate", "hardening_plate", "thickness_plate", "anisotropy_plate",
                     "yield_field", "thickness_field"):
            check_number(f"scatter {name}", getattr(self, name), low=0.0, high=0.2)
        check_number("scatter field_modes", self.field_modes, low=1, high=64, integer=True)
        check_positive("shortest wavelength", self.shortest_wavelength_mm, unit="mm")
        check_number("longest wavelength", self.longest_wavelength_mm, low=self.shortest_wavelength_mm, unit="mm")


NO_SCATTER = Scatter(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
"""A plate exactly as nominal (closed-form checks)."""


@dataclass(frozen=True, eq=False)
class PhysicalPlate:
    """The true properties of one plate.

    Attributes
    ----------
    steel : PlateSteel
        True steel (nominal + plate-to-plate scatter).
    thickness_mm : float
        True mean thickness.
    yield_modes, thickness_modes : (k, 4) float
        Fourier modes (k_u 1/mm, k_v 1/mm, phase rad, amplitude) of the relative fields.
    seed : int or None
        The seed it was drawn with.
    """

    steel: PlateSteel
    thickness_mm: float
    yield_modes: np.ndarray
    thickness_modes: np.ndarray
    seed: int | None = None

    def yield_factor(self, uv_mm) -> np.ndarray:
        """Factor (n,) on the initial yield stress at plate points ``uv_mm`` (n, 2)."""
        return 1.0 + _field(self.yield_modes, uv_mm)

    def thickness_at(self, uv_mm) -> np.ndarray:
        """Local thickness (n,) at plate points ``uv_mm`` (n, 2), mm."""
        return self.thickness_mm * (1.0 + _field(self.thickness_modes, uv_mm))

    def to_dict(self) -> dict:
        """Plain values (JSON-able) that :meth:`from_dict` rebuilds the plate from."""
        return {"steel": asdict(self.steel), "thickness_mm": self.thickness_mm, "seed": self.seed,
                "yield_modes": self.yield_modes.tolist(), "thickness_modes": self.thickness_modes.tolist()}

    @classmethod
    def from_dict(cls, data: dict) -> PhysicalPlate:
        """The plate of :meth:`to_dict`."""
        return cls(PlateSteel(**data["steel"]), float(data["thickness_mm"]),
                   np.asarray(data["yield_modes"], dtype=float).reshape(-1, 4),
                   np.asarray(data["thickness_modes"], dtype=float).reshape(-1, 4), data.get("seed"))


def sample_plate(steel: PlateSteel, thickness_mm: float, scatter: Scatter = Scatter(),
                 seed: int | None = 0) -> PhysicalPlate:
    """Draw one physical plate around the nominal steel and thickness.

    Parameters
    ----------
    steel : PlateSteel
        Nominal steel.
    thickness_mm : float
        Nominal thickness, mm.
    scatter : Scatter
    seed : int or None
        Seed of the draw; None: the nominal plate without any scatter.

    Returns
    -------
    PhysicalPlate
    """
    thickness_mm = check_positive("plate thickness", thickness_mm, unit="mm")
    if seed is None:
        return PhysicalPlate(steel, thickness_mm, np.zeros((0, 4)), np.zeros((0, 4)), None)
    rng = np.random.default_rng(seed)
    a_yield, a_hard, a_thick, a_aniso = _truncated_normal(rng, 4)
    hardening = 1.0 + scatter.hardening_plate * a_hard
    true_steel = replace(
        steel,
        yield_stress_mpa=steel.yield_stress_mpa * (1.0 + scatter.yield_plate * a_yield),
        linear_hardening_mpa=steel.linear_hardening_mpa * hardening,
        swift_exponent=min(steel.swift_exponent * hardening, 1.0),
        transverse_yield_ratio=steel.transverse_yield_ratio * (1.0 + scatter.anisotropy_plate * a_aniso),
    )
    yield_modes = _modes(rng, scatter, scatter.yield_field)
    thickness_modes = _modes(rng, scatter, scatter.thickness_field)
    return PhysicalPlate(true_steel, thickness_mm * (1.0 + scatter.thickness_plate * a_thick),
                         yield_modes, thickness_modes, int(seed))


def _truncated_normal(rng: np.random.Generator, n: int, bound: float = 2.0) -> np.ndarray:
    """``n`` standard normal numbers redrawn until within [-bound, bound]."""
    out = rng.standard_normal(n)
    while np.any(np.abs(out) > bound):
        bad = np.abs(out) > bound
        out[bad] = rng.standard_normal(int(bad.sum()))
    return out


def _modes(rng: np.random.Generator, scatter: Scatter, rms: float) -> np.ndarray:
    """Random Fourier modes (k, 4) of a field of RMS ``rms``."""
    k = scatter.field_modes
    wavelength = np.exp(rng.uniform(np.log(scatter.shortest_wavelength_mm), np.log(scatter.longest_wavelength_mm), k))
    direction = rng.uniform(0.0, np.pi, k)
    phase = rng.uniform(0.0, 2.0 * np.pi, k)
    wave = 2.0 * np.pi / wavelength
    amplitude = np.full(k, rms * np.sqrt(2.0 / k))
    return np.column_stack([wave * np.cos(direction), wave * np.sin(direction), phase, amplitude])


def _field(modes: np.ndarray, uv_mm) -> np.ndarray:
    """Relative field (n,) of Fourier modes (k, 4) at plate points (n, 2)."""
    uv = np.asarray(uv_mm, dtype=float).reshape(-1, 2)
    if len(modes) == 0:
        return np.zeros(len(uv))
    arg = uv @ modes[:, :2].T + modes[:, 2]
    return np.cos(arg) @ modes[:, 3]
