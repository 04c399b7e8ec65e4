"""The old simple simulated plate (the planner's own model), pressed step by step.

:class:`PlannerModelPlate` gives :func:`mppf.sim.forming.form_plate` the interface of
:class:`mppf.sim.plate.plate.SteelPlate` (``press_step``, ``formed``, ``state_dict`` /
``from_state``), so the dry-run shop (:mod:`mppf.sim.shop`) can press either. It is the
plate of the loop's benchmarks before issue 14, kept for comparison (``plate_model="planner"``).
"""

from __future__ import annotations

import json

import numpy as np

from mppf.core.errors import InputError
from mppf.core.validate import check_number
from mppf.model.material import Material
from mppf.model.press import PressConfig
from mppf.sim.forming import FormedPlate, check_step_grids, form_plate, sample_plate


class PlannerModelPlate:
    """The old simple simulated plate, pressed step by step like :class:`mppf.sim.plate.plate.SteelPlate`.

    The planner's own model (:func:`form_plate`) with the plate's true, scattered yield
    stress and thickness (:func:`sample_plate`). It has no memory: each step forms the
    plate on its own, so the plate is that of its last step. A step stopped on the way
    (``share < 1``) takes the tips that share of the way from the last step's tips (the
    flat stroke set before the first step).

    Parameters
    ----------
    press : PressConfig
    outline_xy_mm : (k, 2) float
    thickness_mm : float
        Nominal thickness.
    material : Material
        Nominal material.
    seed : int
    yield_scatter, thickness_scatter : float
        As :func:`sample_plate`.
    """

    def __init__(self, press: PressConfig, outline_xy_mm, thickness_mm: float, material: Material = Material(), *,
                 seed: int = 0, yield_scatter: float = 0.15, thickness_scatter: float = 0.03):
        self.press = press
        self.outline_xy_mm = np.asarray(outline_xy_mm, dtype=float)
        self.nominal = (float(thickness_mm), material, int(seed), float(yield_scatter), float(thickness_scatter))
        self.plate = sample_plate(thickness_mm, material, seed, yield_scatter, thickness_scatter)
        self.tips: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._formed = None

    def press_step(self, upper_mm, lower_mm, active, *, share: float = 1.0) -> FormedPlate:
        """Form the plate between this step's tips (see the class docstring); returns :attr:`formed`."""
        share = check_number("share of the step", share, low=0.0, high=1.0, low_open=True)
        upper, lower, act = check_step_grids(self.press, upper_mm, lower_mm, active)
        if share < 1.0:
            was_upper, was_lower = (np.full(self.press.shape, self.plate.thickness_mm), np.zeros(self.press.shape)) \
                if self.tips is None else self.tips[:2]
            upper = np.where(act, was_upper + share * (upper - was_upper), upper)
            lower = np.where(act, was_lower + share * (lower - was_lower), lower)
        self._formed = form_plate(self.press, upper, lower, act, self.plate, self.outline_xy_mm)
        self.tips = (np.where(act, upper, np.nan), np.where(act, lower, np.nan), act)
        return self._formed

    @property
    def formed(self) -> FormedPlate:
        """The plate after its last step."""
        if self._formed is None:
            raise InputError("the plate has not been pressed yet", hint="press a step first")
        return self._formed

    def state_dict(self) -> dict:
        """The nominal values, the seed and the last tips (``np.savez``-able)."""
        thickness, material, seed, ys, ts = self.nominal
        config = {"press": self.press.to_dict(), "outline_xy_mm": self.outline_xy_mm.tolist(), "thickness_mm": thickness,
                  "material": [material.youngs_modulus_mpa, material.poisson, material.yield_stress_mpa],
                  "seed": seed, "yield_scatter": ys, "thickness_scatter": ts}
        state = {"config": json.dumps(config)}
        if self.tips is not None:
            state.update(upper_mm=self.tips[0], lower_mm=self.tips[1], active=self.tips[2])
        return state

    @classmethod
    def from_state(cls, state) -> PlannerModelPlate:
        """The plate of :meth:`state_dict`."""
        from mppf.model.press import press_from_dict

        config = json.loads(str(np.asarray(state["config"])))
        self = cls(press_from_dict(config["press"], "saved plate state"), np.asarray(config["outline_xy_mm"]),
                   config["thickness_mm"], Material(*config["material"]), seed=config["seed"],
                   yield_scatter=config["yield_scatter"], thickness_scatter=config["thickness_scatter"])
        if "active" in state:
            active = np.asarray(state["active"], dtype=bool)
            self.press_step(np.asarray(state["upper_mm"]), np.asarray(state["lower_mm"]), active)
        return self
