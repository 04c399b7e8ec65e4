"""The plate history: every bend - measure - compare cycle of every plate, in SQLite.

One row per plate (input files and their SHA-256, press, thickness, loop settings,
status) and one row per press cycle. A cycle moves through the states

    planned -> pressing -> pressed -> scanned -> compared -> corrected | done

(:mod:`mppf.loop.states`; a rejected scan takes "scanned" back to "pressed"), and each
move is committed at once (WAL journal, ``synchronous=FULL``), so a crash or a power cut
loses at most the step that was running. Moves are conditional
(``UPDATE ... WHERE state = <expected>``): a cycle can enter "pressing" only once, which
is what keeps ``mppf loop --resume`` from ever pressing a cycle twice, even when two
processes race for the same plate. Every move is also appended to the ``events`` table.

The strokes sent, the press read-back, the scan file and its hash, the deviation
statistics and the per-punch deviation grid are stored in the database itself, so the
history is complete without the job and scan files (which it also names).

Default location: ``$MPPF_HOME/history.sqlite`` when ``MPPF_HOME`` is set, else
``~/.local/share/mppf/history.sqlite``.
"""

from __future__ import annotations

import os
import sqlite3
import time
from datetime import datetime, timezone
from pathlib import Path

from mppf.core.db import Transaction, open_sqlite
from mppf.core.errors import InputError
from mppf.core.paths import data_dir
from mppf.core.validate import check_name
from mppf.loop import lease as leases
from mppf.loop.options import PlateFiles
from mppf.loop.records import (CYCLE_COLUMNS, SCHEMA, SCHEMA_VERSION, CycleRecord, Event, PlateRecord,
                               cycle_from_row, dumps, plate_from_row, steps_to_json)
from mppf.loop.states import CycleState, Decision, PlateStatus
from mppf.model.job_parts import StepStrokes, grid_to_json

_WRITE_HINT = ("free disk space or make the history writable, then continue with 'mppf loop --resume'; "
               "the plate stays as it was before this step")


def check_plate_id(plate_id) -> str:
    """``plate_id`` if safe as the name of the plate's folder (:func:`mppf.core.validate.check_name`)."""
    return check_name("plate id", plate_id, hint="e.g. B12-P3")


def default_history_path() -> Path:
    """``$MPPF_HOME/history.sqlite``, else ``~/.local/share/mppf/history.sqlite``."""
    return data_dir() / "history.sqlite"


def _now_utc() -> str:
    return datetime.fromtimestamp(time.time(), tz=timezone.utc).isoformat(timespec="milliseconds")


