"""Writing point files (``.csv``, ``.txt``, ``.xyz``, ``.ply``): the counterpart of :mod:`mppf.geometry.read`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mppf.core.errors import InputError
from mppf.core.transform import as_points
from mppf.geometry.read import PLY_SUFFIXES, TEXT_SUFFIXES

WRITE_SUFFIXES = TEXT_SUFFIXES + PLY_SUFFIXES


def write_points(path, points, header: str | None = None, *, faces=None) -> Path:
    """Write points (mm) to a ``.csv``, ``.txt``, ``.xyz`` or ``.ply`` file.

    Text files get a ``#`` comment line (``header`` or ``x_mm,y_mm,z_mm``) and one
    point per line with the shortest decimal that reads back to the same float. PLY
    files are binary little-endian; ``faces`` ((m, 3) int) are written to PLY only.

    Parameters
    ----------
    path : str or Path
    points : (n, 3) float, mm
    header : str, optional
        One comment line (text) or PLY comment.
    faces : (m, 3) int, optional
        Triangles (PLY only).

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    InputError
        Unknown suffix, faces for a text file, or the file cannot be written.
    """
    path = Path(path)
    pts = as_points(points)
    suffix = path.suffix.lower()
    if suffix not in WRITE_SUFFIXES:
        raise InputError(
            f"cannot write {path}: unknown point file type {path.suffix or '(no suffix)'!r}",
            hint=f"use one of {', '.join(WRITE_SUFFIXES)}",
        )
    if header is not None and ("\n" in header or "\r" in header):
        raise InputError(f"header must be one line, got {header!r}")
    try:
        if suffix in PLY_SUFFIXES:
            _write_ply(path, pts, header, faces)
        else:
            if faces is not None:
                raise InputError(f"cannot write faces to {path}", hint="write meshes as .ply")
            sep = "," if suffix == ".csv" else " "
            first = header if header is not None else sep.join(("x_mm", "y_mm", "z_mm"))
            body = "\n".join(sep.join(map(repr, row)) for row in pts.tolist())
            path.write_text(f"# {first}\n{body}\n", encoding="utf-8")
    except OSError as exc:
        raise InputError(
            f"cannot write {path}: {exc.strerror or exc}",
            hint="check that the folder exists and is writable",
        ) from None
    return path


def _write_ply(path: Path, pts: np.ndarray, header: str | None, faces) -> None:
    import plyfile

    vertex = np.empty(pts.shape[0], dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    vertex["x"], vertex["y"], vertex["z"] = pts.T
    elements = [plyfile.PlyElement.describe(vertex, "vertex")]
    if faces is not None:
        tri = np.asarray(faces, dtype=np.int64)
        if tri.ndim != 2 or tri.shape[1] != 3 or (tri.size and (tri.min() < 0 or tri.max() >= len(pts))):
            raise InputError(f"faces must be (m, 3) indices below {len(pts)}, got shape {tri.shape}")
        face = np.empty(tri.shape[0], dtype=[("vertex_indices", "i4", (3,))])
        face["vertex_indices"] = tri
        elements.append(plyfile.PlyElement.describe(face, "face"))
    comments = [header] if header else []
    plyfile.PlyData(elements, text=False, byte_order="<", comments=comments).write(str(path))
