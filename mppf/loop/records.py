"""What the plate history holds: its tables, and one record type per row.

:data:`SCHEMA` is the SQLite layout of :class:`mppf.loop.history.History`;
:class:`PlateRecord`, :class:`CycleRecord` and :class:`Event` are its rows as frozen
dataclasses (states and statuses as :mod:`mppf.loop.states` enums, stored as their text),
with the conversions from rows and of the strokes to and from JSON.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from mppf.core.errors import ConfigError
from mppf.geometry.files import sha256_of
from mppf.loop.states import CycleState, Decision, PlateStatus
from mppf.model.job import Job
from mppf.model.job_parts import StepStrokes, grid_from_json, grid_to_json
from mppf.planning.job import load_job

SCHEMA_VERSION = 1

SCHEMA = """
CREATE TABLE IF NOT EXISTS plates (
    plate_id       TEXT PRIMARY KEY,
    created_utc    TEXT NOT NULL,
    updated_utc    TEXT NOT NULL,
    status         TEXT NOT NULL,      -- active, in_tolerance, max_cycles, diverged
    design_path    TEXT NOT NULL,
    design_sha256  TEXT NOT NULL,
    flat_path      TEXT NOT NULL,
    flat_sha256    TEXT NOT NULL,
    thickness_mm   REAL NOT NULL,
    press_json     TEXT NOT NULL,      -- the press description (TOML layout)
    settings_json  TEXT NOT NULL,      -- loop settings, scanner, PLC URL, seed, work folder
    note           TEXT NOT NULL DEFAULT ''
);
CREATE TABLE IF NOT EXISTS cycles (
    plate_id       TEXT NOT NULL REFERENCES plates (plate_id),
    cycle          INTEGER NOT NULL,   -- 1, 2, ...
    state          TEXT NOT NULL,      -- planned, pressing, pressed, scanned, compared, corrected, done
    created_utc    TEXT NOT NULL,
    updated_utc    TEXT NOT NULL,
    job_path       TEXT NOT NULL,      -- job file of the strokes of this cycle
    job_sha256     TEXT NOT NULL,
    steps_json     TEXT NOT NULL,      -- the strokes: [{upper_mm, lower_mm, active}] (null = inactive)
    step_started   INTEGER NOT NULL DEFAULT 0,  -- last step whose upload/GO began (1-based)
    steps_done     INTEGER NOT NULL DEFAULT 0,  -- steps finished in position
    results_json   TEXT NOT NULL DEFAULT '[]', -- per step: sequence, read-back, max error, duration
    interrupted    INTEGER NOT NULL DEFAULT 0,  -- 1 when resumed from "pressing" (not pressed again)
    scan_path      TEXT,
    scan_sha256    TEXT,
    rms_mm         REAL,
    max_abs_mm     REAL,
    within_pct     REAL,
    deviation_json TEXT,               -- per-punch deviation grid (rows, cols), null = no data
    compare_json   TEXT,               -- the full comparison summary
    gain           REAL,               -- gain of the correction that made these strokes
    correction_json TEXT,              -- that correction (applied mm, clipped, notes)
    decision       TEXT,               -- continue, in_tolerance, max_cycles, diverged
    rejected_json  TEXT NOT NULL DEFAULT '[]',  -- scans refused for this cycle: [{path, sha256, reason}]
    PRIMARY KEY (plate_id, cycle)
);
CREATE TABLE IF NOT EXISTS events (
    id        INTEGER PRIMARY KEY AUTOINCREMENT,
    time_utc  TEXT NOT NULL,
    plate_id  TEXT NOT NULL,
    cycle     INTEGER,
    state     TEXT NOT NULL,
    pid       INTEGER NOT NULL,
    detail    TEXT NOT NULL DEFAULT ''
);
"""



def steps_to_json(steps: list[StepStrokes]) -> list[dict]:
    """Strokes of a cycle as JSON-ready dicts."""
    return [
        {
            "upper_mm": grid_to_json(np.where(s.active, s.upper_mm, np.nan)),
            "lower_mm": grid_to_json(np.where(s.active, s.lower_mm, np.nan)),
            "active": np.asarray(s.active, dtype=bool).tolist(),
        }
        for s in steps
    ]


def steps_from_json(doc: list[dict]) -> list[StepStrokes]:
    """Inverse of :func:`steps_to_json`."""
    return [
        StepStrokes(
            upper_mm=grid_from_json(s["upper_mm"]),
            lower_mm=grid_from_json(s["lower_mm"]),
            active=np.asarray(s["active"], dtype=bool),
        )
        for s in doc
    ]


@dataclass(frozen=True)
class PlateRecord:
    """One plate of the history (see the ``plates`` table)."""

    plate_id: str
    created_utc: str
    updated_utc: str
    status: PlateStatus
    design_path: str
    design_sha256: str
    flat_path: str
    flat_sha256: str
    thickness_mm: float
    press: dict
    settings: dict
    note: str = ""

    def to_dict(self) -> dict:
        """JSON-ready dict."""
        return dict(self.__dict__)


@dataclass(frozen=True)
class CycleRecord:
    """One press cycle of a plate (see the ``cycles`` table).

    Attributes
    ----------
    steps : list of StepStrokes
        The strokes of this cycle (NaN where inactive).
    punch_deviation_mm : (rows, cols) float or None
        Deviation at each punch after this cycle (NaN where not measured).
    """

    plate_id: str
    cycle: int
    state: CycleState
    created_utc: str
    updated_utc: str
    job_path: str
    job_sha256: str
    steps: list
    step_started: int
    steps_done: int
    results: list
    interrupted: bool
    scan_path: str | None
    scan_sha256: str | None
    rms_mm: float | None
    max_abs_mm: float | None
    within_pct: float | None
    punch_deviation_mm: np.ndarray | None
    comparison: dict | None
    gain: float | None
    correction: dict | None
    decision: Decision | None
    rejected_scans: list = field(default_factory=list)

    def to_dict(self, *, grids: bool = True) -> dict:
        """JSON-ready dict (strokes and deviation grid included when ``grids``)."""
        out = {k: v for k, v in self.__dict__.items() if k not in ("steps", "punch_deviation_mm")}
        if grids:
            out["steps"] = steps_to_json(self.steps)
            out["punch_deviation_mm"] = grid_to_json(self.punch_deviation_mm)
        return out


def load_cycle_job(record: CycleRecord) -> Job:
    """The job file of a cycle; ConfigError when it changed since it was recorded.

    The recorded SHA-256 is that of the file's bytes, which is ``job.sha256()`` of a job this mppf wrote; a job
    of an older format version (recorded by an older mppf) reads back in this version's layout, so its own file's
    bytes are compared.
    """
    job = load_job(record.job_path)
    if job.sha256() != record.job_sha256 and sha256_of(record.job_path) != record.job_sha256:
        raise ConfigError(
            f"job file {record.job_path} of cycle {record.cycle} changed since it was recorded",
            hint="restore it; the strokes are also in the history ('mppf history --json')",
        )
    return job


@dataclass(frozen=True)
class Event:
    """One state change (``state``: a cycle state, a plate status, or "created")."""

    id: int
    time_utc: str
    plate_id: str
    cycle: int | None
    state: str
    pid: int
    detail: str = field(default="")


def loads(text):
    """JSON text (or NULL) to a value."""
    return None if text is None else json.loads(text)


def dumps(value) -> str:
    """A value as JSON text (NaN refused)."""
    return json.dumps(value, allow_nan=False)


CYCLE_COLUMNS = (
    "plate_id, cycle, state, created_utc, updated_utc, job_path, job_sha256, steps_json, step_started, "
    "steps_done, results_json, interrupted, scan_path, scan_sha256, rms_mm, max_abs_mm, within_pct, "
    "deviation_json, compare_json, gain, correction_json, decision, rejected_json"
)


def plate_from_row(row) -> PlateRecord:
    """A ``plates`` row (``SELECT *``) as a record."""
    (plate_id, created, updated, status, design_path, design_sha, flat_path, flat_sha, thickness,
     press_json, settings_json, note) = row
    return PlateRecord(plate_id, created, updated, PlateStatus(status), design_path, design_sha, flat_path,
                       flat_sha, float(thickness), json.loads(press_json), json.loads(settings_json), note)


def cycle_from_row(row) -> CycleRecord:
    """A ``cycles`` row (``SELECT`` :data:`CYCLE_COLUMNS`) as a record."""
    (plate_id, cycle, state, created, updated, job_path, job_sha, steps_json, step_started, steps_done,
     results_json, interrupted, scan_path, scan_sha, rms, max_abs, within, deviation_json, compare_json,
     gain, correction_json, decision, rejected_json) = row
    return CycleRecord(
        plate_id=plate_id, cycle=int(cycle), state=CycleState(state), created_utc=created, updated_utc=updated,
        job_path=job_path, job_sha256=job_sha, steps=steps_from_json(json.loads(steps_json)),
        step_started=int(step_started), steps_done=int(steps_done), results=json.loads(results_json),
        interrupted=bool(interrupted), scan_path=scan_path, scan_sha256=scan_sha, rms_mm=rms,
        max_abs_mm=max_abs, within_pct=within, punch_deviation_mm=grid_from_json(loads(deviation_json)),
        comparison=loads(compare_json), gain=gain, correction=loads(correction_json),
        decision=None if decision is None else Decision(decision),
        rejected_scans=json.loads(rejected_json),
    )
