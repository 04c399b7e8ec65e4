"""Simulated plate forming: from the punch tips of a press step to the formed plate.

The model, in three steps (see ``docs/compare.md``, section "The simulated plate"):

1. **Contact.** At every active punch pair the plate's mid-surface passes midway between
   the lower ball (top at ``lower_mm``) and the upper ball (bottom at ``upper_mm``):
   ``z = (lower + upper) / 2`` on the punch axis. (On a slope ``s = sqrt(1 + |grad z|^2)``
   the balls touch off-axis and hold the mid-surface at ``lower - r + (r + t/2) s`` and
   ``upper + r - (r + t/2) s``; the two slope terms cancel in the mean.)
2. **Loaded surface.** A thin-plate spline (:func:`mppf.core.grid.tps_fill`) through those
   mid-surface heights, evaluated on a regular grid covering the plate's outline.
3. **Springback.** The loaded surface's deviation ``w`` from its best-fit plane has the
   curvature tensor ``H`` (the Hessian of ``w``, small-slope approximation). Each principal
   curvature ``k_i`` is scaled by the elastic-plastic ratio ``R_i/R_f = 4x^3 - 3x + 1``,
   ``x = R_i sy' / (E' t)`` (:func:`mppf.forming.springback.springback_ratio`) with the plate's
   TRUE material and thickness. The scaled tensor field is integrated back to heights by
   sparse least squares; the unloaded plate keeps the loaded plate's best-fit plane.

Steps 2 and 3 are :mod:`mppf.forming.plate_model`, the plate model the planner also uses for its
springback pre-compensation (:mod:`mppf.forming.precompensate`) - there with the NOMINAL
material, here with the plate's true one, which the planner does not know.

Each press step is modelled on its own: the plate takes the shape the punches of that
step hold it in (all active punch pairs clamp the whole plate), so after a job the shape
is that of its last step. Everything is deterministic; the plate's scatter of properties
comes from :func:`sample_plate`, seeded.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.interpolate import RectBivariateSpline

from mppf.core import polygon
from mppf.core.errors import GeometryError, InputError
from mppf.core.validate import check_number, check_positive
from mppf.forming.plate_model import grid_axes, loaded_surface, spring_back
from mppf.model.material import Material
from mppf.model.press import PressConfig
from mppf.sim.plate.formed import grid_inside

GRID_SPACING_MM = 20.0
"""Spacing of the internal grid on which the loaded and unloaded surfaces are computed."""


@dataclass(frozen=True)
class PlateSample:
    """The TRUE properties of one physical plate (unknown to the planner).

    Attributes
    ----------
    thickness_mm : float
        Actual thickness.
    material : Material
        Actual material (the yield stress scatters; E and nu are taken as nominal).
    """

    thickness_mm: float
    material: Material


def sample_plate(
    thickness_mm: float,
    material: Material,
    seed: int,
    yield_scatter: float = 0.15,
    thickness_scatter: float = 0.03,
) -> PlateSample:
    """Draw a plate's true properties around the nominal ones, reproducibly.

    The yield stress is ``sy * (1 + yield_scatter * a)`` and the thickness
    ``t * (1 + thickness_scatter * b)`` with ``a, b`` independent standard normal numbers
    truncated to [-1, 1] (so the scatter values are hard bounds: +-15 % and +-3 % by
    default, about 2/3 of the plates within half of that).

    Parameters
    ----------
    thickness_mm : float
        Nominal thickness, mm (> 0).
    material : Material
        Nominal material.
    seed : int
        Seed of the random generator; the same seed gives the same plate.
    yield_scatter, thickness_scatter : float
        Relative bounds of the scatter, in [0, 0.9].

    Returns
    -------
    PlateSample
    """
    check_positive("the plate thickness", thickness_mm, unit="mm")
    for name, value in (("yield_scatter", yield_scatter), ("thickness_scatter", thickness_scatter)):
        check_number(name, value, low=0.0, high=0.9)
    rng = np.random.default_rng(seed)
    a, b = _truncated_normal(rng, 2)
    true_material = replace(material, yield_stress_mpa=material.yield_stress_mpa * (1.0 + yield_scatter * a))
    return PlateSample(thickness_mm=float(thickness_mm * (1.0 + thickness_scatter * b)), material=true_material)


def _truncated_normal(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` standard normal numbers redrawn until within [-1, 1]."""
    out = rng.standard_normal(n)
    while np.any(np.abs(out) > 1.0):
        bad = np.abs(out) > 1.0
        out[bad] = rng.standard_normal(int(bad.sum()))
    return out


