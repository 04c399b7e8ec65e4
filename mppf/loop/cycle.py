"""The bend - measure - compare loop of one plate: a state machine, resumable after a crash.

:func:`mppf.loop.plate.start_plate` plans the job and records the plate and its first
cycle in the history; :func:`run_loop` then drives every cycle through its states
(:mod:`mppf.loop.states`), one handler per state, until the plate is in tolerance, the
cycles run out, or the error diverges:

    planned   -> press every step of the cycle's job (of every
                 section, the plate shifted between them)      -> pressing -> pressed
    pressing  -> (interrupted) never press again               -> pressed
    pressed   -> request the scan (the station's request file, --on-pressed),
                 get it, complete with its reference mark     -> scanned
    scanned   -> register it to the design, deviations; areas not measured
                 (alone): rescan them, compare the union       -> compared (+ decision)
    compared  -> correct the strokes, plan the next cycle      -> corrected | done
                 (or stop with a verdict: cannot converge)      -> done

Each state is committed before the next action, so :func:`run_loop` called again on the
same plate (``mppf loop --resume``) continues where the last run stopped. A cycle found in
"pressing" is never pressed again: the press either finished the step or was stopped by
the PLC's watchdog when the master died, so the plate is measured as it is and the next
cycle corrects whatever happened.

A plate larger than the bed (a sectional job) is pressed section by section, scanned and
compared whole, and corrected section by section (:mod:`mppf.loop.sectional`); a cycle of it
found in "pressing" goes on with the steps not started (the plate is measured whole), never
pressing a step recorded as started.

The loop takes the press (:class:`mppf.core.presslink.PressLink`) and the scanner
(:class:`mppf.core.scanner.Scanner`) as arguments and reports through a
:class:`mppf.core.progress.Reporter`; it prints nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from mppf.core.presslink import PressLink
from mppf.core.progress import NULL_REPORTER, Reporter
from mppf.core.scanner import Scanner
from mppf.geometry.read import PointCloud
from mppf.loop.correcting import check_correctable, plan_next
from mppf.loop.decide import decide
from mppf.loop.endings import Ending, ending
from mppf.loop.history import History
from mppf.loop.marks import MarkedScanner, MarkNeed, needs_mark, plausible_scan
from mppf.loop.measuring import (
    acquire_scan,
    compare_cycle,
    comparison_summary,
    read_checked,
)
from mppf.loop.pressing import press_cycle
from mppf.loop.records import CycleRecord, PlateRecord, load_cycle_job
from mppf.loop.rescanning import rescan_uncovered
from mppf.loop.scan_request import PostedRequest, post_request
from mppf.loop.section_steps import is_sectional
from mppf.loop.sectional import (
    PlaceCallback,
    plan_next_sections,
    press_sections,
    report_placement,
    section_deviations,
)
from mppf.loop.settings import LoopSettings
from mppf.loop.states import CycleState, Decision
from mppf.model.press import PressConfig, press_from_dict
from mppf.planning.job import load_job

#: Called with each cycle record once compared (and again when corrected or done),
#: plus the comparison when it was computed in this run (else None).
CycleCallback = Callable[[CycleRecord, object], None]


@dataclass(frozen=True)
class LoopResult:
    """Outcome of :func:`run_loop`.

    Attributes
    ----------
    plate_id : str
    status : Decision
        IN_TOLERANCE, NEEDS_REVIEW, MAX_CYCLES, DIVERGED or CANNOT_CONVERGE.
    cycles : list of CycleRecord
        Every cycle of the plate, as stored in the history.
    resumed_state : CycleState or None
        State of the cycle the run started from when it continued an earlier run
        (None for a plate that no run had touched since planning).
    verdict : str or None
        The ending in one line (:attr:`mppf.loop.endings.Ending.text`: why, where, what to do).
    ending : Ending or None
        The same as data, with the exit code of ``mppf loop``.
    """

    plate_id: str
    status: Decision
    cycles: list
    resumed_state: CycleState | None = None
    verdict: str | None = None
    ending: Ending | None = None

    @property
    def last(self) -> CycleRecord:
        """The last cycle."""
        return self.cycles[-1]


@dataclass(frozen=True)
class _Run:
    """What every state handler of one :func:`run_loop` call works with."""

    history: History
    plate: PlateRecord
    press: PressConfig
    settings: LoopSettings
    design: PointCloud
    link: PressLink
    scanner: Scanner
    reporter: Reporter
    on_cycle: CycleCallback | None
    verdicts: list
    known: dict
    place: PlaceCallback | None = None

    def notify(self, record: CycleRecord, comparison) -> None:
        if self.on_cycle is not None:
            self.on_cycle(record, comparison)

    def mark_need(self) -> MarkNeed:
        """Whether the plate's scans need the reference mark (worked out once per run, when first asked)."""
        if "mark_need" not in self.known:
            rms = [c.rms_mm for c in self.history.cycles(self.plate.plate_id) if c.rms_mm is not None]
            self.known["mark_need"] = needs_mark(self.design.points, max(rms, default=0.0))
        return self.known["mark_need"]

    def job(self, record: CycleRecord):
        """The cycle's job, checked against its recorded hash (:func:`load_cycle_job`) once per run, not once per
        state handler."""
        key = ("job", record.job_path, record.job_sha256)
        if key not in self.known:
            self.known[key] = load_cycle_job(record)
        return self.known[key]

    def plausible(self, scan_path) -> bool:
        """Whether a scan could be of this plate at all (readable, of its size, margin included)."""
        job = load_job(self.history.cycles(self.plate.plate_id)[-1].job_path)
        return plausible_scan(scan_path, self.design.points, 0.0 if job.layout is None else job.layout.margin_mm)

    @property
    def scan_folder(self) -> Path:
        """Where the scans arrive: the scanner's folder, else the plate's work folder (the simulated scanner)."""
        return Path(self.scanner.folder or self.plate.settings["work_dir"])


