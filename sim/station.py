"""The simulated scanner station of ``mppf sim --station DIR``: a plate pressed with what the PLC did, scanned on request.

A yard's dry run without steel: ``mppf sim`` is the press PLC in its own process, ``mppf loop --plc URL
--scanner DIR`` drives it and waits for scans in DIR, and this station, running inside the simulator,
stands in for the plate and the scanner station:

1. :class:`MotionLog` follows the PLC program scan by scan. Every motion (GO) that ends, complete
   (COMPLETE) or cut short (STOPPED, FAULT, a restart), is kept with the tip heights the punches came
   to rest at; a pair whose both tips are parked (within :data:`PARK_TOLERANCE_MM` of the press's park
   heights) does not act on the plate.
2. :class:`ScanStation` watches DIR for the loop's scan requests (``*.scan-request.json``,
   docs/scanner-station.md). The plate is the one of the job the request names (its layout on the
   press: outline as cut, net outline, thickness; the request's ``plate_id`` keys it): the station needs
   neither the design nor the flat file, as a real station needs only the plate on its table. For a
   cycle's request it presses that plate with every motion since its last scan, in order
   (:class:`mppf.sim.shop.SimulatedPlateScanner`: the finite-difference steel plate or the FE plate,
   seeded by ``--plate-seed``), scans it and writes the mark file, then the scan (both staged in
   :data:`STATE_FOLDER` and renamed into DIR, so the loop never reads half a file); a rescan request
   (``rescan`` >= 1) is answered with a take aimed at its regions, in the first take's frame.

The plate's state is saved after every scan (``<DIR>/.mppf-station/<plate id>/sim-plate.npz``): a
station restarted between cycles continues on the same plate. A plate pressed in sections is not
simulated here (the station says so and leaves the request unanswered). See docs/simulator.md.
"""

from __future__ import annotations

import json
import os
import re
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mppf.core.errors import InputError, MppfError
from mppf.core.progress import NullReporter
from mppf.core.scanner import PressedStep, ScanContext
from mppf.model.press import PressConfig

PARK_TOLERANCE_MM = 1.0
"""A tip within this much of its matrix's park height (beyond the press's position tolerance) is parked."""

STATE_FOLDER = ".mppf-station"
"""The station's own folder inside DIR: each plate's state and the files being written."""

MOVING = ("EXECUTING", "STOPPING")
"""PLC states of a motion under way."""

POLL_S = 0.2
"""Interval between looks into DIR for a new request."""

SAFE_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,99}$")
"""A plate id the station makes a folder of."""


@dataclass(frozen=True)
class Motion:
    """One motion of the press as the PLC ended it.

    Attributes
    ----------
    upper_mm, lower_mm : (rows, cols) float
        Where the tips came to rest, mm.
    active : (rows, cols) bool
        Pairs not parked (acting on the plate).
    complete : bool
        The PLC reported the motion COMPLETE (False: stopped, faulted or restarted on its way).
    """

    upper_mm: np.ndarray
    lower_mm: np.ndarray
    active: np.ndarray
    complete: bool


def active_pairs(press: PressConfig, upper_mm, lower_mm) -> np.ndarray:
    """Pairs (rows, cols) bool whose tips are not both at their park heights."""
    tol = PARK_TOLERANCE_MM + press.position_tolerance_mm
    parked = ((np.abs(np.asarray(upper_mm) - press.upper.park_mm) <= tol)
              & (np.abs(np.asarray(lower_mm) - press.lower.park_mm) <= tol))
    return ~parked


class MotionLog:
    """The motions a simulated PLC program ended, kept as they end (thread-safe).

    :meth:`follow` wraps the program's scan (``advance``): after each scan a motion that started
    (the state became EXECUTING) and has ended (the state is no longer EXECUTING or STOPPING and
    every punch is at rest) is appended with the tips' rest heights.
    """

    def __init__(self, press: PressConfig):
        self.press = press
        self._motions: list[Motion] = []
        self._lock = threading.Lock()
        self._open = False
        self.count = 0

    def follow(self, program) -> None:
        """Observe ``program`` (a :class:`mppf.sim.plc.program.PlcProgram`) after each of its scans."""
        scan = program.advance

        def advance(dt_s: float) -> None:
            scan(dt_s)
            self.observe(program)

        program.advance = advance

    def observe(self, program) -> None:
        """Look at the program after a scan: open a motion at EXECUTING, close it at rest after it."""
        if program.state in MOVING:
            self._open = True
            return
        if not self._open or not program.at_rest:
            return
        self._open = False
        upper, lower = program.actual_positions_mm()
        motion = Motion(upper, lower, active_pairs(self.press, upper, lower), program.state == "COMPLETE")
        with self._lock:
            self._motions.append(motion)
            self.count += 1

    def take(self) -> list[Motion]:
        """The motions ended since the last call, in order (and forget them)."""
        with self._lock:
            motions, self._motions = self._motions, []
        return motions


