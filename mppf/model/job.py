"""The job file as data: the planned strokes of a plate, the contract between planner and press.

A job is JSON, versioned (``"format": "mppf-job"``, ``"version": 5``: sealed, its reports typed; a
plate formed section by section has its ``"sections"``, :mod:`mppf.model.job_sections`); see
``docs/file-formats.md`` and ``docs/sections.md``. This module holds the job and its
(de)serialisation; sealing, the seal check and the one loader of job files are
:mod:`mppf.planning.job` (:func:`~mppf.planning.job.save_job`, :func:`~mppf.planning.job.load_job`).
In memory, stroke arrays are (rows, cols) float mm with NaN where a punch is inactive; in the
file, inactive entries are ``null``. Inactive punches are driven to their parking heights by
the press driver. The parts (steps, plate layout) are :mod:`mppf.model.job_parts`; the planner's
reports :mod:`mppf.model.job_reports`; the sectional summary, the provenance and the seal
:mod:`mppf.model.job_provenance`.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mppf.core.errors import ConfigError, InputError
from mppf.core.transform import tf_from_list, tf_to_list
from mppf.core.validate import check_number
from mppf.model.job_parts import (
    PlateLayout,
    StepStrokes,
    steps_from_json,
    steps_to_json,
)
from mppf.model.job_provenance import (
    BatchRecord,
    LoopProvenance,
    Seal,
    SectionalSummary,
    SectionPiece,
)
from mppf.model.job_reports import PlanReports
from mppf.model.job_sections import Section, sections_from_json
from mppf.model.press import PressConfig, press_from_dict

JOB_FORMAT = "mppf-job"
JOB_VERSION = 5
"""The version written: a sealed job (single piece or in sections) whose reports are typed blocks
(:mod:`mppf.model.job_reports`, :mod:`mppf.model.job_provenance`); older readers refuse it."""
SEALED_VERSION = 4
"""The first version that must carry a seal (:mod:`mppf.core.seal`)."""
SECTIONS_VERSION = 3
"""The first version that may hold sections (a plate larger than the bed)."""
READ_VERSIONS = (1, 2, 3, 4, 5)
"""Job file versions this mppf reads (version 1: the plate layout in loose top-level keys; 1-3 unsealed,
read only where nothing is pressed; 4: sealed, its reports read into the same typed blocks as 5's)."""


@dataclass
class Job:
    """A planned job: press, plate, transforms, punch positions and steps.

    Attributes
    ----------
    press : PressConfig
    thickness_mm : float
    steps : list of StepStrokes
    tf_press_design, tf_press_flat : (4, 4) float
    punch_x_mm : (cols,) float
    punch_y_mm : (rows,) float
    layout : PlateLayout or None
        The plate on the press (None only for old jobs without an outline).
    reports : PlanReports
        The planner's reports (surface fit, registration, pose, validation, plate corners
        and size, counts, input files, springback); of section 1 for a sectional job.
    sections : list of Section or None
        A plate larger than the bed: its sections in pressing order (then ``steps``,
        the transforms and ``layout`` are those of section 1); None for a single piece.
    sectional : SectionalSummary or None
        The split of a sectional job (None for a single piece).
    batch : BatchRecord or None
        What ``mppf batch`` stored to resume (None outside a batch).
    loop : LoopProvenance or None
        Set in a job the forming loop corrected.
    piece : SectionPiece or None
        Set in a single-section job made from a sectional one (key ``"section"``).
    seal : Seal or None
        The seal of the file it was read from or saved to (None before it is saved).
    """

    press: PressConfig
    thickness_mm: float
    steps: list[StepStrokes]
    tf_press_design: np.ndarray = field(default_factory=lambda: np.eye(4))
    tf_press_flat: np.ndarray = field(default_factory=lambda: np.eye(4))
    punch_x_mm: np.ndarray | None = None
    punch_y_mm: np.ndarray | None = None
    layout: PlateLayout | None = None
    reports: PlanReports = field(default_factory=PlanReports)
    sections: list[Section] | None = None
    sectional: SectionalSummary | None = None
    batch: BatchRecord | None = None
    loop: LoopProvenance | None = None
    piece: SectionPiece | None = None
    seal: Seal | None = None

    def __post_init__(self):
        if self.punch_x_mm is None:
            self.punch_x_mm = self.press.punch_x_mm
        if self.punch_y_mm is None:
            self.punch_y_mm = self.press.punch_y_mm

    def to_dict(self) -> dict:
        """The JSON document of this job."""
        doc = {
            "format": JOB_FORMAT,
            "version": JOB_VERSION,
            "press": self.press.to_dict(),
            "thickness_mm": float(self.thickness_mm),
            "tf_press_design": tf_to_list(self.tf_press_design),
            "tf_press_flat": tf_to_list(self.tf_press_flat),
            "punch_x_mm": [float(x) for x in self.punch_x_mm],
            "punch_y_mm": [float(y) for y in self.punch_y_mm],
            "steps": steps_to_json(self.steps),
        }
        if self.layout is not None:
            doc["plate"] = self.layout.to_dict()
        if self.sections is not None:
            doc["sections"] = [s.to_dict() for s in self.sections]
        doc.update(self.reports.to_doc())
        for key, block in (("sectional", self.sectional), ("batch", self.batch), ("loop", self.loop),
                           ("section", self.piece), ("seal", self.seal)):
            if block is not None:
                doc[key] = block.to_doc()
        return doc

    def to_json(self) -> str:
        """Serialized job (stable key order, so its hash is reproducible; the seal of the file it was read from
        or saved to is ``seal``, last)."""
        return json.dumps(self.to_dict(), indent=1, allow_nan=False)

    def sha256(self) -> str:
        """SHA-256 of the serialized job (used in the audit log and history)."""
        return hashlib.sha256(self.to_json().encode()).hexdigest()


def job_from_dict(doc: dict, source: str = "job") -> Job:
    """Validate and build a :class:`Job` from its JSON document.

    Raises
    ------
    ConfigError
        Wrong format or version, missing keys, or grids that do not match the press.
    """
    check_format(doc, source)
    for key in ("press", "thickness_mm", "steps"):
        if key not in doc:
            raise ConfigError(f"{source}: missing key '{key}'")
    press = press_from_dict(doc["press"], source=f"{source} [press]")
    thickness = check_number(f"{source}: thickness_mm", doc["thickness_mm"], low=0.0, low_open=True, unit="mm",
                             hint="re-plan the plate with 'mppf plan'", error=ConfigError)
    steps = steps_from_json(doc["steps"], press, source)
    layout = _layout_from_doc(doc, source)
    transforms = {}
    for key in ("tf_press_design", "tf_press_flat"):
        try:
            transforms[key] = tf_from_list(doc.get(key, np.eye(4).tolist()), key)
        except InputError as exc:
            raise ConfigError(f"{source}: {exc.message}", hint="re-plan the plate with 'mppf plan'") from None
    return Job(
        press=press,
        thickness_mm=float(thickness),
        steps=steps,
        punch_x_mm=_axis_from_json(doc.get("punch_x_mm", press.punch_x_mm), press.cols, "punch_x_mm", source),
        punch_y_mm=_axis_from_json(doc.get("punch_y_mm", press.punch_y_mm), press.rows, "punch_y_mm", source),
        layout=layout,
        reports=PlanReports.from_doc(doc, f"{source}:"),
        sections=_sections_from_doc(doc, press, source),
        **_blocks_from_doc(doc, source),
        **transforms,
    )


_BLOCKS = {"sectional": SectionalSummary, "batch": BatchRecord, "loop": LoopProvenance, "piece": SectionPiece,
           "seal": Seal}
"""The job's typed blocks besides the planner's reports, by field (the piece's key is ``"section"``)."""


def _blocks_from_doc(doc: dict, source: str) -> dict:
    """The typed blocks present in the document (``sectional``, ``batch``, ``loop``, ``section``, ``seal``)."""
    out = {}
    for name, cls in _BLOCKS.items():
        key = "section" if name == "piece" else name
        if doc.get(key) is not None:
            out[name] = cls.from_doc(doc[key], f"{source}: {key}")
    return out


def _sections_from_doc(doc: dict, press: PressConfig, source: str) -> list[Section] | None:
    """The sections of a version-3 job (None for a single piece; refused in older versions)."""
    if "sections" not in doc:
        return None
    if doc["version"] < SECTIONS_VERSION:
        raise ConfigError(f"{source}: a version-{doc['version']} job cannot hold sections",
                          hint="re-plan the plate with 'mppf plan'")
    return sections_from_json(doc["sections"], press, source)


V1_LAYOUT_KEYS = {"plate_outline_mm": "outline_mm", "net_outline_mm": "net_outline_mm", "margin_mm": "margin_mm",
                  "design_mid_mm": "design_mid_mm", "material": "material"}
"""Version-1 top-level keys and the layout fields they became in version 2."""


def _layout_from_doc(doc: dict, source: str) -> PlateLayout | None:
    """The job's plate layout: the ``"plate"`` block (v2) or the loose v1 keys; None without an outline."""
    if doc["version"] >= 2:
        block = doc.get("plate")
        if block is None:
            return None
        if not isinstance(block, dict):
            raise ConfigError(f"{source}: 'plate' must be an object with the plate layout")
        return PlateLayout.from_dict(block, source)
    if not doc.get("plate_outline_mm"):
        return None
    return PlateLayout.from_dict({new: doc[old] for old, new in V1_LAYOUT_KEYS.items() if doc.get(old) is not None},
                                 source)


def _axis_from_json(values, count: int, name: str, source: str) -> np.ndarray:
    """Punch axis positions (count,) mm from the job document, checked."""
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{source}: {name} must be a list of numbers (mm), got {values!r:.60}") from None
    if arr.shape != (count,):
        raise ConfigError(f"{source}: {name} must hold {count} finite numbers (one per punch), got shape "
                          f"{arr.shape}", hint="re-plan the plate with 'mppf plan'")
    if not np.all(np.isfinite(arr)):
        k = int(np.argmin(np.isfinite(arr)))
        raise ConfigError(f"{source}: {name} must hold {count} finite numbers (one per punch), got {arr[k]} at "
                          f"position {k + 1}", hint="re-plan the plate with 'mppf plan'")
    return arr


def check_format(doc, source: str) -> None:
    """Refuse a document that is not an mppf job of a version this mppf reads.

    Raises
    ------
    ConfigError
        Another format, or a version not in :data:`READ_VERSIONS`; names ``source`` and the value seen.
    """
    if not isinstance(doc, dict) or doc.get("format") != JOB_FORMAT:
        raise ConfigError(
            f"{source}: not an mppf job file (format {doc.get('format') if isinstance(doc, dict) else None!r})",
            hint="make one with 'mppf plan'",
        )
    if isinstance(doc.get("version"), bool) or doc.get("version") not in READ_VERSIONS:
        raise ConfigError(
            f"{source}: job file version {doc.get('version')!r} is not supported (this mppf reads "
            f"{', '.join(str(v) for v in READ_VERSIONS)})",
            hint="re-plan the plate with this version of mppf",
        )


def read_job_document(path) -> dict:
    """The JSON document of a job file, not yet checked.

    Raises
    ------
    InputError
        Missing or unreadable file, invalid JSON.
    """
    import stat

    path = Path(path)
    try:
        info = path.stat()
        if stat.S_ISREG(info.st_mode) and info.st_size > MAX_JOB_BYTES:
            raise InputError(f"job file {path} is {info.st_size / 1e6:.0f} MB: larger than any job "
                             f"({MAX_JOB_BYTES / 1e6:.0f} MB at most)", hint="give the job file 'mppf plan' wrote")
        if not stat.S_ISREG(info.st_mode) and not stat.S_ISDIR(info.st_mode):
            raise InputError(f"job file {path} is not a regular file (a device, a pipe or a socket)",
                             hint="give the job file 'mppf plan' wrote")
        text = path.read_text()
    except FileNotFoundError:
        raise InputError(f"job file {path} does not exist", hint="make one with 'mppf plan'") from None
    except (IsADirectoryError, UnicodeDecodeError, PermissionError) as exc:
        raise InputError(f"job file {path} cannot be read: {exc}") from None
    try:
        doc = json.loads(text, parse_int=_parse_int)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{path}, line {exc.lineno}: not valid JSON: {exc.msg}") from None
    except RecursionError:
        raise ConfigError(f"{path}: not a job: its JSON is nested too deeply to be one",
                          hint="give the job file 'mppf plan' wrote") from None
    return doc


def _parse_int(text: str):
    """A JSON integer: an int, or beyond 18 digits a float (infinite beyond floats: refused as not finite)."""
    return int(text) if len(text.lstrip("-")) <= 18 else float(text)


MAX_JOB_BYTES = 256_000_000
"""The largest job file read (a job of a 16 x 24 press is about 0.1 MB a step; the largest plates in many
sections and steps stay far below)."""
