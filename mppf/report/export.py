"""Per-point export of a comparison: PLY (binary, CloudCompare scalar fields) or CSV.

Every measured point, moved into design coordinates (mm), with its values
(``docs/compare.md``, "Export"):

- ``deviation``: the signed normal deviation (mm; + on the design's +normal side),
- ``form_deviation``: the form deviation (mm; NaN where none: outside or set aside),
- ``inlier``, ``set_aside``, ``outside``, ``margin``: flags (1 or 0).

In a PLY file they are vertex properties named ``scalar_<name>`` (``scalar_deviation``, ...),
which CloudCompare loads as scalar fields (named without the prefix); in a CSV file they are
columns after ``x_mm, y_mm, z_mm``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mppf.core.errors import InputError
from mppf.measure.result import Comparison

EXPORT_SUFFIXES = (".ply", ".csv")
"""The file types of ``--export``."""

SCALAR_PREFIX = "scalar_"
"""PLY vertex properties with this prefix are scalar fields in CloudCompare."""


def point_fields(comparison: Comparison) -> dict[str, np.ndarray]:
    """The exported values of every point, by name (each (n,)): deviation, form deviation, the four flags."""
    c = comparison
    form = c.form_deviation_mm if c.form_deviation_mm is not None else np.full(c.n_points, np.nan)
    return {
        "deviation": np.asarray(c.deviation_mm, dtype=float),
        "form_deviation": np.asarray(form, dtype=float),
        "inlier": c.inlier.astype(np.uint8),
        "set_aside": c.is_outlier.astype(np.uint8),
        "outside": c.is_outside.astype(np.uint8),
        "margin": c.in_margin.astype(np.uint8),
    }


def export_points(comparison: Comparison, path) -> Path:
    """Write the per-point export to ``path`` (.ply binary little-endian, or .csv); return the path.

    Raises
    ------
    InputError
        Another suffix.
    OSError
        The file cannot be written.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in EXPORT_SUFFIXES:
        raise InputError(f"cannot export to {path}: unknown file type {suffix or '(none)'}",
                         hint="give a .ply (CloudCompare scalar fields) or .csv file name")
    xyz = np.asarray(comparison.measured_in_design, dtype=float)
    fields = point_fields(comparison)
    if suffix == ".ply":
        _write_ply(path, xyz, fields)
    else:
        _write_csv(path, xyz, fields)
    return path


def _write_ply(path: Path, xyz: np.ndarray, fields: dict) -> None:
    from plyfile import PlyData, PlyElement

    dtype = [("x", "f8"), ("y", "f8"), ("z", "f8")]
    dtype += [(SCALAR_PREFIX + name, "f8" if values.dtype.kind == "f" else "u1") for name, values in fields.items()]
    vertex = np.empty(xyz.shape[0], dtype=dtype)
    vertex["x"], vertex["y"], vertex["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    for name, values in fields.items():
        vertex[SCALAR_PREFIX + name] = values
    element = PlyElement.describe(vertex, "vertex")
    PlyData([element], text=False, byte_order="<",
            comments=["mppf comparison: points in design coordinates (mm), scalar_* per-point values"]).write(str(path))


def _write_csv(path: Path, xyz: np.ndarray, fields: dict) -> None:
    header = ",".join(["x_mm", "y_mm", "z_mm", "deviation_mm", "form_deviation_mm", "inlier", "set_aside", "outside",
                       "margin"])
    table = np.column_stack([xyz, *fields.values()])
    formats = ["%.4f"] * 5 + ["%d"] * 4
    np.savetxt(path, table, delimiter=",", header=header, comments="", fmt=formats)
