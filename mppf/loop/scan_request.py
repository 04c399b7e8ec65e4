"""The scan request: the loop tells the scanner station that a cycle is pressed, and what to scan.

When a cycle is pressed the loop writes ``<plate>-cycle-<NN>.scan-request.json`` into the
folder the scans arrive in (the scanner's folder; with the simulated scanner the plate's work
folder), atomically (a temporary file renamed into place), and removes it once the scan is
taken, or when the wait ends in any other way (a timeout, Ctrl-C, an error). Then the optional
``on_pressed`` command runs (:func:`run_on_pressed`). The schema, with an example, is in
``docs/scanner-station.md``; :data:`REQUEST_VERSION` changes only when a key changes meaning
or goes away (new keys may be added within a version).
"""

from __future__ import annotations

import json
import os
import shlex
import subprocess
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from mppf.core.progress import Reporter
from mppf.geometry.read import READ_SUFFIXES
from mppf.loop.records import CycleRecord, PlateRecord
from mppf.loop.settings import LoopSettings
from mppf.measure.mark import mark_path
from mppf.model.job import Job

REQUEST_FORMAT = "mppf-scan-request"
REQUEST_VERSION = 1
REQUEST_SUFFIX = ".scan-request.json"
"""A request file is ``<plate id>-cycle-<NN>`` + this suffix."""

SCAN_SUFFIX = ".ply"
"""The suffix of the scan file name the request asks for (any point format of :data:`SCAN_FORMATS` is taken)."""

SCAN_FORMATS = tuple(s for s in READ_SUFFIXES if s not in (".stl", ".obj", ".step", ".stp", ".iges", ".igs"))
"""Point formats a scan may come in."""

REQUEST_ENV = "MPPF_SCAN_REQUEST"
"""The environment variable that holds the request file's path for the ``on_pressed`` command."""

FRAME = ("press coordinates, mm: x along the punch columns, y along the rows, origin at the centre of the "
         "punch matrix, z up; the flat plate's bottom skin at z = 0")

SKIN_MEANING = ("top = the design's +normal side, offset by half the thickness: the side from which a curved "
                "plate looks concave (the inside of the bowl), whichever side faces the scanner; the loop lays "
                "the plate with that side up on the press")


@dataclass(frozen=True)
class PostedRequest:
    """A request file written into the scan folder.

    Attributes
    ----------
    path : Path
        The request file.
    scan_path, mark_path : Path
        Where the scan and its mark are expected.
    written : bool
        False: the folder refused the file (nothing to withdraw).
    """

    path: Path
    scan_path: Path
    mark_path: Path
    written: bool = True

    def withdraw(self) -> None:
        """Remove the request file (the scan is taken, or the wait ended); a file already gone is fine."""
        if not self.written:
            return
        try:
            self.path.unlink(missing_ok=True)
        except OSError:  # a read-only folder: the next request replaces it
            pass


@dataclass(frozen=True)
class RescanAsk:
    """What a rescan request asks for: which rescan, of which regions, in the frame of which scan.

    Attributes
    ----------
    number : int
        K >= 1: the cycle's K-th rescan (of at most ``settings.rescans``).
    regions : tuple of dict
        What to rescan, each with a ``kind``: "uncovered", areas not measured
        (:func:`mppf.loop.rescanning.region_doc`); "artefacts", spots of set-aside points beyond
        the tolerance (:func:`mppf.loop.rescanning.artefact_spots`).
    first_scan : dict or None
        The cycle's first scan, ``{"path", "sha256"}``: the rescan is in its frame and the
        union of the scans is compared.
    spots_total : int
        How many artefact spots there are (the request lists at most
        :data:`mppf.loop.rescanning.SPOTS_LISTED` of them).
    """

    number: int
    regions: tuple = ()
    first_scan: dict | None = None
    spots_total: int = 0


NO_RESCAN = RescanAsk(0)
"""The cycle's own scan: no rescan, no regions."""


def _stem(plate_id: str, cycle: int, rescan: int = 0) -> str:
    return f"{plate_id}-cycle-{int(cycle):02d}" + (f"-rescan-{int(rescan)}" if rescan else "")


def request_name(plate_id: str, cycle: int, rescan: int = 0) -> str:
    """The request file's name: ``<plate id>-cycle-<NN>.scan-request.json`` (a rescan: ``...-cycle-<NN>-rescan-<K>...``)."""
    return _stem(plate_id, cycle, rescan) + REQUEST_SUFFIX


