"""Springback pre-compensation: over-bend the target so the plate springs back to it.

The plate's principal curvatures ``k1, k2`` and directions ``e1, e2`` are taken at its
centre (the origin of its local frame). Each is over-bent to the loaded curvature
``k'`` of :func:`mppf.springback.loaded_curvature` (R_i/R_f = 4x^3 - 3x + 1). The
surface is changed by swapping, along each principal direction, the circular arc of
the target curvature for the arc of the over-bent curvature:

    z'(u, v) = z(u, v) + sum_i [ arc(k'_i, a_i) - arc(k_i, a_i) ],
    a_i = e_i . (u, v),   arc(k, a) = (1 - sqrt(1 - k^2 a^2)) / k

so a cylinder of radius R becomes exactly a cylinder of radius R_i, and the plate's
local deviations from its principal arcs are kept as they are. Directions flatter than
``FLAT_RADIUS_MM`` are left alone. See ``docs/planning.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.errors import GeometryError
from mppf.springback import Material, loaded_curvature
from mppf.surface import curvatures

FLAT_RADIUS_MM = 1.0e6
"""Principal radii above this (1 km) count as flat and are not over-bent."""

MAX_ARC_FRACTION = 0.95
"""|k a| must stay below this over the plate (the over-bent arc must stay a graph)."""


def _arc(kappa, a):
    """Height of a circular arc of curvature kappa at distance a, and its two derivatives."""
    root = np.sqrt(1.0 - (kappa * a) ** 2)
    height = kappa * a * a / (1.0 + root)
    slope = kappa * a / root
    bend = kappa / root**3
    return height, slope, bend


@dataclass(frozen=True, eq=False)
class OverbentSurface:
    """A height field with its principal arcs at the centre replaced by over-bent ones.

    Attributes
    ----------
    base : Surface
        The target surface (local plate frame).
    target_k : (2,) float
        Principal curvatures of the target at the centre (1/mm, + concave from +w).
    loaded_k : (2,) float
        Over-bent curvatures.
    directions : (2, 2) float
        Rows: unit (du, dv) of the two principal directions.
    """

    base: object
    target_k: np.ndarray
    loaded_k: np.ndarray
    directions: np.ndarray

    def derivatives(self, u, v):
        """(z, zu, zv, zuu, zuv, zvv) of the over-bent surface at local (u, v), mm."""
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float)
        z, zu, zv, zuu, zuv, zvv = (np.array(x, dtype=float) for x in self.base.derivatives(u, v))
        for (du, dv), k_t, k_l in zip(self.directions, self.target_k, self.loaded_k):
            if k_t == k_l:
                continue
            a = du * u + dv * v
            h_l, s_l, b_l = _arc(k_l, a)
            h_t, s_t, b_t = _arc(k_t, a)
            dh, ds, db = h_l - h_t, s_l - s_t, b_l - b_t
            z, zu, zv = z + dh, zu + ds * du, zv + ds * dv
            zuu, zuv, zvv = zuu + db * du * du, zuv + db * du * dv, zvv + db * dv * dv
        return z, zu, zv, zuu, zuv, zvv

    def evaluate(self, u, v):
        """Height z'(u, v), mm."""
        return self.derivatives(u, v)[0]


def overbend(surface, thickness_mm: float, material: Material, half_size_mm: float) -> OverbentSurface:
    """The over-bent surface to press so the plate springs back to ``surface``.

    Parameters
    ----------
    surface : Surface
        Target (design) surface in its local frame, origin at the plate centre.
    thickness_mm : float
    material : Material
    half_size_mm : float
        Largest distance from the centre over which the surface is used (plate plus
        trim allowance), to check that the over-bent arcs exist there.

    Raises
    ------
    GeometryError
        The over-bent radius is too small for the plate (the arc would turn vertical).
    """
    curv = curvatures(surface, np.zeros(1), np.zeros(1))
    target = np.array([curv.k1[0], curv.k2[0]])
    directions = np.vstack([curv.dir1[0], curv.dir2[0]])
    flat = np.abs(target) < 1.0 / FLAT_RADIUS_MM
    loaded = np.where(flat, target, loaded_curvature(np.where(flat, 0.0, target), thickness_mm, material))
    worst = float(np.abs(loaded).max()) * half_size_mm
    if worst >= MAX_ARC_FRACTION:
        raise GeometryError(
            f"the over-bent radius {1.0 / np.abs(loaded).max():.0f} mm is too small for a plate reaching "
            f"{half_size_mm:.0f} mm from its centre",
            hint="form this plate without --springback, or in parts",
        )
    return OverbentSurface(base=surface, target_k=target, loaded_k=loaded, directions=directions)
