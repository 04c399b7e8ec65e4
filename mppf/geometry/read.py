"""Reading point and mesh files (with :mod:`mppf.geometry.write`, the only file I/O of the geometry core).

Supported formats (see ``docs/file-formats.md``, section "Point and mesh files"):

=================  ===========================================================
suffix             content
=================  ===========================================================
``.csv``           text, comma separated (whitespace also accepted per line)
``.txt`` ``.xyz``  text, whitespace or comma separated
``.ply``           PLY, ASCII or binary (``plyfile``); faces kept if present
``.stl``           STL, ASCII or binary (``trimesh``); duplicate vertices merged
``.obj``           Wavefront OBJ (``trimesh``); faces kept if present
``.igs`` ``.stp``  IGES / STEP surfaces, tessellated (:mod:`mppf.geometry.exchange`)
``.e57`` ``.las``  laser scans: E57 (poses applied), LAS / LAZ (``.laz``)
=================  ===========================================================

Text files: blank lines and ``#`` comments (whole line or trailing) are skipped;
header lines (every field non-numeric) are allowed before the first data line; each
data line has the same number of columns, at least three; the first three are x, y, z
and further columns (intensity, colour, ...) are ignored.

Every problem is a :class:`~mppf.core.errors.FileFormatError` naming the file, and the line
where it applies. Lengths come back in millimetres (``units="m"`` scales by 1000; CAD and
E57 files declare their unit), times ``scale`` for model-scale files.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mppf.core.errors import FileFormatError, InputError
from mppf.core.validate import check_positive
from mppf.geometry.exchange import CHORD_TOLERANCE_MM, EXCHANGE_SUFFIXES
from mppf.geometry.files import check_fits
from mppf.geometry.mesh_checks import check_mesh_bytes
from mppf.geometry.text_points import parse_text

TEXT_SUFFIXES = (".csv", ".txt", ".xyz")
PLY_SUFFIXES = (".ply",)
MESH_SUFFIXES = (".stl", ".obj")
READ_SUFFIXES = TEXT_SUFFIXES + PLY_SUFFIXES + MESH_SUFFIXES + EXCHANGE_SUFFIXES

TEXT_BYTES_PER_FILE_BYTE = 40
"""Memory a text, PLY or mesh file takes while parsed, per byte of the file (roughly)."""

UNIT_SCALE_MM = {"mm": 1.0, "m": 1000.0}

_SUPPORTED = ", ".join(READ_SUFFIXES)


@dataclass(frozen=True, eq=False)
class PointCloud:
    """Points (and optional triangles) read from a file.

    Attributes
    ----------
    points : (n, 3) float
        Coordinates in mm.
    faces : (m, 3) int or None
        Triangles as indices into ``points`` (meshes only; polygons are fanned).
    path : Path or None
        The file read, or None for clouds built in memory.
    sha256 : str
        Hex SHA-256 of the file's bytes ("" for clouds built in memory).
    warnings : tuple of str
        What looks wrong but is read (a plate a few millimetres across: metres read as mm?).
    """

    points: np.ndarray
    faces: np.ndarray | None = None
    path: Path | None = None
    sha256: str = ""
    warnings: tuple = ()

    @property
    def n_points(self) -> int:
        """Number of points."""
        return int(self.points.shape[0])


def _unit_scale(units: str) -> float:
    if units not in UNIT_SCALE_MM:
        raise InputError(
            f"unknown length unit {units!r}", hint=f"use one of {', '.join(UNIT_SCALE_MM)}"
        )
    return UNIT_SCALE_MM[units]


def read_points(path, units: str = "mm", scale: float = 1.0, *,
                chord_tolerance_mm: float = CHORD_TOLERANCE_MM) -> PointCloud:
    """Read a point, mesh, CAD or scan file into a :class:`PointCloud` in mm.

    Parameters
    ----------
    path : str or Path
        A ``.csv``, ``.txt``, ``.xyz``, ``.ply``, ``.stl``, ``.obj``, ``.igs``, ``.iges``,
        ``.stp``, ``.step``, ``.e57``, ``.las`` or ``.laz`` file.
    units : {"mm", "m"}
        Length unit of the file (IGES, STEP and E57 declare their own and ignore it); the
        result is always in mm.
    scale : float
        Model scale factor: coordinates are multiplied by it (31.6 for a 1:31.6 model).
    chord_tolerance_mm : float
        Chordal tolerance of a CAD file's tessellation, mm at full scale.

    Returns
    -------
    PointCloud

    Raises
    ------
    FileFormatError
        Missing or empty file, unknown suffix, content that is not what the suffix
        says, non-numeric fields, wrong column count, NaN or inf, no points.
    """
    unit_scale = _unit_scale(units)
    model_scale = check_positive("the model scale", scale, hint="give e.g. --scale 31.6 for a 1:31.6 model")
    scale = unit_scale * model_scale
    path = Path(path)
    suffix = _checked_suffix(path)
    if suffix in EXCHANGE_SUFFIXES:  # CAD and scanner files: mppf.geometry.exchange
        from mppf.geometry.exchange import read_exchange

        points, faces, sha256 = read_exchange(path, unit_scale=unit_scale, scale=model_scale,
                                              chord_tolerance_mm=chord_tolerance_mm)
        return PointCloud(points=points, faces=faces, path=path, sha256=sha256)
    data = _file_bytes(path)
    points, faces = _parse(path, suffix, data)
    _check_points(path, points)
    points = points * scale if scale != 1.0 else points
    return PointCloud(points=points, faces=faces, path=path, sha256=hashlib.sha256(data).hexdigest(),
                      warnings=size_warnings(path, points, units))


def _checked_suffix(path: Path) -> str:
    """The file's suffix in lower case; :class:`FileFormatError` unless mppf reads it."""
    suffix = path.suffix.lower()
    if suffix not in READ_SUFFIXES:
        raise FileFormatError(
            path, f"unknown file type {path.suffix or '(no suffix)'!r}",
            hint=f"give a point or mesh file with one of the suffixes {_SUPPORTED}",
        )
    return suffix