@dataclass(frozen=True, eq=False)
class FormedPlate:
    """A plate after a press step, in press coordinates (mm).

    The surfaces are height fields ``z(x, y)`` on a regular grid (``x_mm`` along the
    press columns, ``y_mm`` along the rows); the plate covers the polygon ``outline_xy_mm``.

    Attributes
    ----------
    x_mm : (nx,) float
    y_mm : (ny,) float
    loaded_z_mm : (ny, nx) float
        Mid-surface while held between the punches.
    unloaded_z_mm : (ny, nx) float
        Mid-surface after springback.
    outline_xy_mm : (k, 2) float
        The plate's outline in press x, y.
    plate : PlateSample
        The true thickness and material used.
    contact_xyz_mm : (m, 3) float
        Mid-surface points at the active punch axes (loaded).
    mean_ratio : float
        Mean springback ratio R_i/R_f over the plate (1 = no springback).
    """

    x_mm: np.ndarray
    y_mm: np.ndarray
    loaded_z_mm: np.ndarray
    unloaded_z_mm: np.ndarray
    outline_xy_mm: np.ndarray
    plate: PlateSample
    contact_xyz_mm: np.ndarray
    mean_ratio: float

    @property
    def thickness_mm(self) -> float:
        """True thickness of the plate."""
        return self.plate.thickness_mm

    def _spline(self, loaded: bool) -> RectBivariateSpline:
        z = self.loaded_z_mm if loaded else self.unloaded_z_mm
        return RectBivariateSpline(self.y_mm, self.x_mm, z, kx=3, ky=3, s=0)

    def height_mm(self, x_mm, y_mm, *, loaded: bool = False) -> np.ndarray:
        """Mid-surface height z at press positions (x, y) (any matching shapes), mm."""
        x = np.asarray(x_mm, dtype=float)
        y = np.asarray(y_mm, dtype=float)
        return self._spline(loaded).ev(y, x)

    def sample_xy(self, spacing_mm: float) -> np.ndarray:
        """Press (x, y) (n, 2) of a regular grid of ``spacing_mm`` inside the outline (:func:`grid_inside`)."""
        return grid_inside(self.outline_xy_mm, spacing_mm)

    def mid_surface_points(self, spacing_mm: float = GRID_SPACING_MM, *, loaded: bool = False) -> np.ndarray:
        """Mid-surface points on a regular x, y grid inside the outline.

        Parameters
        ----------
        spacing_mm : float
            Grid spacing in press x and y.
        loaded : bool
            The loaded surface instead of the unloaded (sprung-back) one.

        Returns
        -------
        (n, 3) float, press coordinates, mm
        """
        xy = self.sample_xy(spacing_mm)
        return np.column_stack([xy, self._spline(loaded).ev(xy[:, 1], xy[:, 0])])

    def skin_points(self, spacing_mm: float = GRID_SPACING_MM, side: float = 1.0) -> np.ndarray:
        """Points of a skin of the unloaded plate: the mid-surface offset by ``side * t/2``.

        Parameters
        ----------
        spacing_mm : float
            Grid spacing in press x, y of the mid-surface points offset.
        side : float
            +1 for the top skin, -1 for the bottom skin, 0 for the mid-surface.

        Returns
        -------
        (n, 3) float, press coordinates, mm
        """
        xy = self.sample_xy(spacing_mm)
        return self.offset_points(xy, side * 0.5 * self.thickness_mm)

    def top_skin_points(self, spacing_mm: float = GRID_SPACING_MM) -> np.ndarray:
        """Top-skin points of the unloaded plate (mid-surface + t/2 along the up normal), (n, 3) mm."""
        return self.skin_points(spacing_mm, side=1.0)

    def offset_points(self, xy_mm, offset_mm: float) -> np.ndarray:
        """Unloaded mid-surface points above ``xy_mm`` (m, 2) moved ``offset_mm`` along the up normal.

        Returns
        -------
        (m, 3) float, press coordinates, mm
        """
        xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
        spline = self._spline(False)
        z = spline.ev(xy[:, 1], xy[:, 0])
        zx = spline.ev(xy[:, 1], xy[:, 0], dy=1)
        zy = spline.ev(xy[:, 1], xy[:, 0], dx=1)
        normal = np.column_stack([-zx, -zy, np.ones_like(z)])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        return np.column_stack([xy, z]) + offset_mm * normal

    def normals(self, xy_mm) -> np.ndarray:
        """Unit up normals (m, 3) of the unloaded mid-surface above ``xy_mm`` (m, 2)."""
        xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
        return self.offset_points(xy, 1.0) - self.offset_points(xy, 0.0)


