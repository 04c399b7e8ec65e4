"""Springback pre-compensation: over-bend the target so the plate springs back to it.

The plate's principal curvatures ``k1, k2`` and directions ``e1, e2`` are taken at its
centre (the origin of its local frame). Each is over-bent to the loaded curvature
``k'`` of :func:`mppf.forming.springback.loaded_curvature` (R_i/R_f = 4x^3 - 3x + 1). The
surface is changed by swapping, along each principal direction, the circular arc of
the target curvature for the arc of the over-bent curvature:

    z'(u, v) = z(u, v) + sum_i [ arc(k'_i, a_i) - arc(k_i, a_i) ],
    a_i = e_i . (u, v),   arc(k, a) = (1 - sqrt(1 - k^2 a^2)) / k

so a cylinder of radius R becomes exactly a cylinder of radius R_i, and the plate's
local deviations from its principal arcs are kept as they are. Directions flatter than
``FLAT_RADIUS_MM`` are left alone.

Hull plates whose curvature changes over the plate (saddles, bilges running into the
flat) are over-bent point by point on top of that: on a grid over the plate the target's
curvature tensor ``K = k1 d1 d1' + k2 d2 d2'`` is mapped to the loaded one
``K' = k1' d1 d1' + k2' d2 d2'`` (each principal curvature over-bent as above, nominal
material), the arcs' surface's own curvature tensor is subtracted, and the remaining
field ``K' - K_arcs`` is integrated to a height correction by least squares (its best
plane removed; the planner chooses the plate's offset and tilt). A plate of uniform
curvature (a cylinder) gets no correction: the arcs are exact there. See
``docs/planning.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RectBivariateSpline

from mppf.core.errors import GeometryError
from mppf.core.grid import from_principal, integrate_hessian, without_plane
from mppf.forming.springback import loaded_curvature
from mppf.geometry.curvature import curvatures
from mppf.model.material import Material

FLAT_RADIUS_MM = 1.0e6
"""Principal radii above this (1 km) count as flat and are not over-bent."""

MAX_ARC_FRACTION = 0.95
"""|k a| must stay below this over the plate (the over-bent arc must stay a graph)."""

FIELD_SPACING_MM = 40.0
"""Grid spacing of the point-by-point over-bend field."""

FIELD_MARGIN_MM = 200.0
"""The field grid covers the surface's bounds grown by this (ball contacts past the edge)."""

UNIFORM_CURVATURE = 1.0e-9
"""Curvature variation (1/mm) below which the plate counts as uniformly curved (no field)."""


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
    field: object = None

    def derivatives(self, u, v):
        """(z, zu, zv, zuu, zuv, zvv) of the over-bent surface at local (u, v), mm."""
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float)
        z, zu, zv, zuu, zuv, zvv = self._arc_derivatives(u, v)
        if self.field is not None:
            uu, vv = np.broadcast_arrays(u, v)
            extra = [self.field.ev(uu, vv, dx=dx, dy=dy) for dx, dy in ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))]
            z, zu, zv, zuu, zuv, zvv = (a + b for a, b in zip((z, zu, zv, zuu, zuv, zvv), extra))
        return z, zu, zv, zuu, zuv, zvv

    def _arc_derivatives(self, u, v):
        """Derivatives of the base with the principal arcs at the centre over-bent (no field)."""
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
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float)
        z = self._arc_derivatives(u, v)[0]
        if self.field is not None:
            uu, vv = np.broadcast_arrays(u, v)
            z = z + self.field.ev(uu, vv)
        return z


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
    arcs = OverbentSurface(base=surface, target_k=target, loaded_k=loaded, directions=directions)
    return OverbentSurface(base=surface, target_k=target, loaded_k=loaded, directions=directions,
                           field=_field(surface, arcs, thickness_mm, material))


class _Arcs:
    """The arcs-only over-bent surface as a Surface (for :func:`mppf.geometry.curvature.curvatures`)."""

    def __init__(self, arcs: OverbentSurface):
        self.arcs = arcs

    def derivatives(self, u, v):
        return self.arcs._arc_derivatives(u, v)


def _loaded_map(values, thickness_mm: float, material: Material) -> np.ndarray:
    """Over-bent curvatures of ``values`` (1/mm), tabulated (the exact solve is per value)."""
    values = np.asarray(values, dtype=float)
    mag = np.abs(values)
    top = float(mag.max())
    if top < 1.0 / FLAT_RADIUS_MM:
        return values.copy()
    table = np.geomspace(1.0 / FLAT_RADIUS_MM, top * 1.001, 150)
    loaded = loaded_curvature(table, thickness_mm, material)
    out = np.sign(values) * np.exp(np.interp(np.log(np.maximum(mag, 1e-300)), np.log(table), np.log(loaded)))
    return np.where(mag < 1.0 / FLAT_RADIUS_MM, values, out)


def _tensor(k1, k2, d1, d2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Kuu, Kuv, Kvv) of k1 d1 d1' + k2 d2 d2' (directions as unit (du, dv))."""
    tensor = from_principal(np.stack([k1, k2], -1), np.stack([d1, d2], -1))
    return tensor[:, 0, 0], tensor[:, 0, 1], tensor[:, 1, 1]


def _field(surface, arcs: OverbentSurface, thickness_mm: float, material: Material):
    """Spline of the height correction that over-bends the curvature point by point, or None."""
    bounds = getattr(surface, "bounds", None)
    if bounds is None:
        return None
    (u0, u1), (v0, v1) = bounds
    u_ax = np.arange(u0 - FIELD_MARGIN_MM, u1 + FIELD_MARGIN_MM + FIELD_SPACING_MM, FIELD_SPACING_MM)
    v_ax = np.arange(v0 - FIELD_MARGIN_MM, v1 + FIELD_MARGIN_MM + FIELD_SPACING_MM, FIELD_SPACING_MM)
    uu, vv = np.meshgrid(u_ax, v_ax, indexing="ij")
    target = curvatures(surface, uu.ravel(), vv.ravel())
    if max(np.ptp(target.k1), np.ptp(target.k2)) < UNIFORM_CURVATURE:
        return None  # uniform curvature: the over-bent arcs are exact
    want = _tensor(_loaded_map(target.k1, thickness_mm, material), _loaded_map(target.k2, thickness_mm, material),
                   target.dir1, target.dir2)
    have_c = curvatures(_Arcs(arcs), uu.ravel(), vv.ravel())
    have = _tensor(have_c.k1, have_c.k2, have_c.dir1, have_c.dir2)
    delta = [(w - h).reshape(uu.shape) for w, h in zip(want, have)]
    # first grid axis u, second v: the integrator's "x" is v (second axis), its "y" is u
    dz = integrate_hessian(delta[2], delta[1], delta[0], FIELD_SPACING_MM, FIELD_SPACING_MM)
    inside = (uu >= u0) & (uu <= u1) & (vv >= v0) & (vv <= v1)
    dz = without_plane(uu, vv, dz, inside)
    return RectBivariateSpline(u_ax, v_ax, dz, kx=3, ky=3, s=0)