def _file_bytes(path: Path) -> bytes:
    """The content of a point or mesh file; :class:`FileFormatError` if missing, too large, unreadable or empty."""
    if not path.exists():
        raise FileFormatError(path, "file not found", hint="check the path and the file name")
    if not path.is_file():
        raise FileFormatError(path, "is not a file (a directory?)", hint="give a point file")
    check_fits(path, TEXT_BYTES_PER_FILE_BYTE * path.stat().st_size, f"its {path.stat().st_size:,} bytes")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise FileFormatError(path, f"cannot be read: {exc.strerror}", hint="check permissions") from None
    if not data.strip():
        raise FileFormatError(path, "file is empty", hint="the file holds no points; check the export")
    return data


def _parse(path: Path, suffix: str, data: bytes) -> tuple[np.ndarray, np.ndarray | None]:
    """Points (n, 3) float in the file's unit and faces ((m, 3) int or None) of a text, PLY or mesh file."""
    if suffix in TEXT_SUFFIXES:
        return parse_text(path, data), None
    if suffix in PLY_SUFFIXES:
        return _read_ply(path, data)
    check_mesh_bytes(path, suffix, data)
    return _read_mesh(path, suffix)


def _check_points(path: Path, points: np.ndarray) -> None:
    """:class:`FileFormatError` unless the file gave points, all of them finite."""
    if points.shape[0] == 0:
        raise FileFormatError(path, "holds no points", hint="check the export")
    bad = ~np.all(np.isfinite(points), axis=1)
    if bad.any():
        first = int(np.argmax(bad))
        raise FileFormatError(
            path, f"vertex {first} has a NaN or infinite coordinate {points[first].tolist()}",
            hint="remove or repair invalid points in the source program",
        )