def run_loop(
    history: History,
    plate_id: str,
    link: PressLink,
    scanner: Scanner,
    *,
    reporter: Reporter = NULL_REPORTER,
    on_cycle: CycleCallback | None = None,
    place: PlaceCallback | None = None,
) -> LoopResult:
    """Drive the plate's cycles from where the history stands until the loop ends.

    Parameters
    ----------
    history : History
    plate_id : str
        A plate recorded by :func:`mppf.loop.plate.start_plate`.
    link : PressLink
        The connected press.
    scanner : Scanner
    reporter : Reporter
    on_cycle : callable, optional
        ``on_cycle(record, comparison)`` after each compare and at the end of each cycle.
    place : callable, optional
        A plate pressed in sections: ``place(section, previous)`` before each section's steps
        (:data:`mppf.loop.sectional.PlaceCallback`: tell the operator, and on a real press wait for the
        confirmation); default: the placement line is reported and the loop goes on (a simulated press).

    Returns
    -------
    LoopResult

    Raises
    ------
    InputError
        The plate's job lacks the design heights at the punches the correction aims at (an older
        job: :func:`mppf.loop.correcting.check_correctable`, before anything is pressed), the
        design file changed since the plate was planned, or the history refuses a
        state change; or a scan is unreadable (FileFormatError) or does not match the
        design (GeometryError): that scan is recorded as rejected, the cycle waits in
        "pressed" for another one.
    MarkMissing
        A scan of a nearly symmetric plate came without its reference mark and none came
        within ``LoopSettings.mark_timeout_s`` (:mod:`mppf.loop.marks`, exit 4): the cycle
        stays "pressed", the scan is not rejected (resume takes it again, with its mark).
    PressRefused, LimitError
        The press refused the step before any motion; the step is recorded as not
        started and is pressed when the loop is resumed.
    LinkError, PlcError, PressFault, Cancelled
        From the press during a step; the cycle stays "pressing" and is measured, not
        pressed again, on resume.
    """
    run = _start_run(history, plate_id, link, scanner, reporter, on_cycle, place or report_placement(reporter))
    resumed, number = _resume_point(history, plate_id)
    while True:
        record = history.cycle(plate_id, number)
        if record.state == CycleState.DONE:
            return _result(run, record, resumed)
        number = _HANDLERS[record.state](run, record)


