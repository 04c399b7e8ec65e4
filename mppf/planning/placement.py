"""Placement: the flat plate on the press bed, and the design registered onto it.

Press coordinates (see ``docs/press.md``): origin at the matrix centre, x along the
columns, z up; the flat plate's bottom skin lies at z = 0, so its mid-surface at
z = t/2. Point files hold the plate's mid-surface. See ``docs/planning.md``. Whether the
flat belongs to the design is :mod:`mppf.planning.belongs`; the offset and tilt of least
travel :mod:`mppf.planning.pose`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from mppf.core.errors import GeometryError, LimitError
from mppf.core.progress import NULL_REPORTER
from mppf.core.transform import apply_tf, make_tf
from mppf.geometry.frame import fit_frame
from mppf.model.press import PressConfig
from mppf.registration.register import Registration, register_icp, register_paired
from mppf.registration.settings import RegisterOptions

FLATNESS_FRACTION = 0.01
"""A flat plate may deviate from its plane by at most this fraction of its size."""


@dataclass(frozen=True, eq=False)
class FlatPlacement:
    """The flat plate lying on the bed.

    Attributes
    ----------
    tf_press_flat : (4, 4) float
        Maps the flat file's coordinates into press coordinates (mid-surface at z = t/2).
    flat_press_mm : (n, 3) float
        The flat's points in press coordinates.
    size_mm : (2,) float
        Extent of the flat along x and y.
    corners_mm : (4, 3) float
        The plate corners on the bed (bottom skin, z = 0), in the order
        (-x, -y), (+x, -y), (+x, +y), (-x, +y): where the operator puts the plate.
    """

    tf_press_flat: np.ndarray
    flat_press_mm: np.ndarray
    size_mm: np.ndarray
    corners_mm: np.ndarray


def place_flat(flat_points, press: PressConfig, thickness_mm: float) -> FlatPlacement:
    """Lay the flat plate on the bed: centred, longer side along x, bottom skin at z = 0.

    Parameters
    ----------
    flat_points : (n, 3) float, mm
        The flat plate's mid-surface in any coordinates.
    press : PressConfig
    thickness_mm : float

    Raises
    ------
    GeometryError
        The "flat" plate is not flat.
    LimitError
        The plate does not fit between the outermost punch axes.
    """
    placement = lay_flat(flat_points, press, thickness_mm)
    bed = np.array(press.bed_size_mm)
    if not fits_bed(placement, press):
        extent = placement.size_mm
        raise LimitError(
            f"the plate ({extent[0]:.0f} x {extent[1]:.0f} mm) does not fit on the bed of "
            f"{press.name} ({bed[0]:.0f} x {bed[1]:.0f} mm between the outermost punch axes)",
            hint="plan it in sections (docs/sections.md: 'mppf batch' does) or use a larger press",
        )
    return placement


def fits_bed(placement: FlatPlacement, press: PressConfig) -> bool:
    """Does the (net) flat plate fit between the outermost punch axes?"""
    return bool(np.all(placement.size_mm <= np.array(press.bed_size_mm) + 1e-6))


def lay_flat(flat_points, press: PressConfig, thickness_mm: float) -> FlatPlacement:
    """Lay the flat plate as :func:`place_flat` does, on a bed of any size (no size check).

    The plate coordinates of sectional forming (:mod:`mppf.planning.sections`).

    Raises
    ------
    GeometryError
        The "flat" plate is not flat.
    """
    frame = fit_frame(flat_points)
    local = frame.to_local(flat_points)
    size = float(np.ptp(local[:, :2], axis=0).max())
    bow = float(np.abs(local[:, 2]).max())
    if bow > FLATNESS_FRACTION * size:
        raise GeometryError(
            f"the flat plate is not flat: its points lie up to {bow:.1f} mm from their best plane "
            f"(allowed {FLATNESS_FRACTION * size:.1f} mm for a {size:.0f} mm plate)",
            hint="give the unfolded (flat) plate as the second file, e.g. from 'mppf unfold'",
        )
    # u (longest spread) along x, then centre the bounding box, mid-surface at t/2
    tf_press_local = make_tf(np.eye(3), [0.0, 0.0, thickness_mm / 2.0])
    if press.cols * press.pitch_x_mm < press.rows * press.pitch_y_mm:  # longer axis is y
        tf_press_local[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    tf_press_flat = tf_press_local @ frame.tf_local_world
    flat_press = apply_tf(tf_press_flat, flat_points)
    centre = (flat_press[:, :2].min(axis=0) + flat_press[:, :2].max(axis=0)) / 2.0
    tf_press_flat = make_tf(translation=[-centre[0], -centre[1], 0.0]) @ tf_press_flat
    flat_press = apply_tf(tf_press_flat, flat_points)
    extent = np.ptp(flat_press[:, :2], axis=0)
    return FlatPlacement(tf_press_flat, flat_press, extent, _corners(flat_press, extent))


def _corners(flat_press, extent) -> np.ndarray:
    """(4, 3): the flat's points nearest the corners of its bounding box, on the lower tips (z = 0)."""
    half = extent / 2.0
    box = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * half
    _, nearest = cKDTree(flat_press[:, :2]).query(box)
    return np.column_stack([flat_press[nearest, :2], np.zeros(4)])


def register_design(design_points, flat_press_mm, reporter=NULL_REPORTER) -> Registration:
    """Register the design onto the flat plate lying on the bed (gives ``tf_press_design``).

    Paired (closed form) when both have the same number of points, which the
    unfolding keeps in order; ICP point-to-point from the principal axes otherwise.

    Returns
    -------
    Registration
        ``tf`` maps design coordinates into press coordinates.
    """
    design = np.asarray(design_points, dtype=float)
    flat = np.asarray(flat_press_mm, dtype=float)
    if design.shape == flat.shape:
        return register_paired(design, flat)
    return register_icp(design, flat, RegisterOptions(method="point", init="principal"), reporter=reporter)