PLATE_MIN_MM = 50.0
PLATE_MAX_MM = 100_000.0
"""A plate smaller or larger across than these (mm) is most likely in another unit than the one read."""
PLATE_MIN_POINTS = 50
"""Fewer points are a sketch or a test, not a plate's design or scan: their size is not judged."""


def size_warnings(path, points: np.ndarray, units: str) -> tuple[str, ...]:
    """Warnings for a plate (:data:`PLATE_MIN_POINTS` or more) of implausible size: metres read as mm, or reverse."""
    if points.shape[0] < PLATE_MIN_POINTS:
        return ()
    extent = float(np.ptp(points, axis=0).max())
    if 0.0 < extent < PLATE_MIN_MM:
        hint = "is the file in metres? then give --units m" if units == "mm" else "check the file's unit"
        return (f"{path}: the plate is only {extent:.3g} mm across; {hint}",)
    if extent > PLATE_MAX_MM:
        hint = "was --units m given for a file in mm?" if units == "m" else "is it in micrometres, or a whole hull?"
        return (f"{path}: the plate is {extent / 1000:.3g} m across; {hint}",)
    return ()


# --------------------------------------------------------------------- PLY


def _read_ply(path: Path, data: bytes) -> tuple[np.ndarray, np.ndarray | None]:
    import plyfile

    if not data.startswith(b"ply"):
        raise FileFormatError(
            path, "is not a PLY file (it does not start with 'ply')", line=1,
            hint="is it a text point file? give it a .csv/.txt/.xyz suffix",
        )
    _check_ply_counts(path, data)  # before plyfile allocates what the header announces
    try:
        ply = plyfile.PlyData.read(str(path))
    except Exception as exc:  # plyfile raises several types for a broken file
        line = getattr(exc, "line", None)
        raise FileFormatError(path, f"is not a readable PLY file: {exc}", line=line,
                              hint="re-export it from the scanner or CAD program") from None
    names = [element.name for element in ply.elements]
    if "vertex" not in names:
        raise FileFormatError(path, f"PLY file without a 'vertex' element (has {names})",
                              hint="the file holds no points")
    vertex = ply["vertex"]
    props = [prop.name for prop in vertex.properties]
    missing = [axis for axis in "xyz" if axis not in props]
    if missing:
        raise FileFormatError(path, f"PLY vertices lack property {missing} (have {props})",
                              hint="vertices need x, y and z")
    points = np.column_stack([np.asarray(vertex[axis], dtype=float) for axis in "xyz"])
    faces = None
    if "face" in names and ply["face"].count > 0:
        face = ply["face"]
        face_props = [prop.name for prop in face.properties]
        key = next((k for k in ("vertex_indices", "vertex_index") if k in face_props), None)
        if key is None:
            raise FileFormatError(path, f"PLY faces lack 'vertex_indices' (have {face_props})")
        faces = _fan_triangles(path, list(face[key]), points.shape[0])
    return points, faces


_PLY_TYPE_BYTES = {"char": 1, "int8": 1, "uchar": 1, "uint8": 1, "short": 2, "int16": 2, "ushort": 2, "uint16": 2,
                   "int": 4, "int32": 4, "uint": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}


