"""Analytic plate surfaces for the planner tests (height fields with exact derivatives)."""

from __future__ import annotations

import numpy as np


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
