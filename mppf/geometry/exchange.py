"""The yard's exchange formats behind :func:`mppf.geometry.read.read_points`: CAD and scanner files.

=====================  ==============================================  ======================
suffix                 what is read                                    length unit
=====================  ==============================================  ======================
``.igs`` ``.iges``     IGES trimmed surfaces, tessellated              the file's (converted to mm)
``.stp`` ``.step``     STEP faces, tessellated                         the file's (converted to mm)
``.e57``               every scan, its pose applied                    metres (the standard)
``.las`` ``.laz``      the points, scale and offset applied            ``units`` (usually m)
=====================  ==============================================  ======================

Every result is further multiplied by ``scale`` (a model-scale file to full size). A CAD
file is tessellated at ``chord_tolerance_mm`` (at full scale; see :mod:`mppf.geometry.cad`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mppf.core.errors import FileFormatError
from mppf.geometry.cad_files import CAD_SUFFIXES, CHORD_TOLERANCE_MM
from mppf.geometry.files import sha256_of
from mppf.geometry.scans import E57_SUFFIXES, LAS_SUFFIXES, SCAN_SUFFIXES

EXCHANGE_SUFFIXES = CAD_SUFFIXES + SCAN_SUFFIXES

__all__ = ["CHORD_TOLERANCE_MM", "EXCHANGE_SUFFIXES", "read_exchange"]


def read_exchange(path, *, unit_scale: float, scale: float,
                  chord_tolerance_mm: float = CHORD_TOLERANCE_MM) -> tuple[np.ndarray, np.ndarray | None, str]:
    """Read a CAD or scanner file: points (n, 3) mm, triangles or None, SHA-256 of the file.

    Parameters
    ----------
    path : Path
    unit_scale : float
        mm per unit of the file, for formats without a declared unit (LAS / LAZ).
    scale : float
        Model scale factor (all formats).
    chord_tolerance_mm : float
        Chordal tolerance of a CAD tessellation, mm at full scale.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    faces = None
    if suffix in CAD_SUFFIXES:
        from mppf.geometry.cad_mesh import read_cad_mesh

        points, faces = read_cad_mesh(path, scale=scale, chord_tolerance_mm=chord_tolerance_mm)
    elif suffix in E57_SUFFIXES:
        from mppf.geometry.scans import read_e57

        points = read_e57(path) * scale
    elif suffix in LAS_SUFFIXES:
        from mppf.geometry.scans import read_las

        points = read_las(path, unit_scale) * scale
    else:
        raise FileFormatError(path, f"is not a CAD or scanner file ({', '.join(EXCHANGE_SUFFIXES)})")
    bad = ~np.all(np.isfinite(points), axis=1)
    if bad.any():
        first = int(np.argmax(bad))
        raise FileFormatError(path, f"point {first} has a NaN or infinite coordinate {points[first].tolist()}",
                              hint="remove or repair invalid points in the source program")
    return points, faces, sha256_of(path)