class History:
    """The SQLite plate history.

    Parameters
    ----------
    path : path-like, optional
        Database file (created with its folder). Default :func:`default_history_path`.

    Raises
    ------
    InputError
        The file cannot be created or is not an mppf history database.
    """

    def __init__(self, path=None):
        self.path = Path(path) if path is not None else default_history_path()
        self._db = open_sqlite(self.path, "the plate history", SCHEMA + leases.LEASE_SCHEMA, SCHEMA_VERSION,
                               hint="give a writable SQLite file with --history or set MPPF_HOME")

    # -- plates -------------------------------------------------------------------------

    def create_plate(self, plate_id: str, files: PlateFiles, *, thickness_mm: float, press: dict, settings: dict,
                     note: str = "") -> PlateRecord:
        """Add a new plate (status "active") made from ``files``, ``thickness_mm`` thick, for ``press``
        (:meth:`PressConfig.to_dict`), with the loop ``settings`` (JSON-ready).

        Raises
        ------
        InputError
            A plate with this id is already in the history.
        """
        now = _now_utc()
        try:
            with self._transaction():
                self.check_new_plate(plate_id)
                self._db.execute("DELETE FROM plates WHERE plate_id = ?", (plate_id,))  # one without cycles
                self._db.execute(
                    "INSERT INTO plates VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                    (plate_id, now, now, PlateStatus.ACTIVE, str(files.design_path), files.design_sha256,
                     str(files.flat_path), files.flat_sha256, float(thickness_mm), dumps(press), dumps(settings),
                     note),
                )
                self._event(plate_id, None, "created", f"design {files.design_path}")
        except sqlite3.IntegrityError:  # created by another process meanwhile
            self.check_new_plate(plate_id)
            raise
        return self.plate(plate_id)

    def check_new_plate(self, plate_id: str) -> None:
        """Raise InputError when ``plate_id`` is not a safe id or already in the history.

        A plate recorded without any cycle (by an mppf older than the one-transaction
        recording, killed in between) does not count: it is replaced.
        """
        check_plate_id(plate_id)
        row = self._db.execute("SELECT status, (SELECT COUNT(*) FROM cycles WHERE plate_id = ?) FROM plates "
                               "WHERE plate_id = ?", (plate_id, plate_id)).fetchone()
        if row is not None and row[1] > 0:
            raise InputError(
                f"plate {plate_id!r} is already in the history {self.path} (status {row[0]})",
                hint="choose another --plate-id, or continue it with 'mppf loop --resume --plate-id "
                f"{plate_id}'",
            )

    def plate(self, plate_id: str) -> PlateRecord:
        """The plate ``plate_id``.

        Raises
        ------
        InputError
            No such plate.
        """
        row = self._db.execute("SELECT * FROM plates WHERE plate_id = ?", (plate_id,)).fetchone()
        if row is None:
            known = [p.plate_id for p in self.plates()][-5:]
            raise InputError(
                f"plate {plate_id!r} is not in the history {self.path}",
                hint=f"known plates: {', '.join(known) or 'none'} (see 'mppf history')",
            )
        return plate_from_row(row)

    def plates(self) -> list[PlateRecord]:
        """All plates, oldest first."""
        rows = self._db.execute("SELECT * FROM plates ORDER BY created_utc, plate_id").fetchall()
        return [plate_from_row(r) for r in rows]

    def active_plates(self) -> list[PlateRecord]:
        """Plates whose loop has not finished, oldest first."""
        return [p for p in self.plates() if p.status == PlateStatus.ACTIVE]

    def set_plate_status(self, plate_id: str, status: PlateStatus) -> None:
        """Set why the plate's loop stopped (or "active")."""
        status = PlateStatus(status)  # ValueError for an unknown status
        with self._transaction():
            self._db.execute(
                "UPDATE plates SET status = ?, updated_utc = ? WHERE plate_id = ?", (status, _now_utc(), plate_id)
            )
            self._event(plate_id, None, status, "plate status")

    # -- cycles -------------------------------------------------------------------------

    def add_cycle(self, plate_id: str, cycle: int, *, job_path, job_sha256: str, steps: list[StepStrokes],
                  gain: float | None = None, correction: dict | None = None,
                  previous_decision: str | None = None) -> CycleRecord:
        """Record a new cycle in state "planned".

        When ``previous_decision`` is given, the previous cycle (``cycle - 1``, which
        must be "compared") is moved to "corrected" in the same transaction, so a crash
        never leaves a corrected cycle without its successor or the other way round.
        """
        now = _now_utc()
        with self._transaction():
            if previous_decision is not None:
                self._move(plate_id, cycle - 1, (CycleState.COMPARED,), CycleState.CORRECTED,
                           decision=Decision(previous_decision))
            self._db.execute(
                "INSERT INTO cycles (plate_id, cycle, state, created_utc, updated_utc, job_path, job_sha256, "
                "steps_json, gain, correction_json) VALUES (?, ?, 'planned', ?, ?, ?, ?, ?, ?, ?)",
                (plate_id, int(cycle), now, now, str(job_path), job_sha256, dumps(steps_to_json(steps)),
                 None if gain is None else float(gain), None if correction is None else dumps(correction)),
            )
            self._event(plate_id, cycle, CycleState.PLANNED, f"job {job_path} sha256 {job_sha256[:12]}")
        return self.cycle(plate_id, cycle)

    def mark_step_started(self, plate_id: str, cycle: int, step: int) -> None:
        """Record that step ``step`` (1-based) is about to be uploaded and started.

        The first step moves the cycle from "planned" to "pressing"; later steps need
        the previous step done. Committed before anything is sent to the press.

        Raises
        ------
        InputError
            The cycle is not in a state where this step may start (it was already
            started, possibly by another process): nothing may be sent.
        """
        with self._transaction():
            if step == 1:
                self._move(plate_id, cycle, (CycleState.PLANNED,), CycleState.PRESSING, step_started=1,
                           detail="step 1 started")
                return
            else:
                cur = self._db.execute(
                    "UPDATE cycles SET step_started = ?, updated_utc = ? WHERE plate_id = ? AND cycle = ? "
                    "AND state = 'pressing' AND step_started = ? AND steps_done = ?",
                    (step, _now_utc(), plate_id, cycle, step - 1, step - 1),
                )
                if cur.rowcount != 1:
                    self._refuse(plate_id, cycle, f"start step {step}")
            self._event(plate_id, cycle, CycleState.PRESSING, f"step {step} started")

    def mark_step_not_started(self, plate_id: str, cycle: int, step: int, reason: str) -> None:
        """Undo :meth:`mark_step_started` for a step the press provably never started.

        Only for refusals that guarantee nothing moved (the PLC or the driver refused the
        upload or GO): the step may then be pressed later. The first step takes the cycle
        back to "planned".
        """
        with self._transaction():
            if step == 1:
                self._move(plate_id, cycle, (CycleState.PRESSING,), CycleState.PLANNED, step_started=0,
                           detail=f"step 1 not started: {reason}")
                return
            cur = self._db.execute(
                "UPDATE cycles SET step_started = ?, updated_utc = ? WHERE plate_id = ? AND cycle = ? "
                "AND state = 'pressing' AND step_started = ? AND steps_done = ?",
                (step - 1, _now_utc(), plate_id, cycle, step, step - 1),
            )
            if cur.rowcount != 1:
                self._refuse(plate_id, cycle, f"undo the start of step {step}")
            self._event(plate_id, cycle, CycleState.PRESSING, f"step {step} not started: {reason}")

    def mark_step_done(self, plate_id: str, cycle: int, step: int, result: dict) -> None:
        """Record the read-back of a finished step (``result`` is JSON-ready)."""
        with self._transaction():
            record = self.cycle(plate_id, cycle)
            results = list(record.results) + [result]
            cur = self._db.execute(
                "UPDATE cycles SET steps_done = ?, results_json = ?, updated_utc = ? WHERE plate_id = ? AND "
                "cycle = ? AND state = 'pressing' AND step_started = ? AND steps_done = ?",
                (step, dumps(results), _now_utc(), plate_id, cycle, step, step - 1),
            )
            if cur.rowcount != 1:
                self._refuse(plate_id, cycle, f"finish step {step}")
            self._event(plate_id, cycle, CycleState.PRESSING,
                        f"step {step} done, max error {result.get('max_error_mm')}")

    def mark_pressed(self, plate_id: str, cycle: int, *, interrupted: bool = False, detail: str = "") -> None:
        """Move the cycle from "pressing" to "pressed".

        ``interrupted`` marks a cycle found in "pressing" after a crash: it is not pressed
        again but measured as it is. It is recorded only when a step was really cut short
        (a step started and not recorded done, or steps left): a crash after the last step
        was recorded done leaves a cycle that is simply pressed. A plate pressed in sections goes on
        with the later steps after a cut step (recorded done, ``complete: false``): still interrupted.
        """
        with self._transaction():
            record = self.cycle(plate_id, cycle)
            interrupted = interrupted and (record.step_started > record.steps_done
                                           or record.steps_done < len(record.steps)
                                           or any(r.get("complete") is False for r in record.results))
            self._move(plate_id, cycle, (CycleState.PRESSING,), CycleState.PRESSED, interrupted=int(interrupted),
                       detail=detail)

    def mark_scanned(self, plate_id: str, cycle: int, scan_path, scan_sha256: str) -> None:
        """Move the cycle from "pressed" to "scanned" with its scan file."""
        with self._transaction():
            self._move(plate_id, cycle, (CycleState.PRESSED,), CycleState.SCANNED, scan_path=str(scan_path),
                       scan_sha256=scan_sha256, detail=f"scan {scan_path} sha256 {scan_sha256[:12]}")

    def reject_scan(self, plate_id: str, cycle: int, scan_path, scan_sha256: str, reason: str) -> None:
        """Refuse a scan of the cycle (unreadable, or not matching the design).

        The scan is added to the cycle's rejected scans (never taken again) and a cycle in
        "scanned" goes back to "pressed", so the next run waits for a new scan.
        """
        with self._transaction():
            record = self.cycle(plate_id, cycle)
            rejected = list(record.rejected_scans) + [
                {"path": str(scan_path), "sha256": scan_sha256, "reason": reason}]
            self._move(plate_id, cycle, (CycleState.PRESSED, CycleState.SCANNED), CycleState.PRESSED,
                       scan_path=None, scan_sha256=None,
                       rejected_json=dumps(rejected), detail=f"scan {scan_path} rejected: {reason}")

    def mark_compared(self, plate_id: str, cycle: int, *, rms_mm: float, max_abs_mm: float, within_pct: float,
                      punch_deviation_mm, comparison: dict, decision: Decision) -> None:
        """Move the cycle from "scanned" to "compared" with its deviations and decision."""
        decision = Decision(decision)
        with self._transaction():
            self._move(
                plate_id, cycle, (CycleState.SCANNED,), CycleState.COMPARED,
                rms_mm=float(rms_mm), max_abs_mm=float(max_abs_mm), within_pct=float(within_pct),
                deviation_json=dumps(grid_to_json(punch_deviation_mm)), compare_json=dumps(comparison),
                decision=decision, detail=f"form max {max_abs_mm:.2f} mm, RMS {rms_mm:.2f} mm -> {decision}",
            )

    def mark_done(self, plate_id: str, cycle: int, decision: Decision) -> None:
        """End the loop at this cycle: the cycle becomes "done", the plate gets ``decision`` as its status."""
        status = PlateStatus(decision)  # a decision that ends the loop
        with self._transaction():
            self._move(plate_id, cycle, (CycleState.COMPARED,), CycleState.DONE, decision=Decision(decision))
            self._db.execute(
                "UPDATE plates SET status = ?, updated_utc = ? WHERE plate_id = ?", (status, _now_utc(), plate_id)
            )
            self._event(plate_id, None, status, f"loop ended after cycle {cycle}")

    def cycle(self, plate_id: str, cycle: int) -> CycleRecord:
        """One cycle (InputError when missing)."""
        row = self._db.execute(
            f"SELECT {CYCLE_COLUMNS} FROM cycles WHERE plate_id = ? AND cycle = ?", (plate_id, int(cycle))
        ).fetchone()
        if row is None:
            raise InputError(f"plate {plate_id!r} has no cycle {cycle} in the history {self.path}")
        return cycle_from_row(row)

    def cycles(self, plate_id: str) -> list[CycleRecord]:
        """The cycles of a plate in order."""
        rows = self._db.execute(
            f"SELECT {CYCLE_COLUMNS} FROM cycles WHERE plate_id = ? ORDER BY cycle", (plate_id,)
        ).fetchall()
        return [cycle_from_row(r) for r in rows]

    def events(self, plate_id: str | None = None) -> list[Event]:
        """State changes in order (of one plate or all)."""
        if plate_id is None:
            rows = self._db.execute("SELECT * FROM events ORDER BY id").fetchall()
        else:
            rows = self._db.execute("SELECT * FROM events WHERE plate_id = ? ORDER BY id", (plate_id,)).fetchall()
        return [Event(*r) for r in rows]

    # -- one loop per plate -------------------------------------------------------------

    def lease(self, plate_id: str):
        """Hold the plate's lease during a ``with`` block (:func:`mppf.loop.lease.hold`).

        Yields why a stale lease was taken over (None: it was free); InputError naming the
        owner when another live process holds it.
        """
        return leases.hold(self._db, self._transaction, self._connect, plate_id)

    def current_lease(self, plate_id: str):
        """Who holds the plate now (:class:`mppf.loop.lease.Lease`), or None."""
        return leases.current_lease(self._db, plate_id)

    def transaction(self):
        """One transaction around several changes (e.g. a plate and its first cycle); nests."""
        return self._transaction()

    def _connect(self) -> sqlite3.Connection:
        return open_sqlite(self.path, "the plate history", SCHEMA + leases.LEASE_SCHEMA, SCHEMA_VERSION, hint="")

    def close(self) -> None:
        """Close the database."""
        self._db.close()

    def __enter__(self) -> History:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- internals ----------------------------------------------------------------------

    def _transaction(self):
        return Transaction(self._db, f"the plate history {self.path}", hint=_WRITE_HINT)

    def _event(self, plate_id, cycle, state, detail=""):
        self._db.execute(
            "INSERT INTO events (time_utc, plate_id, cycle, state, pid, detail) VALUES (?, ?, ?, ?, ?, ?)",
            (_now_utc(), plate_id, cycle, state, os.getpid(), detail),
        )

    def _move(self, plate_id, cycle, from_states, to_state, *, detail="", **columns):
        sets = ", ".join([f"{k} = ?" for k in columns] + ["state = ?", "updated_utc = ?"])
        marks = ", ".join("?" for _ in from_states)
        cur = self._db.execute(
            f"UPDATE cycles SET {sets} WHERE plate_id = ? AND cycle = ? AND state IN ({marks})",
            (*columns.values(), to_state, _now_utc(), plate_id, int(cycle), *from_states),
        )
        if cur.rowcount != 1:
            self._refuse(plate_id, cycle, f"move to '{to_state}'")
        self._event(plate_id, cycle, to_state, detail)

    def _refuse(self, plate_id, cycle, what):
        row = self._db.execute(
            "SELECT state, step_started, steps_done FROM cycles WHERE plate_id = ? AND cycle = ?", (plate_id, cycle)
        ).fetchone()
        seen = "missing" if row is None else f"state '{row[0]}', step {row[1]} started, {row[2]} done"
        raise InputError(
            f"cannot {what} for cycle {cycle} of plate {plate_id!r}: the history shows {seen}",
            hint="another 'mppf loop' may be running this plate; check 'mppf history --plate-id "
            f"{plate_id}'",
        )
