"""Checks of IGES and STEP files before OpenCASCADE reads them.

OpenCASCADE reads what it can of a damaged file and says nothing: an IGES file cut off
half-way loads 16 of its 18 surfaces. So the file's structure is checked first:

* IGES (ANSI/US PRO IPO-100, fixed 80-column records): every record carries its section
  letter (S, G, D, P, T) in column 73, and the last record, the Terminate section, counts
  the records of each section; a missing T record or counts that do not match mean the
  file is truncated or damaged. (Compressed and binary IGES are not read.)
* STEP (ISO 10303-21): the file starts with ``ISO-10303-21;`` and ends with
  ``END-ISO-10303-21;``.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from mppf.core.errors import FileFormatError

IGES_SUFFIXES = (".igs", ".iges")
STEP_SUFFIXES = (".stp", ".step")
CAD_SUFFIXES = IGES_SUFFIXES + STEP_SUFFIXES

CHORD_TOLERANCE_MM = 0.1
"""Default chordal tolerance of a tessellation, mm at full scale (here, not in :mod:`mppf.geometry.cad_mesh`,
so that reading a point file does not import the CAD reader)."""

_SECTIONS = "SGDPT"
_EXPORT_HINT = "export the surfaces from the CAD system again (IGES 5.3 or STEP AP203/AP214)"


def check_cad_file(path: Path) -> None:
    """Raise :class:`FileFormatError` when ``path`` is not a complete IGES or STEP file (by its suffix)."""
    if path.suffix.lower() not in CAD_SUFFIXES:
        raise FileFormatError(path, f"is not a CAD model: its suffix {path.suffix or '(none)'!r} is not one of "
                              f"{', '.join(CAD_SUFFIXES)}", hint="give the hull or plate as IGES or STEP surfaces")
    if path.suffix.lower() in IGES_SUFFIXES:
        _check_iges(path)
    else:
        _check_step(path)


def _check_iges(path: Path) -> None:
    counts: Counter[str] = Counter()
    last, broken = "", None
    with open(path, "rb") as stream:
        for number, raw in enumerate(stream, start=1):
            line = raw.rstrip(b"\r\n").decode("latin-1")
            if not line.strip():
                continue
            if broken is not None:  # a broken record before the end: damage, not truncation
                raise FileFormatError(path, f"record without an IGES section letter in column 73: {broken[1]!r}",
                                      line=broken[0], hint=f"the file is damaged; {_EXPORT_HINT}")
            letter = line[72:73]
            if not letter or letter not in _SECTIONS:
                if number == 1:
                    raise FileFormatError(
                        path, "is not an IGES file: its first record has no section letter (S, G, D, P or T) "
                        "in column 73", line=1,
                        hint="is it really IGES? (a point file needs .csv/.xyz/.ply; a STEP file .stp) -- "
                             + _EXPORT_HINT)
                broken = (number, line[:40])
                continue
            counts[letter] += 1
            last = line
    if broken is not None or not last or last[72:73] != "T":
        raise FileFormatError(path, "is truncated: the IGES Terminate (T) record at its end is missing",
                              hint=f"the file was cut off (an interrupted copy or export); {_EXPORT_HINT}")
    declared = _terminate_counts(last)
    for letter in "SGDP":
        if letter in declared and declared[letter] != counts[letter]:
            raise FileFormatError(
                path, f"is damaged: its Terminate record declares {declared[letter]} {letter} records, "
                f"the file holds {counts[letter]}", hint=f"the file was cut or edited; {_EXPORT_HINT}")
    if counts["D"] == 0:
        raise FileFormatError(path, "holds no IGES entities (no Directory Entry records)", hint=_EXPORT_HINT)


def _terminate_counts(record: str) -> dict[str, int]:
    """Section record counts of an IGES Terminate record, e.g. ``S      1G      3D    388P  24250``."""
    counts = {}
    for k in range(4):
        field = record[8 * k:8 * k + 8]
        letter, digits = field[:1], field[1:].strip()
        if letter in "SGDP" and digits.isdigit():
            counts[letter] = int(digits)
    return counts


def _check_step(path: Path) -> None:
    size = path.stat().st_size
    with open(path, "rb") as stream:
        head = stream.read(256).lstrip(b"\xef\xbb\xbf \t\r\n")
        stream.seek(max(0, size - 4096))
        tail = stream.read()
    if not head.upper().startswith(b"ISO-10303-21;"):
        raise FileFormatError(
            path, "is not a STEP file: it does not start with 'ISO-10303-21;'", line=1,
            hint=f"is it really STEP? (a point file needs .csv/.xyz/.ply; an IGES file .igs) -- {_EXPORT_HINT}")
    if b"END-ISO-10303-21;" not in tail.upper():
        raise FileFormatError(path, "is truncated: the closing 'END-ISO-10303-21;' is missing",
                              hint=f"the file was cut off (an interrupted copy or export); {_EXPORT_HINT}")
    _check_no_nul(path)


def _check_no_nul(path: Path, block_bytes: int = 1 << 20) -> None:
    """A STEP file is text: a NUL byte (a disk or copy fault, a binary file renamed) is refused with its line."""
    line, offset = 1, 0
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(block_bytes), b""):
            at = block.find(b"\x00")
            if at >= 0:
                line += block.count(b"\n", 0, at)
                raise FileFormatError(path, f"holds a NUL byte at byte {offset + at:,}: a STEP file is text",
                                      line=line, hint=f"the file is damaged (a disk or copy fault); {_EXPORT_HINT}")
            line += block.count(b"\n")
            offset += len(block)
