"""The plate's reference mark: where it is on the design, and how a scan carries it.

The mark is the corner of the plate AS CUT (the net outline grown by the trim margin: the
physical corner the operator sees and the cutter's DXF marks), the one with the smallest
press x + y (:func:`mppf.model.job_parts.reference_corner_xy`,
:attr:`mppf.model.job_parts.PlateLayout.reference_corner_mm`). A scan carries it in the mark
file beside it, ``<scan>.mark.json`` (:data:`MARK_SUFFIX`), or in its header where the format
has room for a line of text (:func:`mppf.geometry.scans.read_header_mark`); the mark file
wins when there are both. See ``docs/file-formats.md``, "The reference mark".
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from mppf.core.errors import GeometryError, InputError
from mppf.core.transform import apply_tf, invert_tf
from mppf.geometry.scans import read_header_mark
from mppf.model.job import Job
from mppf.model.job_parts import reference_corner_xy

MARK_SUFFIX = ".mark.json"
"""The reference-corner mark of a scan ``S`` is read from ``S`` + this suffix, when present:
``{"reference_mark_mm": [x, y, z]}`` in the scan's coordinates (see ``docs/compare.md``)."""

EXTRAPOLATION_POINTS = 200
"""Design points nearest the corner that the design surface is extended through to a corner off the design."""


def mark_path(scan_path) -> Path:
    """The mark file of a scan: ``<scan>`` + :data:`MARK_SUFFIX`."""
    return Path(str(scan_path) + MARK_SUFFIX)


def reference_mark(scan_path, design_points: np.ndarray, job: Job | None, mark_mm=None, *, margin_mm: float = 0.0):
    """``(measured_xyz, design_xyz)`` of the reference mark for :func:`mppf.measure.compare.compare`, or None.

    The measured side is ``mark_mm`` (``compare --mark X,Y,Z``) when given, else it comes from
    ``<scan>.mark.json`` (:data:`MARK_SUFFIX`), written by the scanner software or the
    operator, else from the scan file's header (:func:`read_scan_mark`); the design side is
    the design surface under the reference corner of the plate as cut (:func:`design_mark`).
    None when there is no mark.

    Parameters
    ----------
    margin_mm : float
        Without a job layout: the trim margin the plate was cut with (0: cut to its net outline).

    Raises
    ------
    InputError
        The mark file is unreadable or lacks three finite coordinates.
    """
    measured = read_scan_mark(scan_path) if mark_mm is None else np.asarray(mark_mm, dtype=float).reshape(3)
    if measured is None:
        return None
    return measured, design_mark(design_points, job, margin_mm=margin_mm)


def read_scan_mark(scan_path) -> np.ndarray | None:
    """The mark (3,) mm a scan carries: its mark file (:func:`read_mark`), else its header; None without either.

    Raises
    ------
    InputError
        The mark file is unreadable or lacks three finite coordinates.
    """
    if scan_path is None:
        return None
    measured = read_mark(scan_path)
    return read_header_mark(scan_path) if measured is None else measured


def read_mark(scan_path) -> np.ndarray | None:
    """The mark (3,) mm in the scan's coordinates from ``<scan>.mark.json``, or None when there is no such file.

    Raises
    ------
    InputError
        The mark file is unreadable or lacks three finite coordinates.
    """
    if scan_path is None:
        return None
    path = mark_path(scan_path)
    if not path.is_file():
        return None
    try:
        measured = np.asarray(json.loads(path.read_text())["reference_mark_mm"], dtype=float).reshape(3)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(f"cannot read the reference mark {path}: {exc}",
                         hint='it must hold {"reference_mark_mm": [x, y, z]} in the scan\'s coordinates, '
                              "or delete it to register without the mark") from None
    if not np.all(np.isfinite(measured)):
        raise InputError(f"the reference mark in {path} is not finite: {measured.tolist()}",
                         hint="pick the mark again, or delete the file to register without it")
    return measured


def design_mark(design_points: np.ndarray, job: Job | None, *, margin_mm: float = 0.0) -> np.ndarray:
    """The point (3,) of the design surface, design coordinates, under the reference corner of the plate as cut.

    With a job that has a layout: the layout's reference corner on the press
    (:attr:`mppf.model.job_parts.PlateLayout.reference_corner_mm`, a corner of the outline as
    cut), the design placed by the job. Without: :func:`mppf.model.job_parts.reference_corner_xy`
    of the design's convex outline grown by ``margin_mm``, in the design's own frame (u along
    its longest extent, v across; :mod:`mppf.geometry.frame`). The corner of a plate cut with
    a margin lies off the design: the design surface is extended to it
    (:func:`_surface_at`).
    """
    points = np.asarray(design_points, dtype=float)
    if job is not None and job.layout is not None:
        tf = np.asarray(job.tf_press_design, dtype=float)
        return apply_tf(invert_tf(tf), _surface_at(apply_tf(tf, points), job.layout.reference_corner_mm)[None])[0]
    from mppf.core.polygon import convex_outline, offset_convex
    from mppf.geometry.frame import fit_frame

    frame = fit_frame(points)
    local = frame.to_local(points)
    outline = convex_outline(local[:, :2], "the design")
    if margin_mm > 0:
        outline = offset_convex(outline, float(margin_mm))
    return frame.to_world(_surface_at(local, reference_corner_xy(outline))[None])[0]


def _surface_at(points: np.ndarray, corner_xy) -> np.ndarray:
    """The surface through ``points`` (n, 3) at ``corner_xy`` (2,): a point of it, or the surface extended.

    A corner on a design point (a plate cut to its net outline) is that point; a corner off
    the design (the trim margin) gets the height of a quadratic fitted to the
    :data:`EXTRAPOLATION_POINTS` design points nearest it (the nearest point's height when
    they do not determine one).
    """
    corner = np.asarray(corner_xy, dtype=float).reshape(2)
    distance = np.linalg.norm(points[:, :2] - corner, axis=1)
    nearest = int(np.argmin(distance))
    if distance[nearest] <= 1e-6:
        return points[nearest].copy()
    from mppf.geometry.polynomial import fit_polynomial

    near = points[np.argsort(distance)[: min(len(points), EXTRAPOLATION_POINTS)]]
    try:
        height = float(fit_polynomial(near[:, 0], near[:, 1], near[:, 2], degree=2).evaluate(corner[0], corner[1]))
    except (GeometryError, InputError):  # too few or collinear points: the nearest one's height
        height = float(points[nearest, 2])
    return np.array([corner[0], corner[1], height])
