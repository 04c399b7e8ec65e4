"""The trial press of ``bench_loop.py --trial-press FRACTION`` (issue 40): the alternative to under-bending.

Before the full first press, a short trial press (every step of the nominal plan at ``fraction`` of its
travel from the flat plate) is measured; the plate's effective yield stress is fitted to it through the
planner's plate model (:func:`mppf.forming.precompensate.predict_mid_heights`), and the full first press is
planned for the fitted yield stress. The trial counts as a press: the run's first cycle is the trial.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.optimize import minimize_scalar

from mppf.core.transform import apply_tf
from mppf.forming.material import Material
from mppf.forming.precompensate import deviation, predict_mid_heights
from mppf.planning.steps import flat_heights

YIELD_BOUNDS = (0.6, 1.6)
"""Range of the fitted yield stress, as factors of the nominal one."""


def trial_strokes(press, job, fraction: float):
    """The trial's steps: each step of ``job`` at ``fraction`` of its travel from the flat plate.

    Returns
    -------
    list of (upper_mm, lower_mm, active)
        (rows, cols) tip heights (parked where inactive) and the active punches of each step.
    """
    up0, lo0 = flat_heights(job.thickness_mm)
    out = []
    for step in job.steps:
        upper, lower = step.setpoints_mm(press)
        act = step.active
        out.append((np.where(act, up0 + fraction * (upper - up0), upper),
                    np.where(act, lo0 + fraction * (lower - lo0), lower), act))
    return out


def fit_trial_yield(press, trial_last, measured_punch_mm, job, nominal: Material) -> tuple[Material, float]:
    """The yield stress that makes the plate model predict the trial's measured punch deviations.

    Parameters
    ----------
    press : PressConfig
    trial_last : (upper_mm, lower_mm, active)
        The trial's last step.
    measured_punch_mm : (rows, cols) float
        The measured deviation at the punches after the trial (best plane removed, NaN unknown).
    job : Job
        The nominal plan (its layout's outline and design heights).
    nominal : Material

    Returns
    -------
    (Material, float)
        The nominal material with the fitted yield stress, and the share of the measured
        deviations' squares the fit explains.
    """
    upper, lower, act = trial_last
    target = job.layout.design_mid_mm
    known = act & np.isfinite(measured_punch_mm)
    thickness = job.thickness_mm

    def cost(yield_mpa: float) -> float:
        material = replace(nominal, yield_stress_mpa=float(yield_mpa))
        mid = predict_mid_heights(press, np.where(act, upper, np.nan), np.where(act, lower, np.nan), act,
                                  job.layout.outline_mm, thickness, material)
        return float(np.sum((deviation(press, mid, target, act) - measured_punch_mm)[known] ** 2))

    lo, hi = (f * nominal.yield_stress_mpa for f in YIELD_BOUNDS)
    best = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 1.0})
    measured = float(np.sum(measured_punch_mm[known] ** 2))
    return replace(nominal, yield_stress_mpa=float(best.x)), 1.0 - float(best.fun) / max(measured, 1e-12)


class Replanned:
    """A hull plate planned again for the fitted material (the bench's ``Planned`` interface)."""

    def __init__(self, press, planned, material: Material, thickness_mm: float):
        from mppf.geometry.read import read_points
        from mppf.loop.plate import plan_first_cycle
        from mppf.loop.settings import LoopSettings

        design = read_points(planned.design_path)
        self.name = planned.name
        self.job = plan_first_cycle(design, planned.flat, press, thickness_mm, material=material,
                                    settings=LoopSettings(yield_uncertainty_pct=0.0))
        self.design_press = apply_tf(self.job.tf_press_design, design.points)
        self.design_path, self.flat = planned.design_path, planned.flat


def run_trial(press, planned, plate, max_cycles: int, fraction: float, bench, correction: str = "learned") -> dict:
    """Trial press, fit, full first press planned for the fitted yield stress, then the loop's corrections.

    ``bench`` is the ``bench_loop`` module (its ``true_deviation``, ``run_direct``, ``NOMINAL``,
    ``THICKNESS_MM``, tolerances); ``correction`` the correction it runs. The row is ``run_direct``'s with the
    trial as cycle 1.
    """
    steps = trial_strokes(press, planned.job, fraction)
    for upper, lower, act in steps:
        plate.press_step(upper, lower, act)
    active = planned.job.steps[-1].active
    form_max, rms, punch, _ = bench.true_deviation(press, plate.formed, planned, active)
    trial = {"max": form_max, "rms": rms}
    if form_max <= bench.TOL_MM and rms <= bench.RMS_TOL_MM:  # the trial press already in tolerance
        return {"max": [form_max], "rms": [rms], "decisions": ["in_tolerance"], "ok_at": 1, "verdict": None,
                "share": [], "trial": trial}
    fitted, explained = fit_trial_yield(press, steps[-1], punch, planned.job, bench.NOMINAL)
    trial.update(fitted_yield_mpa=round(fitted.yield_stress_mpa, 1), explained=round(explained, 3))
    replanned = Replanned(press, planned, fitted, bench.THICKNESS_MM)
    row = bench.run_direct(press, replanned, plate, max_cycles - 1, True, correction)
    row["max"], row["rms"] = [form_max] + row["max"], [rms] + row["rms"]
    row["decisions"] = ["trial"] + row["decisions"]
    row["ok_at"] = None if row["ok_at"] is None else row["ok_at"] + 1
    row["trial"] = trial
    return row
