"""Text point files (``.csv`` ``.txt`` ``.xyz``): parsing, and the real-world mistakes named.

A data line is ``x,y,z`` or ``x y z`` (more columns are ignored; more than three comma-separated
columns without any decimal point are decimal commas, refused). The common mistakes are
recognised and named instead of reported as "no numeric data": a spreadsheet export with
semicolons and decimal commas, decimal commas between tabs or spaces, UTF-16 text (Windows
"Unicode" export), binary content. Every problem is a
:class:`~mppf.core.errors.FileFormatError` naming the file and the line.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from mppf.core.errors import FileFormatError

_NOT_CONTROL = bytes(b for b in range(256) if not (b < 32 and b not in b"\t\r\n\f" or b == 0x7F))
_DECIMAL_COMMA = re.compile(r"^[-+]?\d+,\d+$")
_EXPORT_HINT = ("export the points with '.' as the decimal mark and ',' or spaces between x, y and z "
                "(in a spreadsheet: set the language to English before saving as CSV)")


def parse_text(path: Path, data: bytes) -> np.ndarray:
    """Parse a CSV/TXT/XYZ point file into an (n, 3) float array (line-exact errors).

    Parameters
    ----------
    path : Path
        The file, for messages.
    data : bytes
        Its content.

    Returns
    -------
    (n, 3) float

    Raises
    ------
    FileFormatError
    """
    lines = decode_text(path, data).splitlines()
    # header lines (all fields non-numeric) may precede the first data line
    first = None
    for index, raw in enumerate(lines):
        content = raw.split("#", 1)[0].strip()
        if not content:
            continue
        _refuse_foreign_numbers(path, content, index + 1)
        if any(_is_number(field) for field in split_fields(content)):
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
        raise FileFormatError(
            path, f"has {values.shape[1]} column(s), expected 3 (x, y, z)", line=first + 1,
            hint="each data line needs x, y and z",
        )
    if values.shape[1] > 3:
        _refuse_comma_decimals(path, lines, first)
    points = np.ascontiguousarray(values[:, :3], dtype=float)
    if not np.all(np.isfinite(points)):
        _slow_parse(path, lines, first)  # names the line of the first bad point
    return points


def decode_text(path: Path, data: bytes) -> str:
    """The text of a point file; UTF-16 and binary content refused with their names."""
    if data[:2] in (b"\xff\xfe", b"\xfe\xff") or _looks_utf16(data):
        raise FileFormatError(
            path, "is UTF-16 text (a Windows 'Unicode text' export); mppf reads UTF-8 or ASCII point files",
            hint="save it again as 'CSV UTF-8' or plain text, or convert it: iconv -f UTF-16 -t UTF-8",
        )
    if b"\x00" in data:
        raise FileFormatError(
            path, "is binary, not a text point file (it contains NUL bytes)",
            hint=f"is it really a {path.suffix} file? a binary PLY/STL needs that suffix",
        )
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    control = len(data.translate(None, _NOT_CONTROL))  # C0 control bytes but tab, newlines, form feed; DEL
    if control > 0.01 * len(data):
        raise FileFormatError(
            path, "is binary, not a text point file (it contains control bytes)",
            hint=f"is it really a {path.suffix} file?",
        )
    return text


def _looks_utf16(data: bytes) -> bool:
    """UTF-16 without a byte-order mark: every other byte of ASCII text is NUL."""
    sample = data[:4096]
    if len(sample) < 8:
        return False
    even, odd = sample[0::2], sample[1::2]
    return (odd.count(0) > 0.9 * len(odd) and even.count(0) < 0.1 * len(even)) or \
        (even.count(0) > 0.9 * len(even) and odd.count(0) < 0.1 * len(odd))


def _refuse_foreign_numbers(path: Path, content: str, lineno: int) -> None:
    """Name semicolon separators, decimal commas (a spreadsheet in a European language), quoted numbers."""
    if '"' in content and any(_is_number(f.strip().strip('"')) for f in split_fields(content)):
        raise FileFormatError(path, f"writes its numbers in double quotes: {content[:60]!r}", line=lineno,
                              hint="export the points without quotes (plain numbers: x,y,z)")
    fields = [f.strip() for f in content.split(";")]
    commas = any(_DECIMAL_COMMA.match(f) for f in fields)
    if len(fields) >= 2 and (commas or any(_is_number(f) for f in fields)):
        raise FileFormatError(
            path, f"separates its fields with semicolons{' and writes decimal commas' if commas else ''}: "
            f"{content[:60]!r}", line=lineno, hint=_EXPORT_HINT,
        )
    if "," in content and ("\t" in content or " " in content.strip()):
        words = content.replace("\t", " ").split()
        if len(words) >= 3 and sum(bool(_DECIMAL_COMMA.match(w)) for w in words) >= 2:
            raise FileFormatError(
                path, f"writes decimal commas between spaces or tabs: {content[:60]!r} (is '1,5' one and a half "
                "or two fields?)", line=lineno, hint=_EXPORT_HINT,
            )


def _refuse_comma_decimals(path: Path, lines: list[str], first: int, sample: int = 200) -> None:
    """Refuse comma-separated lines of more than 3 columns without any decimal point: decimal commas.

    ``-600,5,-450,0,27,6`` is x, y, z written with decimal commas between commas, which would
    read as 6 columns (x = -600, y = 5, z = -450: a plate that folds over). A file of more
    than 3 columns whose numbers (the first ``sample`` data lines) hold no '.' and no exponent
    is taken to be that, and refused; real extra columns come with decimal points.
    """
    data = [line.split("#", 1)[0].strip() for line in lines[first:first + sample]]
    data = [line for line in data if line]
    if not data or not all("," in line for line in data):
        return
    if any(("." in field or "e" in field.lower()) for line in data for field in line.split(",")):
        return
    raise FileFormatError(
        path, f"has {len(data[0].split(','))} comma-separated columns and not one decimal point: "
        f"{data[0][:60]!r} looks like x, y, z written with decimal commas", line=first + 1,
        hint=_EXPORT_HINT + " (if the columns really are whole numbers, write x, y and z with a decimal point, "
        "e.g. 100.0)")


def split_fields(line: str) -> list[str]:
    """The fields of a data line: comma separated, else whitespace separated."""
    if "," in line:
        return [field.strip() for field in line.split(",")]
    return line.split()


def _is_number(field: str) -> bool:
    try:
        float(field)
    except ValueError:
        return False
    return True


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
        _refuse_foreign_numbers(path, content, lineno)
        fields = split_fields(content)
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
        rows.append([_value(path, field, column, lineno) for column, field in enumerate(fields, start=1)])
    return np.asarray(rows, dtype=float)


def _value(path: Path, field: str, column: int, lineno: int) -> float:
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
    return value
