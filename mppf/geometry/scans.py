"""Laser-scanner files: E57 (``pye57``) and LAS / LAZ (``laspy`` with ``lazrs``).

* E57 (ASTM E2807): every scan in the file is read, invalid points dropped, spherical
  coordinates converted, and each scan's pose (rotation quaternion w, x, y, z and
  translation) applied, so all scans come back in the file's common frame. E57 lengths
  are metres by the standard; they are returned in mm whatever ``units`` says.
* LAS 1.0-1.4 and LAZ: the integer coordinates with the header's scale and offset
  applied. LAS declares no length unit of its own (it is the coordinate system's, usually
  metres): ``units`` says which.

The point count in the header is checked against the memory available before any point
is read (:func:`mppf.geometry.files.check_fits`).

:func:`read_header_mark` reads the plate's reference mark from a scan file's header, where
the format has free text for it: a ``comment`` line of a PLY header, a ``#`` comment line
before the first point of a text file (``.csv .txt .xyz``). E57 and LAS/LAZ scans carry
their mark in the mark file beside them (``<scan>.mark.json``, :mod:`mppf.measure.mark`).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from mppf.core.errors import FileFormatError
from mppf.geometry.files import check_fits, check_readable, quiet

E57_SUFFIXES = (".e57",)
LAS_SUFFIXES = (".las", ".laz")
SCAN_SUFFIXES = E57_SUFFIXES + LAS_SUFFIXES

E57_BYTES_PER_POINT = 3 * 8 * 3
"""Memory per E57 point while reading: the buffers, the valid copy and the transformed copy."""

LAS_XYZ_BYTES = 3 * 8 * 2
"""Memory per LAS point beyond its record: the scaled copy and the result."""

_RESCAN_HINT = "export the scan again from the scanner software"


def read_e57(path) -> np.ndarray:
    """All scans of an E57 file, poses applied: (n, 3) float, mm.

    Raises
    ------
    FileFormatError
        Missing, empty, truncated or damaged file, not an E57 file, no scans, no points.
    """
    import pye57

    path = check_readable(path, "an E57 scan")
    with open(path, "rb") as stream:
        if stream.read(8) != b"ASTM-E57":
            raise FileFormatError(path, "is not an E57 file (it does not start with 'ASTM-E57')",
                                  hint=f"is it another scan format (.las, .laz, .ply, .xyz)? {_RESCAN_HINT}")
    with quiet():
        try:
            e57 = pye57.E57(str(path))
            try:
                headers = [e57.get_header(index) for index in range(e57.scan_count)]
                total = sum(header.point_count for header in headers)
                check_fits(path, total * E57_BYTES_PER_POINT, f"its {total:,} points")
                scans = [_e57_scan(e57, index) for index in range(len(headers))]
            finally:
                e57.close()
        except FileFormatError:
            raise
        except Exception as exc:  # libE57Format raises its own exception types
            raise FileFormatError(path, f"is not a readable E57 file: {_first_line(exc)}",
                                  hint=f"the file may be truncated or damaged; {_RESCAN_HINT}") from None
    if not scans:
        raise FileFormatError(path, "holds no scans", hint=_RESCAN_HINT)
    points = np.vstack(scans) * 1000.0  # E57 is metres
    if points.shape[0] == 0:
        raise FileFormatError(path, f"holds {len(scans)} scan(s) but no valid points", hint=_RESCAN_HINT)
    return points


def _e57_scan(e57, index: int) -> np.ndarray:
    """One scan in the file's frame (pose applied by pye57: p' = R(q) p + t), metres."""
    data = e57.read_scan(index, ignore_missing_fields=True, transform=True)
    return np.column_stack([np.asarray(data[key], dtype=float) for key in ("cartesianX", "cartesianY", "cartesianZ")])


def _first_line(exc: Exception) -> str:
    text = str(exc).strip().splitlines()
    return (text[0] if text else type(exc).__name__)[:200]


def read_las(path, units_scale: float = 1.0) -> np.ndarray:
    """Points of a LAS or LAZ file, scale and offset applied: (n, 3) float, in the file's unit times ``units_scale``.

    Raises
    ------
    FileFormatError
        Missing, empty, truncated or damaged file, not a LAS/LAZ file, no points.
    """
    import laspy

    path = check_readable(path, "a LAS or LAZ scan")
    with open(path, "rb") as stream:
        if stream.read(4) != b"LASF":
            raise FileFormatError(path, "is not a LAS/LAZ file (it does not start with 'LASF')",
                                  hint=f"is it another scan format (.e57, .ply, .xyz)? {_RESCAN_HINT}")
    try:
        with laspy.open(str(path)) as reader:
            header = reader.header
            count = int(header.point_count)
            _check_las_scales(path, header)
            _check_las_size(path, header, count)
            check_fits(path, count * (header.point_format.size + LAS_XYZ_BYTES), f"its {count:,} points")
            points = np.asarray(reader.read().xyz, dtype=float)
    except FileFormatError:
        raise
    except Exception as exc:  # laspy and lazrs raise several types for a broken file
        raise FileFormatError(path, f"is not a readable {path.suffix[1:].upper()} file: {exc}",
                              hint=f"the file may be truncated or damaged; {_RESCAN_HINT}") from None
    if points.shape[0] != count:
        raise FileFormatError(path, f"is truncated: its header announces {count:,} points, "
                              f"{points.shape[0]:,} are there", hint=_RESCAN_HINT)
    if count == 0:
        raise FileFormatError(path, "holds no points", hint=_RESCAN_HINT)
    return points * units_scale


def _check_las_scales(path: Path, header) -> None:
    """The header's scale factors turn the integer coordinates into lengths: each must be finite and not 0."""
    scales = np.asarray(header.scales, dtype=float)
    bad = [f"{axis} {value:g}" for axis, value in zip("xyz", scales) if not (np.isfinite(value) and value != 0.0)]
    if bad:
        raise FileFormatError(path, f"its header's scale factor(s) {', '.join(bad)} are 0 or not finite: every "
                                    "point would lie at its offset", hint=f"the exporter wrote a broken header; "
                                                                          f"{_RESCAN_HINT}")
    offsets = np.asarray(header.offsets, dtype=float)
    if not np.all(np.isfinite(offsets)):
        raise FileFormatError(path, f"its header's offsets {offsets.tolist()} are not finite numbers",
                              hint=f"the exporter wrote a broken header; {_RESCAN_HINT}")


