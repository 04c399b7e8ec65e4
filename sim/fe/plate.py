"""The FE plate: a steel plate on the press computed by CalculiX, step by step, with plastic memory.

:class:`FEPlate` has the interface of :class:`mppf.sim.plate.plate.SteelPlate` (``place``,
``press_step``, ``formed``, ``state_dict`` / ``from_state``), so the dry run's scanner presses and
scans it like the finite-difference plate. Each :meth:`FEPlate.press_step` is one ccx run of the
deck of :func:`mppf.sim.fe.deck.history_deck`: the model, then every press step the plate has had
(approach, load, release) replayed from the flat plate, then the new one, so the plastic state
(stresses, back stresses, plastic strains) carries from step to step and cycle to cycle. (A ccx
restart file would save the replay, but CalculiX 2.20 does not restore the incompatible modes of
C3D8I elements from it: the restarted plate is out of equilibrium by 1e5 N.)
See docs/simulator-fe.md.
"""

from __future__ import annotations

import json
from dataclasses import asdict

import numpy as np
from mppf.sim.fe.ccx import FESolveError, run_ccx
from mppf.sim.fe.deck import history_deck, materials, model_lines, step_count
from mppf.sim.fe.formed import FormedFEPlate
from mppf.sim.fe.mesh import build_mesh
from mppf.sim.fe.results import last_of_steps, read_frd
from mppf.sim.plate.contact import Compliance, refuse_crushing
from mppf.sim.plate.grid import plate_frame, rotation_2d
from mppf.sim.plate.material import PlateSteel
from mppf.sim.plate.scatter import PhysicalPlate, Scatter, sample_plate

from mppf.core.errors import InputError
from mppf.core.validate import check_number
from mppf.model.press import PressConfig, press_from_dict

CELLS_PER_PITCH = 1
"""Default element edges between neighbouring punch axes (docs/simulator-fe.md, mesh study)."""

LAYERS = 4
"""Default C3D8I elements through the thickness (8 integration points: the through-thickness law within 0.5 %)."""

SMALLEST_STIFFNESS_N_MM = 1e4
"""Ball stiffness used for a rigid press (``punch_mm_per_kn`` 0)."""

NOMINAL_STEEL = PlateSteel()
"""Default nominal steel."""

DEFAULT_SCATTER = Scatter()
"""Default scatter of a plate's properties."""

DEFAULT_COMPLIANCE = Compliance()
"""Default press compliance (only its punch part acts)."""

OPTIONS = {"cells_per_pitch": CELLS_PER_PITCH, "layers": LAYERS}
"""The plate's options and their defaults."""


def _mesh_options(options: dict) -> dict:
    """The mesh options with their defaults (:data:`OPTIONS`); :class:`InputError` naming an unknown one."""
    unknown = set(options) - set(OPTIONS)
    if unknown:
        raise InputError(f"unknown FE plate option(s) {', '.join(sorted(unknown))}",
                         hint=f"use {', '.join(OPTIONS)}")
    return {**OPTIONS, **options}


