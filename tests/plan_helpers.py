"""Helpers of the planning, forming and correction tests: analytic plate surfaces (height fields with
exact derivatives), the example press and a punch grid for the corrections."""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np
import pytest

from mppf.model.material import Material
from mppf.model.press import example_press_path, load_press


class PlaneSurface:
    """w = 0 everywhere."""

    def evaluate(self, u, v):
        return np.zeros_like(np.asarray(u, dtype=float))

    def derivatives(self, u, v):
        zero = np.zeros_like(np.asarray(u, dtype=float))
        return zero, zero, zero, zero, zero, zero


class CylinderSurface:
    """A cylinder of radius ``radius_mm`` with its axis along u, bottom at w = 0.

    w(v) = R - sqrt(R^2 - v^2) for R > 0 (a valley, concave from +w); R < 0 gives the
    mirror image (a ridge).
    """

    def __init__(self, radius_mm: float):
        self.radius_mm = radius_mm

    def evaluate(self, u, v):
        return self.derivatives(u, v)[0]

    def derivatives(self, u, v):
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float) + 0.0 * u
        r = abs(self.radius_mm)
        sign = np.sign(self.radius_mm)
        root = np.sqrt(r * r - v * v)
        z = sign * (r - root)
        zv = sign * v / root
        zvv = sign * r * r / root**3
        zero = np.zeros_like(v)
        return z, zero, zv, zero, zero, zvv


def cylinder_tips_mm(y_mm, radius_mm, tip_radius_mm, thickness_mm, lift_mm=0.0):
    """Closed-form tip heights on a valley cylinder (axis along x at height R + lift).

    The mid-surface is z = lift + R - sqrt(R^2 - y^2). An upper ball (radius
    r + t/2 on the mid-surface) sits inside: its centre is R - (r + t/2) from the
    cylinder axis; a lower ball sits outside at R + (r + t/2).
    """
    big_r = tip_radius_mm + thickness_mm / 2.0
    y = np.asarray(y_mm, dtype=float)
    axis_z = lift_mm + radius_mm
    upper = axis_z - np.sqrt((radius_mm - big_r) ** 2 - y**2) - tip_radius_mm
    lower = axis_z - np.sqrt((radius_mm + big_r) ** 2 - y**2) + tip_radius_mm
    return upper, lower


def cylinder_points(radius_mm, length_mm, width_mm, n_u=41, n_v=31):
    """(n, 3) grid points of a valley cylinder (axis along x), lowest line at z = 0."""
    u = np.linspace(-length_mm / 2, length_mm / 2, n_u)
    v = np.linspace(-width_mm / 2, width_mm / 2, n_v)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    zz = radius_mm - np.sqrt(radius_mm**2 - vv**2)
    return np.column_stack([uu.ravel(), vv.ravel(), zz.ravel()])


def developed_cylinder(radius_mm, length_mm, width_mm, n_u=41, n_v=31):
    """The flat (developed) plate of :func:`cylinder_points`, same point order, z = 0."""
    u = np.linspace(-length_mm / 2, length_mm / 2, n_u)
    v = np.linspace(-width_mm / 2, width_mm / 2, n_v)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    arc = radius_mm * np.arcsin(vv / radius_mm)
    return np.column_stack([uu.ravel(), arc.ravel(), np.zeros(uu.size)])


# -- the correction tests: the example press and a punch grid with a block of active punches --


@pytest.fixture(scope="module")
def press():
    """The bundled example press (24 x 16 punches, 150 mm pitch)."""
    return load_press(example_press_path())


@pytest.fixture(scope="module")
def grid(press):
    """(px, py, active, lower): punch axes, a 3 x 2 m block of active punches, lower tips of a bend along x."""
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    active = (np.abs(px) <= 1500) & (np.abs(py) <= 1000)
    lower = np.where(active, px**2 / 8000.0 - 30.0, np.nan)
    return px, py, active, lower


def neighbour_diffs(values, active):
    """|differences| of all row and column neighbours that are both active (flat array)."""
    out = []
    for axis in (0, 1):
        a = np.moveaxis(values, axis, 0)
        m = np.moveaxis(active, axis, 0)
        both = m[1:] & m[:-1]
        out.append(np.abs(a[1:] - a[:-1])[both])
    return np.concatenate(out)


# -- the plate-model tests: a block of active punches and a plate pressed with strokes refined for nominal steel --

MODEL_THICKNESS_MM = 20.0
NOMINAL = Material()


def model_press():
    """The example press with the plate cut to its net outline (exact geometry)."""
    return dataclasses.replace(load_press(example_press_path()), margin_mm=0.0)


def model_grid(press, active_cols=slice(2, 22), active_rows=slice(1, 15)):
    """(px, py, active, outline): punch axes, a block of active punches and a rectangle 50 mm around them."""
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    active = np.zeros(press.shape, dtype=bool)
    active[active_rows, active_cols] = True
    outline = np.array([[px[active].min() - 50, py[active].min() - 50], [px[active].max() + 50, py[active].min() - 50],
                        [px[active].max() + 50, py[active].max() + 50], [px[active].min() - 50, py[active].max() + 50]])
    return px, py, active, outline


@dataclass(frozen=True, eq=False)
class SofterPlate:
    """A twisted bilge planned on the plate model for nominal steel, pressed into a plate 15 % softer."""

    press: object
    px: np.ndarray
    py: np.ndarray
    active: np.ndarray
    outline: np.ndarray
    target: np.ndarray
    planned: object  # the Refinement for nominal steel
    true: Material
    measured: np.ndarray


@functools.lru_cache(maxsize=None)
def softer_plate_pressed() -> SofterPlate:
    """Strokes refined for the nominal steel; the plate that took them is 15 % softer (computed once, read-only)."""
    from mppf.correct.virtual_cycles import refine_strokes
    from mppf.model.job_parts import StepStrokes
    from mppf.forming.precompensate import deviation, predict_mid_heights

    press = model_press()
    t = MODEL_THICKNESS_MM
    px, py, active, outline = model_grid(press)
    target = np.where(active, py**2 / (2 * 6000.0) + px * py / 2.0e7, np.nan)
    planned = refine_strokes(press, StepStrokes(target + t / 2, target - t / 2, active), target, outline, t, NOMINAL)
    true = Material(yield_stress_mpa=0.85 * NOMINAL.yield_stress_mpa)
    formed = predict_mid_heights(press, planned.upper_mm, planned.lower_mm, active, outline, t, true)
    measured = deviation(press, formed, target, active)
    for array in (px, py, active, outline, target, measured, planned.upper_mm, planned.lower_mm):
        array.flags.writeable = False
    return SofterPlate(press, px, py, active, outline, target, planned, true, measured)