def _check_las_size(path: Path, header, count: int) -> None:
    """An uncompressed LAS file must hold every record its header announces."""
    if path.suffix.lower() != ".las" or header.are_points_compressed:
        return
    needed = header.offset_to_point_data + count * header.point_format.size
    size = path.stat().st_size
    if size < needed:
        raise FileFormatError(
            path, f"is truncated: {count:,} points of {header.point_format.size} bytes need {needed:,} bytes, "
            f"the file has {size:,}", hint=f"the file was cut off (an interrupted copy or export); {_RESCAN_HINT}")


HEADER_MARK_KEY = "reference_mark_mm"
"""The word of a header line that carries the reference mark: ``comment reference_mark_mm X Y Z``
(PLY) or ``# reference_mark_mm X Y Z`` (text); commas or spaces between the numbers, mm, the
scan's coordinates."""

HEADER_MARK_SUFFIXES = (".ply", ".csv", ".txt", ".xyz")
"""Scan formats whose header may carry the mark (:func:`read_header_mark`)."""

HEADER_BYTES = 65536
"""Only this many bytes from the start of a file are searched for the mark line."""

_NUMERIC_START = tuple("0123456789+-.")
_NUMBER = r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)"
_MARK_LINE = re.compile(rf"^\s*(?:comment|#)\s*{HEADER_MARK_KEY}\s*[:=]?\s*{_NUMBER}\s*[,;\s]\s*{_NUMBER}"
                        rf"\s*[,;\s]\s*{_NUMBER}\s*$")


def read_header_mark(path) -> np.ndarray | None:
    """The reference mark (3,) mm written in a scan file's header, or None.

    A PLY file: a ``comment reference_mark_mm X Y Z`` line of its header (before
    ``end_header``, ASCII or binary body). A text file: a ``# reference_mark_mm X Y Z`` comment
    line before its first point (column-name lines may come first). Other formats, a missing file, no such line or a line whose
    numbers are not finite: None (the mark file beside the scan may still give it).

    Parameters
    ----------
    path : path-like
        The scan file.

    Returns
    -------
    (3,) float or None
        The mark in the scan's coordinates, mm.
    """
    path = Path(path)
    if path.suffix.lower() not in HEADER_MARK_SUFFIXES:
        return None
    try:
        with open(path, "rb") as stream:
            head = stream.read(HEADER_BYTES)
    except OSError:
        return None
    text = head.decode("latin-1")
    lines = text.splitlines()
    if path.suffix.lower() == ".ply":
        lines = lines[: next((k for k, line in enumerate(lines) if line.strip() == "end_header"), len(lines))]
    for line in lines:
        stripped = line.strip()
        if path.suffix.lower() != ".ply" and stripped[:1] in _NUMERIC_START:
            break  # the first point of a text file: its header is over
        found = _MARK_LINE.match(line)
        if found:
            mark = np.array([float(v) for v in found.groups()])
            return mark if np.all(np.isfinite(mark)) else None
    return None
