"""Measuring a pressed cycle: take the scan, compare it with the design.

A scan that cannot be read, or that does not match the design (another plate, other
units), is recorded as rejected (never taken again) and the cycle waits in "pressed" for
another one. A scan of this plate far from its design (its outline and shape are the
design's, its point count the previous cycle's scan's) is not rejected: it is judged, badly
formed, and the loop stops there (:mod:`mppf.measure.same_plate`, ``Decision.BADLY_FORMED``).
Every file the loop reads back (design, scan, job) is checked against the SHA-256 recorded
for it. A cycle rescanned where areas were not measured or set-aside points lie beyond the
tolerance (:mod:`mppf.loop.rescanning`) is compared as the union of its scans, in the first
scan's frame, knowing the scan of each point (a set-aside point another scan measured within
the tolerance is cleared); the files are listed in its stored comparison (``scans``), and
:func:`compare_recorded` compares the same union.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from mppf.core.errors import GeometryError, InputError
from mppf.core.progress import Reporter
from mppf.core.scanner import Scanner
from mppf.geometry.read import PointCloud, read_points
from mppf.loop.history import History
from mppf.loop.pressing import scan_context
from mppf.loop.records import CycleRecord, PlateRecord, load_cycle_job
from mppf.loop.settings import LoopSettings
from mppf.measure.compare import compare
from mppf.measure.job_options import job_compare_options
from mppf.measure.options import CompareOptions
from mppf.model.press import PressConfig
from mppf.registration.scan_start import AmbiguousStart


def read_checked(path, sha256: str, what: str, units: str = "mm") -> PointCloud:
    """Read a point file the history names; InputError when it changed since it was recorded."""
    cloud = read_points(path, units=units)
    if cloud.sha256 != sha256:
        raise InputError(
            f"the {what} file {path} changed since the plate was planned "
            f"(SHA-256 {cloud.sha256[:12]}..., recorded {sha256[:12]}...)",
            hint=f"restore the original {what} file, or start a new plate",
        )
    return cloud


def acquire_scan(history: History, plate: PlateRecord, record: CycleRecord, press: PressConfig, scanner: Scanner,
                 reporter: Reporter) -> None:
    """Get the scan of the pressed cycle from the scanner and record it ("scanned").

    Raises
    ------
    InputError
        No scan came, or it cannot be read (FileFormatError: recorded as rejected).
    """
    context = scan_context(history, plate, record, press, reporter)
    context = dataclasses.replace(context, used_paths=context.used_paths + rescan_paths(history, plate.plate_id))
    path = Path(scanner.acquire(record.cycle, context)).resolve()
    try:
        scan = read_points(path)
    except InputError as exc:  # unreadable: never taken again, wait for another
        history.reject_scan(plate.plate_id, record.cycle, path, "", exc.message)
        raise
    history.mark_scanned(plate.plate_id, record.cycle, path, scan.sha256)


def compare_cycle(history: History, plate: PlateRecord, record: CycleRecord, design: PointCloud,
                  settings: LoopSettings):
    """The comparison of the cycle's scan with the design (:func:`mppf.measure.compare.compare`).

    Raises
    ------
    GeometryError
        The scan is not of this plate (or in other units): recorded as rejected, the cycle
        goes back to "pressed".
    AmbiguousStart
        The scan fits the design two ways round (a nearly symmetric plate) and carries no
        reference mark: it is not judged; recorded as rejected ("ambiguous: give the
        reference mark", both candidates), the cycle goes back to "pressed" for a scan with
        its ``<scan>.mark.json`` (exit 4).
    """
    try:
        return _compare(plate, record, design, settings, _expected_points(history, record))
    except (GeometryError, AmbiguousStart) as exc:  # not judged: back to "pressed", wait for another
        history.reject_scan(plate.plate_id, record.cycle, record.scan_path, record.scan_sha256, exc.message)
        raise


def compare_recorded(plate: PlateRecord, record: CycleRecord, design: PointCloud, settings: LoopSettings):
    """The comparison of a recorded cycle's scan (the union of its merged scans), made again (for a report
    written afterwards; nothing recorded).

    Raises
    ------
    InputError
        A scan file is missing or changed since it was recorded.
    """
    merged = [s for s in (record.comparison or {}).get("scans", [])[1:] if s.get("merged")]
    return _compare(plate, record, design, settings, extra=merged)


def compare_union(plate: PlateRecord, record: CycleRecord, design: PointCloud, settings: LoopSettings, rescans: list,
                  start_from=None):
    """The comparison of the union of the cycle's scan and ``rescans`` (``{"path", "sha256"}`` dicts, the
    same frame); nothing recorded, nothing rejected.

    ``start_from``: the comparison whose frame the scans share (the cycle's first scan's, or the union
    so far): its registration is refined, not chosen again.

    Raises
    ------
    GeometryError, AmbiguousStart
        The union does not register onto the design.
    """
    return _compare(plate, record, design, settings, extra=rescans, start_from=start_from)


def rescan_paths(history: History, plate_id: str) -> tuple[str, ...]:
    """Every rescan file the plate's compared cycles took (never taken again as another scan)."""
    return tuple(s["path"] for c in history.cycles(plate_id) for s in (c.comparison or {}).get("scans", [])[1:])


def _expected_points(history: History, record: CycleRecord) -> int | None:
    """The point count of the previous cycle's (first) scan (None for the first cycle)."""
    if record.cycle <= 1:
        return None
    previous = history.cycle(record.plate_id, record.cycle - 1).comparison
    if not previous:
        return None
    scans = previous.get("scans")
    return scans[0]["n_points"] if scans else previous.get("n_points")


def _compare(plate: PlateRecord, record: CycleRecord, design: PointCloud, settings: LoopSettings,
             expected_points: int | None = None, extra: list = (), start_from=None):
    scan = read_checked(record.scan_path, record.scan_sha256, "scan")
    clouds = [scan.points] + [read_checked(s["path"], s["sha256"], "rescan").points for s in extra]
    points = np.vstack(clouds)
    # the scan of each point (0 the first, K the K-th rescan): a rescan clears the artefacts it re-measured
    scan_index = np.concatenate([np.full(c.shape[0], i) for i, c in enumerate(clouds)]) if extra else None
    job = load_cycle_job(record)
    offset_mm = plate.thickness_mm / 2.0 if settings.offset_mm is None else settings.offset_mm
    # the same options as ``mppf compare --job``: the same scan gets the same verdict
    base = CompareOptions(tolerance_mm=settings.tolerance_mm, rms_tolerance_mm=settings.rms_tolerance_mm,
                          expected_points=None if extra else expected_points, scan_index=scan_index,
                          start_from=start_from)
    return compare(design.points, points,
                   job_compare_options(job, design.points, record.scan_path, offset_mm=offset_mm, base=base))


def comparison_summary(comparison, scans: list | None = None, rescan_stopped: str | None = None) -> dict:
    """The comparison as stored with the cycle (the punch deviations have their own column).

    ``scans``: every scan the cycle took (:func:`mppf.loop.rescanning.rescan_uncovered`), the first one
    first; the comparison is of the union of those ``merged``. ``rescan_stopped``: why a rescan was not
    merged (the loop stopped for review).
    """
    doc = comparison.to_dict()
    doc.pop("punch_deviation_mm", None)
    if scans is not None:
        doc["scans"] = list(scans)
        doc["rescan_stopped"] = rescan_stopped
    return doc
