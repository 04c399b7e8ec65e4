"""A simulated steel plate on the press: pressed step by step, it keeps its plastic memory.

:class:`SteelPlate` is one physical plate (seeded) on one press. Each
:meth:`SteelPlate.press_step` takes the tip heights the PLC read back for a step:

1. the tips move from where they last were to the step's tips in ``load_increments``
   sub-increments (parked pairs start at their park heights), the plate in equilibrium
   under the unilateral contacts, the press compliance and its weight at each
   (:func:`mppf.sim.plate.solve.solve_loaded`), the plastic state committed after each;
2. the punches retract and the plate springs back free
   (:func:`mppf.sim.plate.solve.solve_unloaded`), unless ``springback=False``;
3. the plate keeps the unloaded shape and plastic state for the next step and cycle.

Before the first step the plate is flat and stress free, its bottom skin on z = 0, held
by the flat stroke set (lower tips 0, upper tips at the local thickness).
"""

from __future__ import annotations

import json
from dataclasses import asdict

import numpy as np

from mppf.core.errors import GeometryError, InputError
from mppf.core.validate import check_number
from mppf.model.press import PressConfig, press_from_dict
from mppf.sim.plate.contact import Compliance, Punches, refuse_crushing
from mppf.sim.plate.formed import FormedSteelPlate
from mppf.sim.plate.grid import PlateGrid
from mppf.sim.plate.material import PlateSteel
from mppf.sim.plate.mismatch import edge_field
from mppf.sim.plate.options import GRID_SPACING_MM, LOAD_INCREMENTS, PlateOptions  # noqa: F401 - re-exported
from mppf.sim.plate.predict import ContactPredictor
from mppf.sim.plate.scatter import PhysicalPlate, Scatter, sample_plate
from mppf.sim.plate.through_thickness import LayerLaw, LayerState
from mppf.sim.plate.solve import PlateModel, PlateSolveError, Tips, solve_loaded, solve_unloaded

INCREMENT_ITERATIONS = 15
"""Newton iterations an increment may take before it is halved."""

SMALLEST_INCREMENT = 1.0 / 64
"""Smallest share of the tip path in one increment."""

STATE_ARRAYS = ("q", "loaded_q", "force_n", "frame_mm", "tips_lower_mm", "tips_upper_mm", "tips_enabled")
"""Attributes of :class:`SteelPlate` saved by :meth:`SteelPlate.state_dict` (besides the plastic state and
``placement_mm``, which older states lack: the first placement)."""