def scan_name(plate_id: str, cycle: int, rescan: int = 0) -> str:
    """The scan file name the request asks for: ``<plate id>-cycle-<NN>.ply`` (a rescan: ``...-rescan-<K>.ply``)."""
    return _stem(plate_id, cycle, rescan) + SCAN_SUFFIX


def build_request(plate: PlateRecord, record: CycleRecord, job: Job, settings: LoopSettings, folder,
                  *, mark_required: bool | None = None, now: datetime | None = None,
                  rescan: RescanAsk = NO_RESCAN) -> dict:
    """The request document of a pressed cycle (see ``docs/scanner-station.md`` for every key).

    Parameters
    ----------
    plate : PlateRecord
    record : CycleRecord
        The pressed cycle.
    job : Job
        Its job: the plate's layout on the press (outline as cut, mark corner).
    settings : LoopSettings
        The skin offset and the mark waits.
    folder : path-like
        The folder the scan is expected in.
    mark_required : bool or None
        Whether the loop compares a scan of this plate only with its mark (None: not decided).
    rescan : RescanAsk
        :data:`NO_RESCAN`: the cycle's scan; else its ``rescan.number``-th rescan, of the
        regions of ``rescan`` in the frame of its first scan.
    """
    folder = Path(folder).resolve()
    scan_path = folder / scan_name(plate.plate_id, record.cycle, rescan.number)
    layout = job.layout
    offset_mm = plate.thickness_mm / 2.0 if settings.offset_mm is None else float(settings.offset_mm)
    doc = {
        "format": REQUEST_FORMAT,
        "version": REQUEST_VERSION,
        "written_utc": (now or datetime.now(UTC)).isoformat(timespec="seconds"),
        "plate_id": plate.plate_id,
        "cycle": int(record.cycle),
        "job": {"path": str(record.job_path), "sha256": record.job_sha256},
        "frame": FRAME,
        "scan": {
            "path": str(scan_path),
            "formats": list(SCAN_FORMATS),
            "units": "mm (E57: metres, by the standard)",
            "skin": "top" if settings.offset_mm is None else "offset",
            "skin_offset_mm": offset_mm,
            "skin_meaning": SKIN_MEANING,
        },
        "mark": _mark_doc(scan_path, layout, settings, mark_required),
        "plate": {
            "thickness_mm": float(plate.thickness_mm),
            "margin_mm": None if layout is None else float(layout.margin_mm),
            "outline_cut_press_mm": None if layout is None else _rounded(layout.outline_mm),
            "net_outline_press_mm": None if layout is None else _rounded(layout.net_outline_mm),
        },
        "rescan": int(rescan.number),
        "rescans": int(settings.rescans),
        "regions": list(rescan.regions),
        "artefact_spots": int(rescan.spots_total),
        "first_scan": rescan.first_scan,
    }
    if rescan.number:  # the rescan is placed by the first scan's frame: no mark of its own
        doc["mark"].update(required=False, settle_s=0.0,
                           note="a rescan needs no mark: it must be in the frame of the cycle's first scan "
                                "(a fixed station), whose mark places the union")
    return doc


def _mark_doc(scan_path: Path, layout, settings: LoopSettings, mark_required: bool | None) -> dict:
    """The request's ``mark`` block: where the scan's reference mark goes, the plate's corner, the waits (s)."""
    return {
        "path": str(mark_path(scan_path)),
        "file": {"reference_mark_mm": ["x", "y", "z"]},
        "header_line": {"ply": "comment reference_mark_mm X Y Z", "text": "# reference_mark_mm X Y Z"},
        "corner_press_mm": None if layout is None else [round(float(v), 3) for v in layout.reference_corner_mm],
        "corner": "the corner of the plate as cut (margin included) with the smallest press x + y",
        "required": mark_required,
        "settle_s": float(settings.mark_settle_s),
        "timeout_s": float(settings.mark_timeout_s),
    }


def _rounded(points) -> list:
    return [[round(float(x), 3), round(float(y), 3)] for x, y in points]