def _check_ply_counts(path: Path, data: bytes) -> None:
    """Refuse a PLY header whose element counts the file cannot hold (checked before anything is allocated).

    Each row of an element takes at least its properties' bytes (binary; a list at least its
    count) or two characters per property (ASCII: a digit and a separator); the counts times
    those must fit in the bytes after the header.
    """
    end = data.find(b"end_header")
    if end < 0:
        return  # plyfile names the broken header
    header = data[:end].decode("ascii", errors="replace").splitlines()
    body = len(data) - (data.find(b"\n", end) + 1 if data.find(b"\n", end) >= 0 else len(data))
    ascii_format = any(line.split()[:2] == ["format", "ascii"] for line in header if line.strip())
    elements: list[list] = []  # [name, count, least bytes per row]
    for line in header:
        words = line.split()
        if len(words) == 3 and words[0] == "element" and words[2].isdigit():
            elements.append([words[1], int(words[2]), 0])
        elif words[:1] == ["property"] and elements and len(words) >= 3:
            size = _PLY_TYPE_BYTES.get(words[2] if words[1] == "list" else words[1], 1)
            elements[-1][2] += 2 if ascii_format else size
    need = sum(count * max(least, 1) for _, count, least in elements)
    if need > body:
        name, count, _ = max(elements, key=lambda e: e[1] * max(e[2], 1))
        raise FileFormatError(path, f"its PLY header announces {count:,} {name} element(s), which need at least "
                                    f"{need:,} bytes, but only {body:,} bytes follow the header",
                              hint="the file is truncated or its header is corrupt; export it again")


def _fan_triangles(path: Path, polygons: list, n_points: int) -> np.ndarray:
    """Split polygons (lists of vertex indices) into triangles by fans."""
    sizes = np.array([len(polygon) for polygon in polygons])
    if sizes.size and np.all(sizes == 3):  # the usual case: triangles already
        return _check_faces(path, np.stack(polygons).astype(np.int64), n_points)
    triangles = []
    for number, polygon in enumerate(polygons):
        polygon = np.asarray(polygon, dtype=np.int64)
        if polygon.size < 3:
            raise FileFormatError(path, f"face {number} has {polygon.size} vertices, expected >= 3")
        for k in range(1, polygon.size - 1):
            triangles.append((polygon[0], polygon[k], polygon[k + 1]))
    return _check_faces(path, np.asarray(triangles, dtype=np.int64).reshape(-1, 3), n_points)


def _check_faces(path: Path, faces: np.ndarray, n_points: int) -> np.ndarray:
    if faces.size and (faces.min() < 0 or faces.max() >= n_points):
        raise FileFormatError(
            path, f"a face refers to vertex {int(faces.max())}, but there are {n_points} vertices",
            hint="the mesh is broken; re-export it",
        )
    return faces


# --------------------------------------------------------------------- meshes


def _read_mesh(path: Path, suffix: str) -> tuple[np.ndarray, np.ndarray | None]:
    import trimesh

    try:
        # unprocessed first: processing silently drops NaN vertices, which must be reported
        loaded = trimesh.load(str(path), file_type=suffix[1:], process=False)
    except Exception as exc:  # trimesh raises many types for broken files
        raise FileFormatError(path, f"is not a readable {suffix[1:].upper()} file: {exc}",
                              hint="re-export it from the CAD program") from None
    if isinstance(loaded, trimesh.Scene):
        meshes = [g for g in loaded.geometry.values() if isinstance(g, trimesh.Trimesh)]
        if not meshes:
            raise FileFormatError(
                path, f"holds no mesh: not a valid {suffix[1:].upper()} file",
                hint="is it a text point file? give it a .csv/.txt/.xyz suffix",
            )
        loaded = trimesh.util.concatenate(meshes) if len(meshes) > 1 else meshes[0]
        loaded.merge_vertices()
    if isinstance(loaded, trimesh.Trimesh):
        if not np.all(np.isfinite(loaded.vertices)):
            return np.asarray(loaded.vertices, dtype=float), None  # read_points names the vertex
        loaded.process()  # merge duplicate vertices (an STL repeats them per triangle)
        faces = np.asarray(loaded.faces, dtype=np.int64)
        return np.asarray(loaded.vertices, dtype=float), (faces if faces.size else None)
    vertices = getattr(loaded, "vertices", None)
    if vertices is None:
        raise FileFormatError(path, f"holds no points ({type(loaded).__name__})")
    return np.asarray(vertices, dtype=float), None