class SteelPlate:
    """One simulated physical steel plate on a press.

    Parameters
    ----------
    press : PressConfig
        Punch positions and tip radius.
    outline_xy_mm : (k, 2) float
        The plate as cut (trim margin included) in press x, y, mm.
    thickness_mm : float
        Nominal thickness, mm.
    steel : PlateSteel
        Nominal steel.
    seed : int or None
        Seed of the plate's scatter (one seed, one physical plate); None: exactly nominal.
    scatter : Scatter
    compliance : Compliance
    **options
        The fields of :class:`~mppf.sim.plate.options.PlateOptions` (``grid_spacing_mm``,
        ``layers``, ``load_increments``, ``unload_increments``, ``springback``,
        ``cylindrical``, ``edge_yield_factor``, ``edge_band_mm``, ``response_factor``,
        ``response_after_steps``).

    Attributes
    ----------
    options : PlateOptions
    """

    def __init__(self, press: PressConfig, outline_xy_mm, thickness_mm: float, steel: PlateSteel = PlateSteel(), *,
                 seed: int | None = 0, scatter: Scatter = Scatter(), compliance: Compliance = Compliance(), **options):
        self._build(press, outline_xy_mm, sample_plate(steel, thickness_mm, scatter, seed), compliance,
                    PlateOptions.of(options))

    @classmethod
    def from_physical(cls, press: PressConfig, outline_xy_mm, plate: PhysicalPlate, *,
                      compliance: Compliance = Compliance(), **options) -> SteelPlate:
        """A flat plate of a given physical plate (e.g. one drawn by :func:`sample_plate`).

        Parameters
        ----------
        press, outline_xy_mm, compliance
            As for the constructor.
        plate : PhysicalPlate
        **options
            The fields of :class:`~mppf.sim.plate.options.PlateOptions` (defaults as for the constructor).
        """
        self = cls.__new__(cls)
        self._build(press, outline_xy_mm, plate, compliance, PlateOptions.of(options))
        return self

    def _build(self, press, outline_xy_mm, plate, compliance, options: PlateOptions):
        """Grid, punches, model and predictor of the flat, stress-free plate."""
        self.press, self.plate, self.compliance = press, plate, compliance
        self.options = options
        self.grid = PlateGrid(outline_xy_mm, self.options.grid_spacing_mm, cylindrical=self.options.cylindrical)
        self.law, self._placed = LayerLaw(plate.steel, self.options.layers), {}
        self._set_placement(np.zeros(2))
        # the flat, stress-free plate (bottom skin on z = 0) between the flat stroke set
        m = self.punches.count
        self.q = np.full(self.grid.n_dof, 0.5 * plate.thickness_mm)
        self.loaded_q = self.q.copy()
        self.state = LayerState.virgin(len(self.grid.gauss_uv), self.options.layers)
        self.force_n = np.zeros(2 * m)
        self.frame_mm = np.zeros(2)
        self.tips_lower_mm = np.zeros(m)
        self.tips_upper_mm = self.punches.thickness_mm.copy()
        self.tips_enabled = np.ones(m, dtype=bool)
        self.steps = 0
        self.last_iterations: list[int] = []
        self.response_ref_q = self.q.copy() if self.options.response_after_steps == 0 else None

    def _set_placement(self, placement_mm) -> None:
        """Punches, model and predictor of the plate shifted by ``placement_mm`` (built once per placement)."""
        key = tuple(np.round(np.asarray(placement_mm, dtype=float).reshape(2), 6))
        if key not in self._placed:
            punches = Punches(self.press, self.grid, self.plate.thickness_at, key)
            if punches.count < 3:
                raise GeometryError(f"the plate covers {punches.count} punch pair(s) of the press, "
                                    "at least 3 are needed", hint="give the plate's outline in press x, y (mm)")
            model = PlateModel(self.grid, self.law, self.plate, punches, self.compliance)
            model.yield_factor = model.yield_factor * edge_field(self.grid.gauss_uv, self.grid.size_mm,
                                                                 self.options.edge_yield_factor,
                                                                 self.options.edge_band_mm)
            self._placed[key] = (punches, model, ContactPredictor(model))
        self.placement_mm = np.array(key)
        self.punches, self.model, self.predictor = self._placed[key]

    def place(self, placement_mm) -> None:
        """Shift the plate on the bed (the next section of a plate larger than the bed).

        The press's punch axes then lie at press x, y + ``placement_mm`` in the plate's frame (the
        press x, y of its first placement). The plate keeps its shape and plastic state; it lies
        between the new punch pairs as it is, every pair just touching it, so the next step takes the
        tips from there to its own (the formed part is re-pressed where the sections overlap).

        Parameters
        ----------
        placement_mm : (2,) float
            Shift of the punch axes in the plate's frame, mm (0, 0: the first placement).
        """
        placement = np.asarray(placement_mm, dtype=float).reshape(2)
        if np.allclose(placement, self.placement_mm, atol=1e-6):
            return
        self._set_placement(placement)
        m = self.punches.count
        below, above = np.split(self.punches.gaps(self.q, np.zeros(m), np.zeros(m))[0], 2)
        self.tips_lower_mm, self.tips_upper_mm = below, -above  # zero gaps: the pairs touch the plate as it lies
        self.tips_enabled = np.ones(m, dtype=bool)
        self.force_n, self.frame_mm, self.loaded_q = np.zeros(2 * m), np.zeros(2), self.q.copy()

    # --- pressing ----------------------------------------------------------------
    def press_step(self, upper_mm, lower_mm, active, *, share: float = 1.0) -> FormedSteelPlate:
        """Press one step and let the plate spring back.

        Parameters
        ----------
        upper_mm, lower_mm : (rows, cols) float
            Tip heights as the PLC read them back (compliance is applied inside), mm;
            entries of inactive punches are ignored (may be NaN).
        active : (rows, cols) bool
            Punch pairs in use; the others are parked and do not touch.
        share : float
            Share of the way from the last tips to these the tips travel, in (0, 1]: less
            than 1 is a step whose motion was stopped on the way (an interruption).

        Returns
        -------
        FormedSteelPlate
            The plate after the step (:attr:`formed`).

        Raises
        ------
        InputError
            Grids of the wrong shape, NaN tips at active pairs, a gap below half the thickness.
        GeometryError
            Fewer than 3 active pairs over the plate.
        PlateSolveError
            The equilibrium did not converge.
        """
        share = check_number("share of the step", share, low=0.0, high=1.0, low_open=True)
        lower, upper, enabled = self._check_step(upper_mm, lower_mm, active)
        start_lower = np.where(self.tips_enabled, self.tips_lower_mm, self.press.lower.park_mm)
        start_upper = np.where(self.tips_enabled, self.tips_upper_mm, self.press.upper.park_mm)
        if share < 1.0:  # stopped on the way: the tips got this share of it
            lower = np.where(enabled, start_lower + share * (lower - start_lower), lower)
            upper = np.where(enabled, start_upper + share * (upper - start_upper), upper)
        # 1. load: the tips travel from where they were to the step's tips
        loaded, iterations = self._load(start_lower, start_upper, lower, upper, enabled)
        # 2. unload: the punches retract, the plate springs back
        q, state = loaded.q, loaded.state
        if self.options.springback:
            unloaded = solve_unloaded(self.model, loaded, self.options.unload_increments)
            q, state = unloaded.q, unloaded.state
            iterations.append(unloaded.iterations)
        # 3. the plate keeps its shape and plastic state
        self.loaded_q, self.q, self.state, self.force_n = loaded.q, q, state, loaded.force_n
        self.frame_mm = loaded.frame_mm
        self.tips_lower_mm, self.tips_upper_mm, self.tips_enabled = lower, upper, enabled
        self.steps += 1
        if self.steps == self.options.response_after_steps:  # the response factor applies from here
            self.response_ref_q = q.copy()
        self.last_iterations = iterations
        return self.formed

    def _load(self, start_lower, start_upper, lower, upper, enabled):
        """Equilibria along the tip path in sub-increments (halved where Newton struggles).

        Each increment starts from the elastic contact prediction from the last loaded
        state (:class:`mppf.sim.plate.predict.ContactPredictor`); its plastic state is
        committed before the next.

        Returns
        -------
        loaded : Equilibrium
            At the step's tips.
        iterations : list of int
            Newton iterations of each increment.
        """
        ref_q, ref_force, ref_frame, state = self.loaded_q, self.force_n, self.frame_mm, self.state
        done, size, iterations = 0.0, 1.0 / self.options.load_increments, []
        while done < 1.0 - 1e-12:
            s = min(1.0, done + size)
            tips_lower = start_lower + s * (lower - start_lower)
            tips_upper = start_upper + s * (upper - start_upper)
            q0, frame0, guess = self.predictor.predict(ref_q, ref_force, ref_frame, tips_lower, tips_upper, enabled)
            try:
                loaded = solve_loaded(self.model, q0, frame0, state, Tips(tips_lower, tips_upper, enabled), guess,
                                      INCREMENT_ITERATIONS)
            except PlateSolveError:
                if size <= SMALLEST_INCREMENT:
                    raise
                size *= 0.5
                continue
            done, iterations = s, iterations + [loaded.iterations]
            ref_q, ref_force, ref_frame, state = loaded.q, loaded.force_n, loaded.frame_mm, loaded.state
        return loaded, iterations

    @property
    def formed(self) -> FormedSteelPlate:
        """The plate as it is now (unloaded after its last step), scanner compatible."""
        key = (self.steps, id(self.q))
        if getattr(self, "_formed_key", None) != key:
            ref = self.response_ref_q
            shown = self.q if ref is None else ref + self.options.response_factor * (self.q - ref)
            self._formed = FormedSteelPlate.build(self.grid, self.plate, self.loaded_q, shown, self.punches,
                                                  self.force_n)
            self._formed_key = key
        return self._formed

    def _check_step(self, upper_mm, lower_mm, active):
        """Tips (m,) of the pairs over the plate and which of them are active."""
        shape = self.press.shape
        upper = np.asarray(upper_mm, dtype=float)
        lower = np.asarray(lower_mm, dtype=float)
        act = np.asarray(active, dtype=bool)
        for name, arr in (("upper_mm", upper), ("lower_mm", lower), ("active", act)):
            if arr.shape != shape:
                raise InputError(f"{name} has shape {arr.shape}, the press has {shape}")
        if not (np.all(np.isfinite(upper[act])) and np.all(np.isfinite(lower[act]))):
            raise InputError("NaN or infinite tip height at an active punch", hint="every active punch needs a height")
        enabled = self.punches.pick(act)
        if enabled.sum() < 3:
            raise GeometryError(f"a plate needs at least 3 active punch pairs over it, got {int(enabled.sum())}")
        p_lower = np.where(enabled, self.punches.pick(lower), 0.0)
        p_upper = np.where(enabled, self.punches.pick(upper), 0.0)
        refuse_crushing(np.where(enabled, p_upper - p_lower, np.inf), self.punches.thickness_mm, self.punches.index)
        return p_lower, p_upper, enabled

    # --- save / restore ------------------------------------------------------------
    def state_dict(self) -> dict:
        """Everything to rebuild this plate as it is now: JSON-able settings + numpy arrays.

        Returns
        -------
        dict
            ``"config"`` (a JSON string: press, outline, physical plate, options, compliance),
            ``"steps"`` and the arrays of :data:`STATE_ARRAYS` plus ``plastic_strain`` and
            ``alpha``. Save it with ``np.savez(path, **state)``.
        """
        config = {"press": self.press.to_dict(), "outline_xy_mm": self.grid.outline_xy_mm.tolist(),
                  "plate": self.plate.to_dict(), "options": self.options.to_dict(),
                  "compliance": asdict(self.compliance)}
        state = {name: np.array(getattr(self, name)) for name in STATE_ARRAYS}
        state.update(config=json.dumps(config), steps=np.array(self.steps), placement_mm=self.placement_mm.copy(),
                     plastic_strain=self.state.plastic_strain.copy(), alpha=self.state.alpha.copy())
        if self.response_ref_q is not None:
            state["response_ref_q"] = self.response_ref_q.copy()
        return state

    @classmethod
    def from_state(cls, state) -> SteelPlate:
        """The plate of :meth:`state_dict` (a dict, or the mapping ``np.load`` returns).

        Raises
        ------
        InputError
            Something is missing, or the arrays do not fit the plate the settings describe.
        """
        missing = {"config", "steps", "plastic_strain", "alpha", *STATE_ARRAYS} - set(state)
        if missing:
            raise InputError(f"saved plate state lacks {', '.join(sorted(missing))}",
                             hint="save it with SteelPlate.state_dict()")
        config = json.loads(str(np.asarray(state["config"])))
        plate = PhysicalPlate.from_dict(config["plate"])
        press = press_from_dict(config["press"], "saved plate state")
        self = cls.from_physical(press, np.asarray(config["outline_xy_mm"]), plate,
                                 compliance=Compliance(**config["compliance"]), **config["options"])
        if "placement_mm" in state:
            self._set_placement(np.asarray(state["placement_mm"], dtype=float))
        arrays = {name: getattr(self, name) for name in STATE_ARRAYS}
        arrays.update(plastic_strain=self.state.plastic_strain, alpha=self.state.alpha)
        restored = {}
        for name, like in arrays.items():
            value = np.array(state[name], dtype=like.dtype)
            if value.shape != like.shape:
                raise InputError(f"saved plate state: {name} has shape {value.shape}, the plate needs {like.shape}")
            restored[name] = value
        for name in STATE_ARRAYS:
            setattr(self, name, restored[name])
        self.state = LayerState(restored["plastic_strain"], restored["alpha"])
        self.steps = int(np.asarray(state["steps"]))
        if "response_ref_q" in state:
            self.response_ref_q = np.array(state["response_ref_q"], dtype=float)
        return self