def _resume_point(history: History, plate_id: str) -> tuple:
    """Where the loop starts: the state it resumes from (None on a first run) and the cycle number.

    Returns
    -------
    resumed : CycleState or None
        The last cycle's state when any cycle got past "planned" before, else None.
    number : int
        The last cycle recorded.
    """
    last = history.cycles(plate_id)[-1]
    ran_before = any(e.state != CycleState.PLANNED for e in history.events(plate_id) if e.cycle is not None)
    return (last.state if ran_before else None), last.cycle


def _result(run: _Run, record: CycleRecord, resumed) -> LoopResult:
    """The loop's result once its last cycle is done: the decision, every cycle, how it ended and why."""
    plate_id = record.plate_id
    detail = run.verdicts[-1] if run.verdicts else None
    cycles = run.history.cycles(plate_id)
    end = ending(record.decision, cycles, run.settings, detail, reach=run.plate.settings.get("reach"))
    return LoopResult(plate_id, record.decision, cycles, resumed, end.text, end)


def _start_run(history, plate_id, link, scanner, reporter, on_cycle, place) -> _Run:
    """The plate's settings, press and design (checked against its recorded hash)."""
    plate = history.plate(plate_id)
    settings = LoopSettings.from_dict(plate.settings["loop"])
    press = press_from_dict(plate.press, source=f"history of plate {plate_id}")
    design = read_checked(plate.design_path, plate.design_sha256, "design", plate.settings.get("units", "mm"))
    last = history.cycles(plate_id)[-1]
    if last.state != CycleState.DONE:  # a job the correction cannot take is refused before anything is pressed
        check_correctable(load_cycle_job(last), plate)
    return _Run(history, plate, press, settings, design, link, scanner, reporter, on_cycle, [], {}, place)


# -- one handler per state: each does what the state asks and returns the cycle to look at next --


def _on_planned(run: _Run, record: CycleRecord) -> int:
    # press every step of the cycle (each step committed before and after); a plate in sections section by section
    job = run.job(record)
    if is_sectional(job):
        press_sections(run.history, record, run.press, run.link, run.reporter, job, run.place)
    else:
        press_cycle(run.history, record, run.press, run.link, run.reporter)
    return record.cycle


def _on_pressing(run: _Run, record: CycleRecord) -> int:
    # stopped while pressing: never press again, measure the plate as it is; "interrupted" only when a
    # step was really cut short (a crash after the last step was recorded done is not an interruption)
    cut = record.step_started > record.steps_done or record.steps_done < len(record.steps)
    job = run.job(record)
    if is_sectional(job) and record.steps_done < len(record.steps):
        # a plate in sections is measured whole: the steps not started are pressed, the one cut short never again
        run.reporter.info(f"cycle {record.cycle} stopped at step {record.step_started} of {len(record.steps)}: the "
                          "steps recorded as started are not pressed again; pressing the steps not started")
        press_sections(run.history, record, run.press, run.link, run.reporter, job, run.place)
        return record.cycle
    if cut:
        run.reporter.info(f"cycle {record.cycle} was interrupted at step {record.step_started} of "
                          f"{len(record.steps)}: it is not pressed again; measuring the plate as it is")
    else:
        run.reporter.info(f"cycle {record.cycle}: every step was recorded done; measuring the plate")
    run.history.mark_pressed(record.plate_id, record.cycle, interrupted=cut,
                             detail="resumed after an interruption" if cut else "resumed after the last step")
    return record.cycle


