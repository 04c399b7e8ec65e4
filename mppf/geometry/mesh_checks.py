"""Checks of STL and OBJ files before ``trimesh`` reads them: the common broken exports, named.

``trimesh`` reads a truncated binary STL or an ASCII STL cut short with messages about
something else (a missing text-encoding module, "no mesh"), and an OBJ with 0-based face
indices as a few stray triangles. These checks look at the bytes first and raise a
:class:`~mppf.core.errors.FileFormatError` that says what is wrong and what to do.
"""

from __future__ import annotations

import re
import struct
from pathlib import Path

from mppf.core.errors import FileFormatError

STL_HEADER_BYTES = 84
STL_TRIANGLE_BYTES = 50
_FACE = re.compile(rb"^\s*f\s+(.*)$", re.MULTILINE)


def check_mesh_bytes(path: Path, suffix: str, data: bytes) -> None:
    """Refuse a truncated binary STL, an ASCII STL without ``endsolid``, an OBJ with 0-based faces.

    Parameters
    ----------
    path : Path
        The file, for messages.
    suffix : {".stl", ".obj"}
    data : bytes
        Its content.

    Raises
    ------
    FileFormatError
    """
    if suffix == ".stl":
        _check_stl(path, data)
    elif suffix == ".obj":
        _check_obj(path, data)


def _binary_stl_size(data: bytes) -> int | None:
    """The size a binary STL with this header must have, or None when too short for a header."""
    if len(data) < STL_HEADER_BYTES:
        return None
    (count,) = struct.unpack_from("<I", data, 80)
    return STL_HEADER_BYTES + STL_TRIANGLE_BYTES * count


def _check_stl(path: Path, data: bytes) -> None:
    expected = _binary_stl_size(data)
    if expected == len(data):
        return  # a whole binary STL (its header may well start with "solid")
    if data.lstrip()[:5].lower() == b"solid" and b"\x00" not in data[:512]:
        tail = data.rstrip()[-4096:].lower()
        if b"endsolid" not in tail:
            raise FileFormatError(path, "is an ASCII STL without its closing 'endsolid' line: the file is cut short",
                                  hint="the export or the copy was interrupted; export the mesh again")
        if b"facet" not in data.lower():
            raise FileFormatError(path, "is an ASCII STL without any 'facet': it holds no triangles",
                                  hint="export the plate's surface, not an empty solid")
        return
    if expected is None:
        raise FileFormatError(path, f"is too short for a binary STL ({len(data)} bytes, the header alone is "
                              f"{STL_HEADER_BYTES})", hint="the export or the copy was interrupted; export it again")
    count = (expected - STL_HEADER_BYTES) // STL_TRIANGLE_BYTES
    whole = (len(data) - STL_HEADER_BYTES) // STL_TRIANGLE_BYTES
    raise FileFormatError(
        path, f"is a binary STL whose header announces {count:,} triangles ({expected:,} bytes), but the file has "
        f"{len(data):,} bytes ({whole:,} whole triangles): it is truncated or not an STL",
        hint="the export or the copy was interrupted; export the mesh again",
    )


def _check_obj(path: Path, data: bytes) -> None:
    for match in _FACE.finditer(data):
        for token in match.group(1).split():
            index = token.split(b"/", 1)[0]
            if index == b"0":
                line = data.count(b"\n", 0, match.start()) + 1
                raise FileFormatError(
                    path, f"face '{match.group(0).strip().decode('latin-1')}' uses vertex index 0: OBJ counts "
                    "vertices from 1 (this exporter wrote 0-based indices)", line=line,
                    hint="re-export with 1-based indices, or add 1 to every index of the 'f' lines",
                )
