"""The comparison's account of its set-aside points and of what it left out of the statistics.

:func:`set_aside_report` is the report of the set-aside points of the net plate (count, largest,
where on the press, how many a rescan cleared and how many another scan confirmed),
:func:`left_out_notes` the notes on the points left out, :func:`scan_index_of` the scan of each point
of a union of scans. Lengths in mm.
"""

from __future__ import annotations

import numpy as np

from mppf.core.errors import InputError
from mppf.core.transform import apply_tf
from mppf.measure.options import CompareOptions
from mppf.measure.outliers import SetAside
from mppf.measure.punches import nearest_punch


def set_aside_report(mask, dev, artefacts, options: CompareOptions, clearing) -> SetAside:
    """The report of the set-aside points of the net plate: count, largest, where (press, nearest punch), how many
    a rescan cleared (by which scan) and how many another scan confirmed.

    Parameters
    ----------
    mask : (n,) bool
        The set-aside points of the net plate.
    dev : mppf.measure.deviations.Deviation
        Every measured point's deviation.
    artefacts : mppf.measure.outliers.ArtefactTest
        The artefact test's result (point spacing, dense share).
    options : CompareOptions
        The tolerance, the press pose, the punch grid and how punches are named.
    clearing : mppf.measure.outliers.Clearing
        Which points a rescan cleared (by which scan) or confirmed.
    """
    tolerance_mm, tf_press_design = options.tolerance_mm, options.tf_press_design
    punch_xy_mm, label_base = options.punch_xy_mm, options.punch_label_base
    share, spacing = artefacts.dense_fraction, artefacts.spacing_mm
    confirmed = int((clearing.confirmed & mask).sum())
    if not mask.any():
        return SetAside(0, 0.0, 0, None, None, None, spacing, share)
    absolute = np.abs(dev.deviation_mm[mask])
    worst = int(np.flatnonzero(mask)[np.argmax(absolute)])
    press_xy = punch = None
    if tf_press_design is not None:
        press_xy = apply_tf(np.asarray(tf_press_design, dtype=float), dev.moved[worst][None])[0, :2]
        if punch_xy_mm is not None:
            punch = nearest_punch(np.asarray(punch_xy_mm, dtype=float), press_xy, label_base)
    cleared = clearing.cleared & mask
    by = dict(zip(*(v.tolist() for v in np.unique(clearing.cleared_by[cleared], return_counts=True))))
    beyond = int(np.sum(absolute > tolerance_mm)) - int(cleared.sum())
    return SetAside(int(mask.sum()), float(absolute.max()), beyond, dev.uv[worst].copy(), press_xy, punch, spacing,
                    share, int(cleared.sum()), by, confirmed)


def scan_index_of(scan_index, n: int) -> np.ndarray:
    """The (n,) int scan of each measured point (all 0 without ``scan_index``); InputError for another shape."""
    if scan_index is None:
        return np.zeros(n, dtype=int)
    index = np.asarray(scan_index)
    if index.shape != (n,) or not np.issubdtype(index.dtype, np.integer):
        raise InputError(f"scan_index must be ({n},) integers, one per measured point; got {index.shape} {index.dtype}",
                         hint="give the scan number (0, 1, ...) of each point, or leave it out")
    return index.astype(int)


def left_out_notes(set_aside, dev, margin_mm: float) -> list[str]:
    """Notes on the points left out of the statistics."""
    notes = [f"{int(set_aside.sum())} point(s) set aside and {int(dev.outside.sum())} point(s) outside the design "
             "left out of the statistics (the share within the tolerance counts the set-aside ones)"]
    if margin_mm > 0:
        notes.append(f"{int(dev.in_margin.sum())} point(s) in the trim margin ({margin_mm:g} mm) left out of the "
                     "statistics")
    return notes
