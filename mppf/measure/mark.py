"""The plate's reference mark: where it is on the design, and how a scan carries it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from mppf.core.errors import InputError
from mppf.core.transform import apply_tf
from mppf.planning.job import Job, reference_corner_xy

MARK_SUFFIX = ".mark.json"
"""The reference-corner mark of a scan ``S`` is read from ``S`` + this suffix, when present:
``{"reference_mark_mm": [x, y, z]}`` in the scan's coordinates (see ``docs/compare.md``)."""


def reference_mark(scan_path, design_points: np.ndarray, job: Job | None, mark_mm=None):
    """``(measured_xyz, design_xyz)`` of the reference mark for :func:`mppf.measure.compare.compare`, or None.

    The measured side is ``mark_mm`` (``compare --mark X,Y,Z``) when given, else it comes from
    ``<scan>.mark.json`` (:data:`MARK_SUFFIX`), written by the scanner software or the
    operator; the design side is the design point under the reference corner
    (:func:`design_mark`). None when there is neither.

    Raises
    ------
    InputError
        The mark file is unreadable or lacks three finite coordinates.
    """
    measured = read_mark(scan_path) if mark_mm is None else np.asarray(mark_mm, dtype=float).reshape(3)
    if measured is None:
        return None
    return measured, design_mark(design_points, job)


def read_mark(scan_path) -> np.ndarray | None:
    """The mark (3,) mm in the scan's coordinates from ``<scan>.mark.json``, or None when there is no such file.

    Raises
    ------
    InputError
        The mark file is unreadable or lacks three finite coordinates.
    """
    if scan_path is None:
        return None
    path = Path(str(scan_path) + MARK_SUFFIX)
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


def design_mark(design_points: np.ndarray, job: Job | None) -> np.ndarray:
    """The design point (3,) under the plate's reference corner.

    With a job that has a layout: the layout's reference corner on the press
    (:attr:`mppf.planning.job.PlateLayout.reference_corner_mm`), the design placed by the
    job. Without: :func:`mppf.planning.job.reference_corner_xy` of the design's outline in
    its own frame (u along its longest extent, v across; :mod:`mppf.geometry.frame`).
    """
    points = np.asarray(design_points, dtype=float)
    if job is not None and job.layout is not None:
        corner = job.layout.reference_corner_mm
        plane = apply_tf(job.tf_press_design, points)[:, :2]
    else:
        from mppf.core.polygon import convex_outline
        from mppf.geometry.frame import fit_frame

        plane = fit_frame(points).to_local(points)[:, :2]
        corner = reference_corner_xy(convex_outline(plane, "the design"))
    return points[int(np.argmin(np.linalg.norm(plane - corner, axis=1)))]
