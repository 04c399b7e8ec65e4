"""File checks shared by the CAD and scan readers: the file is there, not empty, fits in memory.

The C and C++ libraries behind those readers (OpenCASCADE, libE57Format) print to the
terminal themselves; :func:`quiet` catches that at the file-descriptor level.

Every reader estimates the bytes a file takes once read (from its size, or the point count in
its header) and calls :func:`check_fits` before reading: a scan of two billion points is
refused with a message instead of swapping the machine to a halt. The SHA-256 recorded for
a file is computed in blocks, so a large scan is never held twice.
"""

from __future__ import annotations

import hashlib
import os
import re
import sys
from contextlib import contextmanager
from pathlib import Path

from mppf.core.errors import FileFormatError

MEMORY_FRACTION = 0.5
"""Share of the memory available now that one file may take once read."""

_BLOCK_BYTES = 1 << 20
_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def check_readable(path, kind: str) -> Path:
    """``path`` as a Path to an existing, non-empty file, or a :class:`FileFormatError`.

    Parameters
    ----------
    path : str or Path
    kind : str
        What the file should be, for the hint (e.g. ``"an IGES file"``).
    """
    path = Path(path)
    if not path.exists():
        raise FileFormatError(path, "file not found", hint="check the path and the file name")
    if not path.is_file():
        raise FileFormatError(path, "is not a file (a directory?)", hint=f"give {kind}")
    if path.stat().st_size == 0:
        raise FileFormatError(path, "file is empty", hint=f"the export was interrupted; export {kind} again")
    return path


def sha256_of(path) -> str:
    """Hex SHA-256 of a file's bytes, read in 1 MiB blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(_BLOCK_BYTES), b""):
            digest.update(block)
    return digest.hexdigest()


def available_bytes() -> int:
    """Memory available to this process now (bytes): ``MemAvailable`` of Linux, else free physical memory."""
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return 1 << 62  # unknown: never refuse


def check_fits(path, needed_bytes: float, what: str) -> None:
    """Refuse a file whose content would not fit in memory.

    Parameters
    ----------
    path : str or Path
        The file, for the message.
    needed_bytes : float
        Estimated memory the file takes once read.
    what : str
        What makes it large, for the message (e.g. ``"12,000,000,000 points"``).

    Raises
    ------
    FileFormatError
        ``needed_bytes`` exceeds :data:`MEMORY_FRACTION` of the memory available now.
    """
    free = available_bytes()
    if needed_bytes > MEMORY_FRACTION * free:
        raise FileFormatError(
            Path(path), f"is too large to read: {what} need about {needed_bytes / 2**30:.1f} GiB of memory, "
            f"{free / 2**30:.1f} GiB is available",
            hint="thin or crop it in the scanner or CAD software, or read it on a machine with more memory",
        )


@contextmanager
def quiet():
    """Send what C and C++ code print on file descriptors 1 and 2 to a buffer.

    Yields a list that holds, after the block, the captured text (ANSI colours removed).
    Python's own ``sys.stdout`` / ``sys.stderr`` are flushed first. Where the descriptors
    cannot be duplicated (closed streams), the block runs unredirected. The descriptors are
    the process's: what another thread prints meanwhile is caught too, so blocks are kept to
    the library calls that print (an import, a tessellation, a scan read).
    """
    captured: list[str] = []
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, ValueError, OSError):
            pass
    try:
        saved = (os.dup(1), os.dup(2))
    except OSError:
        yield captured
        return
    import tempfile  # here: reading a point file needs no temporary file

    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 1)
        os.dup2(sink.fileno(), 2)
        try:
            yield captured
        finally:
            _flush_c_streams()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
            sink.seek(0)
            captured.append(_ANSI.sub("", sink.read().decode("utf-8", "replace")))


def _flush_c_streams() -> None:
    """fflush(NULL): C stdio (and C++ iostreams synced with it) buffer what they print."""
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):
        pass