class FEPlate:
    """One simulated physical steel plate on a press, computed by CalculiX.

    Parameters
    ----------
    press : PressConfig
    outline_xy_mm : (k, 2) float
        The plate as cut (trim margin included) in press x, y, mm.
    thickness_mm : float
        Nominal thickness, mm.
    steel : PlateSteel
        Nominal steel (E, nu, yield stress, Swift + linear hardening; the Hill anisotropy is not used).
    seed : int or None
        Seed of the plate's scatter; None: exactly nominal.
    scatter : Scatter
    compliance : Compliance
        Only the punch part acts (the stiffness of the gap elements); see docs/simulator-fe.md.
    progress : callable, optional
        Called with a line (str) while ccx runs.
    **options
        The mesh (:data:`OPTIONS`): ``cells_per_pitch`` (element edges between neighbouring
        punch axes, default :data:`CELLS_PER_PITCH`) and ``layers`` (C3D8I elements through
        the thickness, default :data:`LAYERS`).
    """

    def __init__(self, press: PressConfig, outline_xy_mm, thickness_mm: float, steel: PlateSteel = NOMINAL_STEEL, *,
                 seed: int | None = 0, scatter: Scatter = DEFAULT_SCATTER, compliance: Compliance = DEFAULT_COMPLIANCE,
                 progress=None, **options):
        plate = sample_plate(steel, thickness_mm, scatter, seed)
        self._build(press, outline_xy_mm, plate, compliance, _mesh_options(options), progress)

    @classmethod
    def from_physical(cls, press: PressConfig, outline_xy_mm, plate: PhysicalPlate, *,
                      compliance: Compliance = DEFAULT_COMPLIANCE, progress=None, **options) -> FEPlate:
        """A flat FE plate of a given physical plate; ``options``: ``cells_per_pitch``, ``layers``."""
        self = cls.__new__(cls)
        self._build(press, outline_xy_mm, plate, compliance, _mesh_options(options), progress)
        return self

    def _build(self, press, outline_xy_mm, plate, compliance, options, progress):
        """Mesh and initial state of the flat, stress-free plate between the flat stroke set."""
        self.press, self.plate, self.compliance, self.progress = press, plate, compliance, progress
        self.options = {
            "cells_per_pitch": check_number("cells per pitch", options["cells_per_pitch"], low=1, high=8,
                                            integer=True),
            "layers": check_number("layers", options["layers"], low=1, high=8, integer=True)}
        self.outline_xy_mm = np.asarray(outline_xy_mm, dtype=float)
        centre, angle, _ = plate_frame(self.outline_xy_mm)
        self._frame = (centre, angle)
        self.mesh = build_mesh(press, self.outline_xy_mm, lambda xy: plate.thickness_at(self.to_plate(xy)),
                               self.options["cells_per_pitch"], self.options["layers"])
        m = len(self.mesh.bottom)
        self.u_mm = np.zeros((self.mesh.node_count, 3))
        self.loaded_u_mm = self.u_mm.copy()
        self.force_n = np.zeros(2 * m)
        self.tips_lower_mm = np.zeros(m)
        self.tips_upper_mm = self.mesh.thickness_mm.copy()
        self.tips_enabled = np.ones(m, dtype=bool)
        self.history: list[tuple] = []  # (tips (2 m,), touch (2 m,)) of every press step
        self.steps = 0
        self.last_seconds = self.last_cpu_s = 0.0  # the last ccx run's wall and CPU time, s
        self.last_ccx_steps: dict = {}  # its analysis steps: (increments, cutbacks, iterations)

    def to_plate(self, xy_mm) -> np.ndarray:
        """Plate u, v (n, 2) of press x, y (n, 2) (the frame of the scatter fields), mm."""
        centre, angle = self._frame
        return (np.asarray(xy_mm, dtype=float).reshape(-1, 2) - centre) @ rotation_2d(angle)

    @property
    def punch_stiffness_n_mm(self) -> float:
        """Stiffness of one ball and punch (the gap elements), N/mm."""
        c = self.compliance.punch_mm_per_kn / 1000.0
        return 1.0 / c if c > 0 else 1e3 * SMALLEST_STIFFNESS_N_MM

    def place(self, placement_mm) -> None:
        """Only the first placement: the FE plate is not pressed in sections.

        Raises
        ------
        InputError
            A placement other than (0, 0).
        """
        if np.any(np.abs(np.asarray(placement_mm, dtype=float)) > 1e-6):
            raise InputError("the FE plate cannot be pressed in sections (its punch contacts are fixed to the "
                             f"first placement), got placement {np.asarray(placement_mm).tolist()} mm",
                             hint="use the finite-difference plate (--physics fd) for plates larger than the bed")

    def press_step(self, upper_mm, lower_mm, active, *, share: float = 1.0) -> FormedFEPlate:
        """Press one step (one ccx run) and let the plate spring back.

        Parameters
        ----------
        upper_mm, lower_mm : (rows, cols) float
            Tip heights as the PLC read them back, mm (inactive entries ignored, may be NaN).
        active : (rows, cols) bool
            Punch pairs in use; the others go to their park heights.
        share : float
            Share of the way from the last tips to these that the tips travel, in (0, 1].

        Returns
        -------
        FormedFEPlate

        Raises
        ------
        InputError
            Grids of the wrong shape, NaN tips at active pairs, a gap below half the thickness,
            ccx not installed.
        FESolveError
            ccx did not converge (its deck and log are kept).
        """
        share = check_number("share of the step", share, low=0.0, high=1.0, low_open=True)
        lower, upper, enabled = self._check_step(upper_mm, lower_mm, active)
        start_lower = np.where(self.tips_enabled, self.tips_lower_mm, self.press.lower.park_mm)
        start_upper = np.where(self.tips_enabled, self.tips_upper_mm, self.press.upper.park_mm)
        if share < 1.0:
            lower = np.where(enabled, start_lower + share * (lower - start_lower), lower)
            upper = np.where(enabled, start_upper + share * (upper - start_upper), upper)
        entry = (np.concatenate([lower, upper]), np.concatenate(self._skins()))
        run = run_ccx(self.deck([entry]), progress=self.progress)
        steps = last_of_steps(read_frd(run.frd))
        free_step = step_count(len(self.history) + 1)
        if free_step - 1 not in steps or free_step not in steps:
            raise FESolveError(f"ccx wrote no displacements for steps {free_step - 1} and {free_step}",
                               hint="see the kept log")
        self.loaded_u_mm, self.u_mm = self._displacements(steps[free_step - 1]), self._displacements(steps[free_step])
        self.force_n = self._contact_forces(lower, upper)
        self.history.append(entry)
        self.last_seconds, self.last_cpu_s, self.last_ccx_steps = run.seconds, run.cpu_s, run.steps
        if self.progress is not None:
            counts = np.array(list(run.steps.values()) or [(0, 0, 0)]).sum(axis=0)
            self.progress(f"ccx: press step {self.steps + 1} done in {run.seconds:.0f} s ({run.cpu_s:.0f} s CPU, "
                          f"{len(run.steps)} analysis steps, {counts[0]} increments, {counts[2]} iterations)")
        self.tips_lower_mm, self.tips_upper_mm, self.tips_enabled = lower, upper, enabled
        self.steps += 1
        return self.formed

    def deck(self, more: list[tuple] = ()) -> str:
        """The CalculiX deck replaying the plate's press steps from the flat plate (and ``more`` after them).

        ``ccx -i`` on it gives the plate as it is now (docs/simulator-fe.md, "Running CalculiX by hand").

        Parameters
        ----------
        more : list of (tips (2 m,), touch (2 m,))
            Press steps to add (:func:`mppf.sim.fe.deck.history_deck`).
        """
        factor = self._yield_factor()
        model = model_lines(self.mesh, self.plate.steel, factor, self.punch_stiffness_n_mm)
        return history_deck(self.mesh, model, list(self.history) + list(more), materials(self.plate.steel, factor))

    def _yield_factor(self) -> np.ndarray:
        """Yield factor (e,) of each element (the plate's field at its centre)."""
        return self.plate.yield_factor(self.to_plate(self.mesh.hex_centre_xy_mm))

    def _displacements(self, block) -> np.ndarray:
        """Displacements (n, 3) of the plate's nodes from a DISP block, mm."""
        u = np.zeros((self.mesh.node_count, 3))
        keep = block.nodes <= self.mesh.node_count
        u[block.nodes[keep] - 1] = block.values[keep, :3]
        return u

    def _skins(self, u_mm=None) -> tuple[np.ndarray, np.ndarray]:
        """Heights (m,) of the bottom and top nodes on the punch axes, mm."""
        z = self.mesh.xyz_mm[:, 2] + (self.u_mm if u_mm is None else u_mm)[:, 2]
        return z[self.mesh.bottom - 1], z[self.mesh.top - 1]

    def _contact_forces(self, lower, upper) -> np.ndarray:
        """Ball forces (2 m,) at the end of loading from the gaps' overclosure, N."""
        bottom, top = self._skins(self.loaded_u_mm)
        k = self.punch_stiffness_n_mm
        return np.concatenate([k * np.maximum(lower - bottom, 0.0), k * np.maximum(top - upper, 0.0)])

    @property
    def formed(self) -> FormedFEPlate:
        """The plate as it is now (free after its last step), scanner compatible."""
        key = (self.steps, id(self.u_mm))
        if getattr(self, "_formed_key", None) != key:
            self._formed = self._build_formed()
            self._formed_key = key
        return self._formed

    def _build_formed(self) -> FormedFEPlate:
        mesh, m = self.mesh, len(self.mesh.bottom)
        levels = mesh.column[..., [0, -1]]
        used = levels[..., 0] > 0
        bottom, top = levels[used][:, 0] - 1, levels[used][:, 1] - 1

        def mid(u):
            xyz = mesh.xyz_mm + u
            return 0.5 * (xyz[bottom] + xyz[top])

        loaded_mid = mid(self.loaded_u_mm)
        pushed = (self.force_n[:m] > 0) | (self.force_n[m:] > 0)
        contact = 0.5 * (mesh.xyz_mm[mesh.bottom - 1] + self.loaded_u_mm[mesh.bottom - 1]
                         + mesh.xyz_mm[mesh.top - 1] + self.loaded_u_mm[mesh.top - 1])
        return FormedFEPlate(self.outline_xy_mm, self.plate, loaded_mid, mid(self.u_mm),
                             np.column_stack([mesh.punch_xy_mm[pushed], contact[pushed, 2]]),
                             self._spread(self.force_n[:m]), self._spread(self.force_n[m:]), self.to_plate)

    def _spread(self, values) -> np.ndarray:
        """(rows, cols) of per-pair values, NaN where no pair acts on the plate."""
        out = np.full(self.press.shape, np.nan)
        out[self.mesh.punch_index[:, 0], self.mesh.punch_index[:, 1]] = values
        return out

    def _check_step(self, upper_mm, lower_mm, active):
        """Tips (m,) of the pairs over the plate and which of them are active (parked ones at park)."""
        upper, lower = np.asarray(upper_mm, dtype=float), np.asarray(lower_mm, dtype=float)
        act = np.asarray(active, dtype=bool)
        for name, arr in (("upper_mm", upper), ("lower_mm", lower), ("active", act)):
            if arr.shape != self.press.shape:
                raise InputError(f"{name} has shape {arr.shape}, the press has {self.press.shape}")
        if not (np.all(np.isfinite(upper[act])) and np.all(np.isfinite(lower[act]))):
            raise InputError("NaN or infinite tip height at an active punch", hint="every active punch needs a height")
        r, c = self.mesh.punch_index[:, 0], self.mesh.punch_index[:, 1]
        enabled = act[r, c]
        if enabled.sum() < 3:
            raise InputError(f"a plate needs at least 3 active punch pairs over it, got {int(enabled.sum())}")
        p_lower = np.where(enabled, lower[r, c], self.press.lower.park_mm)
        p_upper = np.where(enabled, upper[r, c], self.press.upper.park_mm)
        refuse_crushing(np.where(enabled, p_upper - p_lower, np.inf), self.mesh.thickness_mm, self.mesh.punch_index)
        return p_lower, p_upper, enabled

    # --- save / restore ------------------------------------------------------------
    def state_dict(self) -> dict:
        """Everything to rebuild this plate as it is now: settings (JSON), arrays and the press steps to replay.

        Returns
        -------
        dict
            Save it with ``np.savez(path, **state)``.
        """
        config = {"press": self.press.to_dict(), "outline_xy_mm": self.outline_xy_mm.tolist(),
                  "plate": self.plate.to_dict(), "options": self.options, "compliance": asdict(self.compliance)}
        m2 = 2 * len(self.mesh.bottom)
        history = [np.array([h[i] for h in self.history]).reshape(-1, m2) for i in range(2)]
        return {"config": json.dumps(config), "model": "fe", "steps": np.array(self.steps),
                "u_mm": self.u_mm.copy(), "loaded_u_mm": self.loaded_u_mm.copy(),
                "force_n": self.force_n.copy(), "tips_lower_mm": self.tips_lower_mm.copy(),
                "tips_upper_mm": self.tips_upper_mm.copy(), "tips_enabled": self.tips_enabled.copy(),
                "history_tips_mm": history[0], "history_touch_mm": history[1]}

    @classmethod
    def from_state(cls, state, progress=None) -> FEPlate:
        """The plate of :meth:`state_dict` (a dict, or what ``np.load`` returns).

        Raises
        ------
        InputError
            Something is missing or does not fit the mesh the settings describe.
        """
        names = ("u_mm", "loaded_u_mm", "force_n", "tips_lower_mm", "tips_upper_mm", "tips_enabled")
        history = ("history_tips_mm", "history_touch_mm")
        missing = {"config", "steps", *history, *names} - set(state)
        if missing:
            raise InputError(f"saved FE plate state lacks {', '.join(sorted(missing))}",
                             hint="save it with FEPlate.state_dict()")
        config = json.loads(str(np.asarray(state["config"])))
        self = cls.from_physical(press_from_dict(config["press"], "saved plate state"),
                                 np.asarray(config["outline_xy_mm"]), PhysicalPlate.from_dict(config["plate"]),
                                 compliance=Compliance(**config["compliance"]), progress=progress,
                                 **config["options"])
        for name in names:
            like = getattr(self, name)
            value = np.array(state[name], dtype=like.dtype)
            if value.shape != like.shape:
                raise InputError(f"saved FE plate state: {name} has shape {value.shape}, the plate needs {like.shape}")
            setattr(self, name, value)
        self.steps = int(np.asarray(state["steps"]))
        tips, touch = (np.asarray(state[name], dtype=float) for name in history)
        m2 = 2 * len(self.mesh.bottom)
        if tips.shape != (self.steps, m2) or touch.shape != tips.shape:
            raise InputError(f"saved FE plate state: a history of {tips.shape} tips for {self.steps} steps and "
                             f"{m2} tips", hint="save it with FEPlate.state_dict()")
        self.history = list(zip(tips, touch))
        return self