def form_plate(press: PressConfig, upper_mm, lower_mm, active, plate: PlateSample, outline_xy_mm=None, *,
               grid_spacing_mm: float = GRID_SPACING_MM) -> FormedPlate:
    """Form a plate between the punch tips of one press step, then let it spring back.

    Parameters
    ----------
    press : PressConfig
    upper_mm, lower_mm : (rows, cols) float
        Tip heights in press z (the actual positions read back from the PLC); entries
        of inactive punches are ignored (may be NaN).
    active : (rows, cols) bool
        Punch pairs that hold the plate; at least 3, not all in one line.
    plate : PlateSample
        The plate's true thickness and material.
    outline_xy_mm : (k, 2) float, optional
        The plate's outline in press x, y (e.g. the flat plate's corners mapped by the
        job's ``tf_press_flat``). Default: the rectangle of the active punches grown by
        half a pitch.
    grid_spacing_mm : float
        Spacing of the internal computation grid.

    Returns
    -------
    FormedPlate

    Raises
    ------
    InputError
        Grids of the wrong shape, NaN tip heights at active punches, upper below lower.
    GeometryError
        Too few active punches, or an outline that is not a polygon of at least 3 points.
    """
    upper, lower, act = check_step_grids(press, upper_mm, lower_mm, active)
    _check_gap(upper[act] - lower[act], plate.thickness_mm)
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    xy_contact = np.column_stack([px[act], py[act]])
    outline = _outline(press, act, outline_xy_mm)

    # 1. contact heights at the punch axes: midway between the lower and the upper ball.
    # On a slope s = sqrt(1 + |grad z|^2) the lower ball holds the mid-surface at
    # (lower - r) + (r + t/2) s and the upper ball at (upper + r) - (r + t/2) s; their mean,
    # the value used, is (lower + upper) / 2 whatever the slope.
    z_contact = 0.5 * (lower[act] + upper[act])

    # 2. loaded mid-surface: thin-plate spline through the contact heights
    x_mm, y_mm = grid_axes(outline, grid_spacing_mm)
    loaded = loaded_surface(xy_contact, z_contact, x_mm, y_mm)

    # 3. springback of the principal curvatures, integrated back to heights
    unloaded, mean_ratio = spring_back(x_mm, y_mm, loaded, plate.thickness_mm, plate.material, outline)
    return FormedPlate(
        x_mm=x_mm,
        y_mm=y_mm,
        loaded_z_mm=loaded,
        unloaded_z_mm=unloaded,
        outline_xy_mm=outline,
        plate=plate,
        contact_xyz_mm=np.column_stack([xy_contact, z_contact]),
        mean_ratio=mean_ratio,
    )


def _check_gap(gap_mm: np.ndarray, thickness_mm: float) -> None:
    """InputError where the gap between upper and lower tips ((k,) mm, active punches) is under half the plate."""
    if np.any(gap_mm < thickness_mm * 0.5):
        i = int(np.argmin(gap_mm))
        raise InputError(
            f"the gap between upper and lower tips is {gap_mm[i]:.3f} mm at an active punch, less than half "
            f"the plate thickness {thickness_mm:.3f} mm",
            hint="the step would crush the plate; check the strokes",
        )


def check_step_grids(press: PressConfig, upper_mm, lower_mm, active):
    """The tip heights and active punches of one press step as arrays, checked against the press.

    Parameters
    ----------
    press : PressConfig
    upper_mm, lower_mm : (rows, cols) float, mm
        Tip heights of the upper and lower matrix.
    active : (rows, cols) bool
        The punches under the plate.

    Returns
    -------
    upper : (rows, cols) float, mm
    lower : (rows, cols) float, mm
    active : (rows, cols) bool

    Raises
    ------
    InputError
        A grid of another shape than the press's, a NaN or infinite height at an active punch.
    GeometryError
        Fewer than 3 active punches.
    """
    shape = press.shape
    upper = np.asarray(upper_mm, dtype=float)
    lower = np.asarray(lower_mm, dtype=float)
    act = np.asarray(active, dtype=bool)
    for name, arr in (("upper_mm", upper), ("lower_mm", lower), ("active", act)):
        if arr.shape != shape:
            raise InputError(f"{name} has shape {arr.shape}, the press has {shape}")
    if act.sum() < 3:
        raise GeometryError(f"a plate needs at least 3 active punches, got {int(act.sum())}")
    if not (np.all(np.isfinite(upper[act])) and np.all(np.isfinite(lower[act]))):
        raise InputError("NaN or infinite tip height at an active punch", hint="every active punch needs a height")
    return upper, lower, act


def _outline(press: PressConfig, act: np.ndarray, outline_xy_mm) -> np.ndarray:
    if outline_xy_mm is None:
        rows, cols = np.nonzero(act)
        x, y = press.punch_x_mm, press.punch_y_mm
        x0, x1 = x[cols.min()] - press.pitch_x_mm / 2, x[cols.max()] + press.pitch_x_mm / 2
        y0, y1 = y[rows.min()] - press.pitch_y_mm / 2, y[rows.max()] + press.pitch_y_mm / 2
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    outline = np.asarray(outline_xy_mm, dtype=float)
    if outline.ndim != 2 or outline.shape[1] != 2 or outline.shape[0] < 3 or not np.all(np.isfinite(outline)):
        raise GeometryError(f"the plate outline must be a polygon (k >= 3, 2) in mm, got shape {outline.shape}")
    if abs(polygon.area(outline)) <= 0:
        raise GeometryError("the plate outline has no area", hint="give the corners of the flat plate in press x, y")
    return outline