def write_request(folder, doc: dict) -> PostedRequest:
    """Write the request into ``folder`` atomically (``.<name>.tmp``, renamed into place).

    Raises
    ------
    InputError
        The folder is not writable.
    """
    from mppf.core.errors import InputError

    folder = Path(folder)
    path = folder / request_name(doc["plate_id"], doc["cycle"], doc.get("rescan", 0))
    tmp = folder / f".{path.name}.tmp"
    try:
        tmp.write_text(json.dumps(doc, indent=2) + "\n")
        os.replace(tmp, path)
    except OSError as exc:
        raise InputError(f"cannot write the scan request {path}: {exc.strerror or exc}",
                         hint="the scan folder must be writable by mppf") from None
    return PostedRequest(path, Path(doc["scan"]["path"]), Path(doc["mark"]["path"]))


def run_on_pressed(command: str, request_path, reporter: Reporter, timeout_s: float) -> int | None:
    """Run the ``on_pressed`` command with the request file; report what happened, never raise.

    The command line is split like a shell would (:func:`shlex.split`) but run without a
    shell (no expansion, no injection); the request file's path is appended as the last
    argument and put in :data:`REQUEST_ENV`. It must end within ``timeout_s`` (then it is
    killed). Its failure is reported and the loop goes on (the request file stays for the
    station to find).

    Returns
    -------
    int or None
        The command's exit status; None when it could not start or timed out.
    """
    try:
        args = shlex.split(command) + [str(request_path)]
    except ValueError as exc:
        reporter.info(f"on-pressed command not run: cannot split {command!r}: {exc}; the loop goes on")
        return None
    env = {**os.environ, REQUEST_ENV: str(request_path)}
    try:
        done = subprocess.run(args, env=env, capture_output=True, text=True, timeout=timeout_s, shell=False,
                              stdin=subprocess.DEVNULL, check=False)
    except subprocess.TimeoutExpired:
        reporter.info(f"on-pressed command {args[0]!r} did not end within {timeout_s:g} s: killed; the loop goes "
                      "on waiting for the scan")
        return None
    except OSError as exc:
        reporter.info(f"on-pressed command {args[0]!r} could not start: {exc.strerror or exc}; the loop goes on "
                      "waiting for the scan")
        return None
    if done.returncode != 0:
        tail = (done.stderr or done.stdout or "").strip().splitlines()[-1:] or ["no output"]
        reporter.info(f"on-pressed command {args[0]!r} failed (exit {done.returncode}: {tail[0][:200]}); the loop "
                      "goes on waiting for the scan")
    else:
        reporter.info(f"on-pressed command {args[0]!r} done (exit 0)")
    return done.returncode


def post_request(plate: PlateRecord, record: CycleRecord, job: Job, settings: LoopSettings, folder, reporter: Reporter,
                 *, mark_required: bool | None = None, rescan: RescanAsk = NO_RESCAN) -> PostedRequest:
    """Write the pressed cycle's request (or its ``rescan.number``-th rescan's) into ``folder``, say so, and run the
    ``on_pressed`` command.

    A folder the request cannot be written into is reported and the loop goes on waiting for
    the scan (as before there were requests); the ``on_pressed`` command then does not run.
    """
    from mppf.core.errors import InputError

    # 1. the request, atomically, where the station looks
    doc = build_request(plate, record, job, settings, folder, mark_required=mark_required, rescan=rescan)
    what = f"rescan {rescan.number} of {settings.rescans} asked" if rescan.number else "pressed"
    try:
        posted = write_request(folder, doc)
    except InputError as exc:
        reporter.info(f"cycle {record.cycle}: {what}; {exc.message}: no scan request for the station, "
                      f"the on-pressed command not run; waiting for the scan all the same")
        return PostedRequest(Path(folder) / request_name(plate.plate_id, record.cycle, rescan.number),
                             Path(doc["scan"]["path"]), Path(doc["mark"]["path"]), written=False)
    if rescan.number:
        kinds = [r.get("kind", "uncovered") for r in doc["regions"]]
        listed = [f"{kinds.count('uncovered')} area(s)"] if "uncovered" in kinds else []
        listed += [f"{kinds.count('artefacts')} artefact spot(s)"] if "artefacts" in kinds else []
        reporter.info(f"cycle {record.cycle}: {what}; scan request {posted.path}: scan the {' and '.join(listed)} "
                      f"to {posted.scan_path.name}, in the frame of the first scan")
    else:
        reporter.info(f"cycle {record.cycle}: pressed; scan request {posted.path}: scan to {posted.scan_path.name}, "
                      f"its mark to {posted.mark_path.name}")
    # 2. the station's trigger, when configured (its failure is reported, never fatal)
    if settings.on_pressed:
        run_on_pressed(settings.on_pressed, posted.path, reporter, settings.on_pressed_timeout_s)
    return posted
