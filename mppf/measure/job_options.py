"""A comparison of a scan of a planned plate: what the job says (margin, skin, punch grid, press pose, mark).

``mppf compare --job JOB.json`` and the loop (:mod:`mppf.loop.measuring`) judge a scan with the
same options, so the same scan gets the same verdict from both (``docs/compare.md``, "With
the job").
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from mppf.measure.mark import reference_mark
from mppf.measure.options import CompareOptions
from mppf.model.job import Job


def job_compare_options(job: Job, design_points: np.ndarray, scan_path=None, *, offset_mm: float | None = None,
                        mark_mm=None, base: CompareOptions | None = None) -> CompareOptions:
    """The options of :func:`mppf.measure.compare.compare` for a scan of the plate of ``job``.

    Parameters
    ----------
    job : Job
    design_points : (m, 3) float, mm
        The design (mid-surface).
    scan_path : path, optional
        The scan file: its ``<scan>.mark.json`` gives the reference mark when present.
    offset_mm : float, optional
        The measured skin's offset from the mid-surface; default ``+thickness / 2`` (the
        scanner sees the top skin).
    mark_mm : (3,) float, optional
        The reference mark in the scan's coordinates (overrides the mark file).
    base : CompareOptions, optional
        The options the job's are set on (tolerances, gaps, ...); default the defaults.

    Returns
    -------
    CompareOptions
        ``base`` with the job's ``offset_mm``, ``punch_xy_mm`` (rows, cols, 2), ``tf_press_design``,
        ``reference_mark``, ``margin_mm`` (the layout's trim margin), ``punch_label_base`` (the press's).
    """
    x, y = np.meshgrid(job.punch_x_mm, job.punch_y_mm)
    return replace(
        CompareOptions() if base is None else base,
        offset_mm=job.thickness_mm / 2.0 if offset_mm is None else float(offset_mm),
        punch_xy_mm=np.stack([x, y], axis=-1),
        tf_press_design=job.tf_press_design,
        reference_mark=reference_mark(scan_path, design_points, job, mark_mm),
        margin_mm=0.0 if job.layout is None else job.layout.margin_mm,
        punch_label_base=int(job.press.label_base),
    )
