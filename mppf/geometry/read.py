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
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mppf.core.errors import FileFormatError, InputError
from mppf.core.validate import check_positive
from mppf.geometry.exchange import CHORD_TOLERANCE_MM, EXCHANGE_SUFFIXES
from mppf.geometry.files import check_fits

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
    """

    points: np.ndarray
    faces: np.ndarray | None = None
    path: Path | None = None
    sha256: str = ""

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
    suffix = path.suffix.lower()
    if suffix not in READ_SUFFIXES:
        raise FileFormatError(
            path, f"unknown file type {path.suffix or '(no suffix)'!r}",
            hint=f"give a point or mesh file with one of the suffixes {_SUPPORTED}",
        )
    if suffix in EXCHANGE_SUFFIXES:  # CAD and scanner files: mppf.geometry.exchange
        from mppf.geometry.exchange import read_exchange

        points, faces, sha256 = read_exchange(path, unit_scale=unit_scale, scale=model_scale,
                                              chord_tolerance_mm=chord_tolerance_mm)
        return PointCloud(points=points, faces=faces, path=path, sha256=sha256)
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

    if suffix in TEXT_SUFFIXES:
        points, faces = _parse_text(path, data), None
    elif suffix in PLY_SUFFIXES:
        points, faces = _read_ply(path, data)
    else:
        points, faces = _read_mesh(path, suffix)

    if points.shape[0] == 0:
        raise FileFormatError(path, "holds no points", hint="check the export")
    bad = ~np.all(np.isfinite(points), axis=1)
    if bad.any():
        first = int(np.argmax(bad))
        raise FileFormatError(
            path, f"vertex {first} has a NaN or infinite coordinate {points[first].tolist()}",
            hint="remove or repair invalid points in the source program",
        )
    points = points * scale if scale != 1.0 else points
    return PointCloud(points=points, faces=faces, path=path, sha256=hashlib.sha256(data).hexdigest())


# --------------------------------------------------------------------- text files


def _decode_text(path: Path, data: bytes) -> str:
    """Decode a text point file, refusing binary content."""
    if b"\x00" in data:
        raise FileFormatError(
            path, "is binary, not a text point file (it contains NUL bytes)",
            hint=f"is it really a {path.suffix} file? a binary PLY/STL needs that suffix",
        )
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    control = sum(1 for ch in text if ord(ch) < 32 and ch not in "\t\r\n\f" or 0x7F <= ord(ch) < 0xA0)
    if control > 0.01 * len(text):
        raise FileFormatError(
            path, "is binary, not a text point file (it contains control bytes)",
            hint=f"is it really a {path.suffix} file?",
        )
    return text


def _split_fields(line: str) -> list[str]:
    if "," in line:
        return [field.strip() for field in line.split(",")]
    return line.split()


def _is_number(field: str) -> bool:
    try:
        float(field)
    except ValueError:
        return False
    return True


def _parse_text(path: Path, data: bytes) -> np.ndarray:
    """Parse a CSV/TXT/XYZ point file into an (n, 3) array (line-exact errors)."""
    lines = _decode_text(path, data).splitlines()
    # Header lines (all fields non-numeric) may precede the first data line.
    first = None
    for index, raw in enumerate(lines):
        content = raw.split("#", 1)[0].strip()
        if not content:
            continue
        fields = _split_fields(content)
        if any(_is_number(field) for field in fields):
            first = index
            break
    if first is None:
        raise FileFormatError(
            path, "has no numeric data lines (only comments or header lines)",
            hint="a point file needs lines 'x,y,z' or 'x y z' of numbers",
        )
    values = _fast_parse(lines[first:])
    if values is None:
        values = _slow_parse(path, lines, first)
    if values.shape[1] < 3:
        # consistent but too few columns
        raise FileFormatError(
            path, f"has {values.shape[1]} column(s), expected 3 (x, y, z)", line=first + 1,
            hint="each data line needs x, y and z",
        )
    points = np.ascontiguousarray(values[:, :3], dtype=float)
    bad = ~np.all(np.isfinite(points), axis=1)
    if bad.any():
        # locate the line of the first bad point
        _slow_parse(path, lines, first)
    return points


def _fast_parse(lines: list[str]) -> np.ndarray | None:
    """numpy's C parser on the data block; None when anything is irregular."""
    content = next(line for line in lines if line.split("#", 1)[0].strip())
    delimiter = "," if "," in content else None
    try:
        values = np.loadtxt(lines, delimiter=delimiter, comments="#", ndmin=2, dtype=float)
    except ValueError:
        return None
    if not np.all(np.isfinite(values)):
        return None
    return values


def _slow_parse(path: Path, lines: list[str], first: int) -> np.ndarray:
    """Line by line parser: the reference semantics, with the line of every error."""
    rows: list[list[float]] = []
    n_columns = None
    for index in range(first, len(lines)):
        lineno = index + 1
        content = lines[index].split("#", 1)[0].strip()
        if not content:
            continue
        fields = _split_fields(content)
        if n_columns is None:
            n_columns = len(fields)
            if n_columns < 3:
                raise FileFormatError(
                    path, f"has {n_columns} column(s) {content!r}, expected 3 (x, y, z)", line=lineno,
                    hint="each data line needs x, y and z",
                )
        elif len(fields) != n_columns:
            raise FileFormatError(
                path, f"has {len(fields)} column(s), expected {n_columns} like the first data line: "
                f"{content!r}", line=lineno, hint="every data line needs the same columns",
            )
        row = []
        for column, field in enumerate(fields, start=1):
            try:
                value = float(field)
            except ValueError:
                raise FileFormatError(
                    path, f"non-numeric field {field!r} in column {column}", line=lineno,
                    hint="fix or delete the line; header lines are only allowed before the data",
                ) from None
            if not math.isfinite(value):
                raise FileFormatError(
                    path, f"{field!r} (NaN or infinite) in column {column}", line=lineno,
                    hint="remove or repair invalid points in the source program",
                )
            row.append(value)
        rows.append(row)
    return np.asarray(rows, dtype=float)


# --------------------------------------------------------------------- PLY


def _read_ply(path: Path, data: bytes) -> tuple[np.ndarray, np.ndarray | None]:
    import plyfile

    if not data.startswith(b"ply"):
        raise FileFormatError(
            path, "is not a PLY file (it does not start with 'ply')", line=1,
            hint="is it a text point file? give it a .csv/.txt/.xyz suffix",
        )
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