def _on_pressed(run: _Run, record: CycleRecord) -> int:
    # tell the scanner station what to scan: the request file in the scan folder, the --on-pressed command
    request = _request(run, record)
    try:
        # measure: the scanner delivers a file of the formed plate (an unreadable one is rejected), complete
        # only with its reference mark, or once the plate is known not to need one (mppf.loop.marks)
        scanner = MarkedScanner(run.scanner, run.mark_need, run.plausible, settle_s=run.settings.mark_settle_s,
                                timeout_s=run.settings.mark_timeout_s)
        acquire_scan(run.history, run.plate, record, run.press, scanner, run.reporter)
    finally:
        # the scan is taken, or the wait ended: the request is withdrawn
        request.withdraw()
    return record.cycle


def _request(run: _Run, record: CycleRecord) -> PostedRequest:
    """The pressed cycle's scan request; whether the mark is required is worked out for a scanner station only."""
    required = run.mark_need().required if run.scanner.folder is not None else None
    return post_request(run.plate, record, run.job(record), run.settings, run.scan_folder, run.reporter,
                        mark_required=required)


def _on_scanned(run: _Run, record: CycleRecord) -> int:
    # compare the scan with the design (a scan of another plate is rejected)
    comparison = compare_cycle(run.history, run.plate, record, run.design, run.settings)
    # areas not measured, and nothing else in the way of the verdict: rescan them, compare the union (mppf.loop.rescanning)
    measured = rescan_uncovered(run, record, comparison)
    comparison = measured.comparison
    if measured.stopped:
        run.verdicts.append(measured.stopped)
    # decide on the plate's form deviation (scanner point noise averaged out, see mppf.measure.compare)
    # and on the RMS of every cycle so far; the raw point extremes stay in the stored comparison
    rms = [c.rms_mm for c in run.history.cycles(record.plate_id)[: record.cycle - 1]] + [comparison.rms_mm]
    beyond = 0 if comparison.set_aside is None else comparison.set_aside.beyond_tolerance
    decision = decide(rms, comparison.form_max_abs_mm, record.cycle, run.settings, set_aside_beyond=beyond,
                      verdict=comparison.verdict)
    # record deviations and decision (a plate in sections: the deviations at every section's punches), tell the caller
    summary = comparison_summary(comparison, measured.scans, measured.stopped)
    job = run.job(record)
    if is_sectional(job):
        summary["sections"] = section_deviations(comparison, run.design.points, job)
    run.history.mark_compared(
        record.plate_id, record.cycle, rms_mm=comparison.rms_mm, max_abs_mm=comparison.form_max_abs_mm,
        within_pct=comparison.within_tolerance_pct, punch_deviation_mm=comparison.punch_deviation_mm,
        comparison=summary, decision=decision,
    )
    run.notify(run.history.cycle(record.plate_id, record.cycle), comparison)
    return record.cycle


def _on_compared(run: _Run, record: CycleRecord) -> int:
    if record.decision != Decision.CONTINUE:
        # the loop ends here: the plate gets the decision as its status
        run.history.mark_done(record.plate_id, record.cycle, record.decision)
    else:
        # correct the strokes and record the next cycle, or stop with the correction's verdict
        if is_sectional(run.job(record)):
            verdict = plan_next_sections(run.history, run.plate, record, run.press, run.settings)
        else:
            verdict = plan_next(run.history, run.plate, record, run.press, run.settings)
        if verdict is not None:
            run.reporter.info(f"plate {record.plate_id}, cycle {record.cycle}: {verdict.text}")
            run.verdicts.append(verdict)
            run.history.mark_done(record.plate_id, record.cycle, Decision.CANNOT_CONVERGE)
    run.notify(run.history.cycle(record.plate_id, record.cycle), None)
    return record.cycle


def _on_corrected(run: _Run, record: CycleRecord) -> int:
    # on to the next cycle
    return record.cycle + 1


_HANDLERS = {
    CycleState.PLANNED: _on_planned,
    CycleState.PRESSING: _on_pressing,
    CycleState.PRESSED: _on_pressed,
    CycleState.SCANNED: _on_scanned,
    CycleState.COMPARED: _on_compared,
    CycleState.CORRECTED: _on_corrected,
}