class _Say(NullReporter):
    """The station's reporter: the simulated plate's progress lines (ccx) as station lines."""

    def __init__(self, say):
        self.say = say

    def info(self, message: str) -> None:
        self.say(f"station: {message}")


class ScanStation:
    """Answers the loop's scan requests in ``folder`` with scans of a simulated plate.

    Parameters
    ----------
    folder : path-like
        The scan folder (``mppf loop --scanner DIR``); created when missing.
    press : PressConfig
        The simulated press (its park heights tell parked pairs; a job for another press is refused).
    log : MotionLog
        The motions of the simulated PLC.
    physics : {"fd", "fe"}
        The plate: the finite-difference steel plate or the FE plate (CalculiX).
    seed : int
        Seeds the plates' true properties and the scans.
    say : callable
        Called with one line (str) per event.
    """

    def __init__(self, folder, press: PressConfig, log: MotionLog, *, physics: str = "fd", seed: int = 0,
                 say=print):
        from mppf.sim.shop import PHYSICS

        if physics not in PHYSICS:
            raise InputError(f"unknown plate physics {physics!r}", hint=f"use {' or '.join(PHYSICS)}")
        if physics == "fe":
            from mppf.sim.fe.ccx import find_ccx

            find_ccx()  # without CalculiX: how to install it, before the simulator starts
        self.folder = Path(folder)
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            (self.folder / STATE_FOLDER).mkdir(exist_ok=True)
        except OSError as exc:
            raise InputError(f"cannot use the station folder {self.folder}: {exc.strerror or exc}",
                             hint="give a folder the simulator may write into (--station DIR)") from None
        self.press, self.log, self.physics, self.seed, self.say = press, log, physics, int(seed), say
        self.plates: dict = {}  # plate id -> SimulatedPlateScanner
        self.cycle_steps: dict = {}  # (plate id, cycle) -> the steps pressed for it
        self.answered: set = set()

    def poll(self) -> int:
        """Answer every request in the folder not answered yet; the number answered."""
        done = 0
        for path in sorted(self.folder.glob("*.scan-request.json")):
            try:
                request = json.loads(path.read_text())
            except (OSError, ValueError):  # withdrawn or being replaced while read: the next poll
                continue
            key = (path.name, request.get("written_utc"))
            if key in self.answered:
                continue
            self.answered.add(key)
            try:
                self.answer(request)
                done += 1
            except MppfError as exc:
                hint = f" ({exc.hint})" if getattr(exc, "hint", None) else ""
                self.say(f"station: request {path.name} not answered: {exc.message}{hint}")
            except (OSError, KeyError, TypeError, ValueError) as exc:  # a request's paths or values the station
                self.say(f"station: request {path.name} not answered: {type(exc).__name__}: {exc}")  # cannot use
        return done

    def run(self, stop: threading.Event) -> None:
        """Poll until ``stop`` is set."""
        while not stop.is_set():
            self.poll()
            stop.wait(POLL_S)

    def answer(self, request: dict) -> Path:
        """Press and scan the plate a request names; write its mark and scan where the request asks.

        Raises
        ------
        InputError
            A request or job the station cannot act on (named, with the value seen).
        """
        plate_id, cycle, number = _request_keys(request)
        scanner = self._scanner(plate_id, request)
        staging = self.folder / STATE_FOLDER / plate_id
        scan_path = Path(request["scan"]["path"])
        staged = staging / scan_path.name
        context = self._context(plate_id, cycle, staging, request, number)
        if number:
            self.say(f"station: {plate_id} cycle {cycle}: rescan {number}, {len(context.regions)} region(s) asked")
            written = scanner.rescan(cycle, number, context, path=staged)
        else:
            new = [s for s in context.steps if [s.cycle, s.step] not in scanner.pressed]
            self.say(f"station: {plate_id} cycle {cycle}: pressing {len(new)} motion(s) on the {self.physics} plate")
            started = time.monotonic()
            written = scanner.acquire(cycle, context, path=staged)
            self.say(f"station: {plate_id} cycle {cycle}: pressed in {time.monotonic() - started:.1f} s")
            mark = Path(str(written) + ".mark.json")
            if mark.exists():  # the mark first: the loop finds it with the scan
                os.replace(mark, Path(request["mark"]["path"]))
        os.replace(written, scan_path)
        self.say(f"station: scan {scan_path.name} written")
        return scan_path

    def _scanner(self, plate_id: str, request: dict):
        """The simulated plate and scanner of a plate id (made from the request's job at its first request)."""
        if plate_id in self.plates:
            return self.plates[plate_id]
        from mppf.sim.shop import PHYSICS, SimulatedPlateScanner

        from mppf.planning.job import load_job

        job = load_job(request["job"]["path"], require_seal=False)
        if job.press.shape != self.press.shape:
            raise InputError(f"the job {request['job']['path']} is for a {job.press.rows} x {job.press.cols} press, "
                             f"the simulator has {self.press.rows} x {self.press.cols}",
                             hint="start mppf sim with the job's press (--press)")
        if job.layout is None or job.sections:
            raise InputError(f"the job {request['job']['path']} has "
                             + ("no plate layout (an old job)" if job.layout is None else
                                f"{len(job.sections)} sections") + ": the station presses one placed plate",
                             hint="plan the plate again with this mppf, on a bed it fits")
        scanner = SimulatedPlateScanner.for_job(self.press, job.thickness_mm, job, None, seed=self.seed,
                                                plate_model=PHYSICS[self.physics])
        self.plates[plate_id] = scanner
        self.say(f"station: plate {plate_id}: {job.thickness_mm:g} mm, the {self.physics} plate, seed {self.seed}")
        return scanner

    def _context(self, plate_id: str, cycle: int, work_dir: Path, request: dict, number: int) -> ScanContext:
        """The scan context: the motions since the plate's last scan as the cycle's steps (a rescan: the same).

        The steps are numbered after those of the cycle already pressed on the plate (also by a station
        run before this one: its saved state), so none is pressed twice and none is skipped.
        """
        from mppf.sim.shop import STATE_FILE

        key = (plate_id, cycle)
        if number == 0 or key not in self.cycle_steps:
            self.plates[plate_id].restore(work_dir / STATE_FILE)
            known = self.cycle_steps.get(key, ())
            base = max([len(known)] + [s for c, s in self.plates[plate_id].pressed if c == cycle])
            new = [m for m in self.log.take() if m.active.any()]
            self.cycle_steps[key] = tuple(known) + tuple(
                PressedStep(cycle, base + k, m.upper_mm, m.lower_mm, m.active) for k, m in enumerate(new, start=1))
        steps = self.cycle_steps[key]
        if number == 0:
            steps = tuple(s for s in steps if [s.cycle, s.step] not in self.plates[plate_id].pressed)
        if not steps:  # not pressed again since its last scan: scanned as it lies (its last step, pressed already)
            pressed = self.plates[plate_id].pressed
            if not pressed:
                raise InputError(f"plate {plate_id} cycle {cycle}: no press motion recorded by this simulator",
                                 hint="press the cycle on this simulator (mppf loop --plc URL of mppf sim --station)")
            shape = self.press.shape
            steps = (PressedStep(*pressed[-1], np.full(shape, np.nan), np.full(shape, np.nan),
                                 np.zeros(shape, dtype=bool)),)
            if number == 0:
                self.say(f"station: {plate_id} cycle {cycle}: no motion since its last scan: scanned as it lies")
        regions = tuple(request.get("regions") or ()) if number else ()
        return ScanContext(plate_id=plate_id, work_dir=work_dir, since_s=0.0, upper_mm=steps[-1].upper_mm,
                           lower_mm=steps[-1].lower_mm, active=steps[-1].active, steps=steps,
                           reporter=_Say(self.say), regions=regions)


def _request_keys(request: dict) -> tuple[str, int, int]:
    """Plate id, cycle and rescan number of a request, checked."""
    try:
        plate_id, cycle, number = request["plate_id"], int(request["cycle"]), int(request.get("rescan", 0))
        request["scan"]["path"], request["mark"]["path"], request["job"]["path"]
    except KeyError as exc:
        raise InputError(f"a scan request without {exc}", hint="see docs/scanner-station.md for its keys") from None
    except (TypeError, ValueError):
        raise InputError(f"a scan request with cycle {request.get('cycle')!r}, rescan {request.get('rescan', 0)!r}",
                         hint="the cycle and the rescan are whole numbers (docs/scanner-station.md)") from None
    if not isinstance(plate_id, str) or not SAFE_ID.match(plate_id):
        raise InputError(f"a scan request for plate id {plate_id!r}", hint="plate ids are letters, digits, _ . -")
    return plate_id, cycle, number
