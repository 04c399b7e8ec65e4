"""The plate's reference mark: where it is on the design, and how a scan carries it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from mppf.core.errors import InputError
from mppf.core.transform import apply_tf
from mppf.planning.job import Job

MARK_SUFFIX = ".mark.json"
"""The reference-corner mark of a scan ``S`` is read from ``S`` + this suffix, when present:
``{"reference_mark_mm": [x, y, z]}`` in the scan's coordinates (see ``docs/compare.md``)."""


def reference_mark(scan_path, design_points: np.ndarray, job: Job):
    """``(measured_xyz, design_xyz)`` of the reference mark for :func:`mppf.measure.compare.compare`, or None.

    The measured side comes from ``<scan>.mark.json`` (:data:`MARK_SUFFIX`), written by the
    scanner software or the operator; the design side is the design point under the
    reference corner (:attr:`mppf.planning.job.PlateLayout.reference_corner_mm`) as the job placed the design on the press.
    None when there is no mark file or the job has no outline.

    Raises
    ------
    InputError
        The mark file is unreadable or lacks three finite coordinates.
    """
    path = Path(str(scan_path) + MARK_SUFFIX)
    if not path.is_file() or job.layout is None:
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
    corner = job.layout.reference_corner_mm
    design_press = apply_tf(job.tf_press_design, design_points)
    nearest = int(np.argmin(np.linalg.norm(design_press[:, :2] - corner, axis=1)))
    return measured, np.asarray(design_points, dtype=float)[nearest]
