"""Helpers of the comparison tests (tests/measure, tests/registration): analytic scans, plates formed
on the simulated press, and the comparisons several test files look at (computed once a session)."""

from __future__ import annotations

from functools import cache

import numpy as np
from scipy.spatial.transform import Rotation

from mppf.core.transform import apply_tf, make_tf
from mppf.model.material import Material
from mppf.measure.compare import compare
from mppf.measure.options import CompareOptions
from mppf.model.press import example_press_path, load_press
from mppf.sim.forming import PlateSample, form_plate
from mppf.sim.scanner import SimulatedScanner

BUMP_UV = (400.0, 200.0)
BUMP_SIGMA_MM = 150.0
THICKNESS_MM = 20.0
OUTLINE = [[-1500.0, -1000.0], [1500.0, -1000.0], [1500.0, 1000.0], [-1500.0, 1000.0]]


def height(u, v):
    """An asymmetric, doubly curved analytic plate (mm)."""
    return u**2 / (2 * 6000.0) - v**2 / (2 * 15000.0) + u**3 / 3e7 + u * v / 20000.0


def normals(u, v):
    zu = u / 6000.0 + u**2 / 1e7 + v / 20000.0
    zv = -v / 15000.0 + u / 20000.0
    n = np.column_stack([-zu, -zv, np.ones_like(u)])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def design():
    uu, vv = np.meshgrid(np.linspace(-1500, 1500, 61), np.linspace(-1000, 1000, 41))
    return np.column_stack([uu.ravel(), vv.ravel(), height(uu, vv).ravel()])


def pose():
    return make_tf(Rotation.from_euler("xyz", [20, -40, 70], degrees=True).as_matrix(), [500.0, -2000.0, 300.0])


def bump(u, v):
    return 5.0 * np.exp(-((u - BUMP_UV[0]) ** 2 + (v - BUMP_UV[1]) ** 2) / (2 * BUMP_SIGMA_MM**2))


def measured(n=8000, with_bump=True, noise_mm=0.3, seed=1):
    """Measured points: the design + a 5 mm Gaussian bump along the normal, noisy, moved."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1480, 1480, n)
    v = rng.uniform(-980, 980, n)
    rise = bump(u, v) if with_bump else np.zeros(n)
    pts = np.column_stack([u, v, height(u, v)]) + rise[:, None] * normals(u, v)
    pts += rng.normal(0.0, noise_mm, pts.shape)
    return u, v, apply_tf(pose(), pts)


@cache
def bump_result():
    """(u, v, comparison) of the bumped, noisy, moved scan of the analytic plate (compared once)."""
    u, v, points = measured()
    return u, v, compare(design(), points, CompareOptions(tolerance_mm=2.5))


@cache
def press():
    return load_press(example_press_path())


@cache
def form(r_x_mm, r_y_mm, asymmetric=True):
    """A plate formed on the simulated press to mid-surface x^2/2Rx - y^2/2Ry (+ cubic, twist)."""
    p = press()
    px, py = np.meshgrid(p.punch_x_mm, p.punch_y_mm)
    mid = px**2 / (2 * r_x_mm) - py**2 / (2 * r_y_mm)
    if asymmetric:
        mid = mid + px**3 / 3e7 + px * py / 20000.0
    active = (np.abs(px) <= 1600) & (np.abs(py) <= 1100)
    t = THICKNESS_MM
    return form_plate(p, mid + t / 2, mid - t / 2, active, PlateSample(t, Material()), OUTLINE)


def punch_grid():
    """(rows, cols, 2) punch axes of the example press."""
    p = press()
    px, py = np.meshgrid(p.punch_x_mm, p.punch_y_mm)
    return np.stack([px, py], axis=-1)


@cache
def formed_and_scan():
    """A plate formed on the simulated press, its simulated scan (occlusion + outliers), their comparison."""
    formed = form(4000.0, 9000.0)
    sample = SimulatedScanner(seed=2).sample(formed)
    plate = formed.mid_surface_points(50.0)  # the design = what was formed: deviations ~ 0
    c = compare(plate, sample.points, CompareOptions(offset_mm=THICKNESS_MM / 2, tf_press_design=np.eye(4),
            punch_xy_mm=punch_grid()))
    return formed, sample, c
