"""The job file: the planned strokes of a plate, the contract between planner and press.

A job is JSON, versioned (``"format": "mppf-job"``, ``"version": 1``); see
``docs/file-formats.md``. In memory, stroke arrays are (rows, cols) float mm with NaN
where a punch is inactive; in the file, inactive entries are ``null``. Inactive punches
are driven to their parking heights by the press driver.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mppf.errors import ConfigError, InputError
from mppf.press import PressConfig, press_from_dict
from mppf.transform import tf_from_list, tf_to_list

JOB_FORMAT = "mppf-job"
JOB_VERSION = 1


@dataclass(frozen=True)
class StepStrokes:
    """Tip heights of both matrices for one press step.

    Attributes
    ----------
    upper_mm, lower_mm : (rows, cols) float
        Tip heights in press z (mm); NaN where the punch is inactive.
    active : (rows, cols) bool
        True where the punch pair acts on the plate.
    """

    upper_mm: np.ndarray
    lower_mm: np.ndarray
    active: np.ndarray

    def setpoints_mm(self, press: PressConfig) -> tuple[np.ndarray, np.ndarray]:
        """Setpoints for every punch: the strokes, parking heights where inactive.

        Returns
        -------
        upper_mm, lower_mm : (rows, cols) float, no NaN
        """
        upper = np.where(self.active, self.upper_mm, press.upper.park_mm)
        lower = np.where(self.active, self.lower_mm, press.lower.park_mm)
        return upper, lower


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
    extra : dict
        Everything else the planner records (registration report, validation,
        input hashes, plate corners, material...), stored as-is.
    """

    press: PressConfig
    thickness_mm: float
    steps: list[StepStrokes]
    tf_press_design: np.ndarray = field(default_factory=lambda: np.eye(4))
    tf_press_flat: np.ndarray = field(default_factory=lambda: np.eye(4))
    punch_x_mm: np.ndarray | None = None
    punch_y_mm: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

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
            "steps": [
                {
                    "index": k + 1,
                    "upper_mm": _grid_to_json(s.upper_mm, s.active),
                    "lower_mm": _grid_to_json(s.lower_mm, s.active),
                    "active": s.active.astype(bool).tolist(),
                }
                for k, s in enumerate(self.steps)
            ],
        }
        for key, value in self.extra.items():
            doc.setdefault(key, value)
        return doc

    def to_json(self) -> str:
        """Serialized job (stable key order, so its hash is reproducible)."""
        return json.dumps(self.to_dict(), indent=1, allow_nan=False)

    def sha256(self) -> str:
        """SHA-256 of the serialized job (used in the audit log and history)."""
        return hashlib.sha256(self.to_json().encode()).hexdigest()


def grid_to_json(values) -> list | None:
    """A (rows, cols) float grid as nested lists, NaN as None (None stays None)."""
    if values is None:
        return None
    arr = np.asarray(values, dtype=float)
    return [[round(float(v), 4) if math.isfinite(v) else None for v in row] for row in arr]


def grid_from_json(rows) -> np.ndarray | None:
    """Inverse of :func:`grid_to_json`."""
    if rows is None:
        return None
    return np.array([[np.nan if v is None else v for v in row] for row in rows], dtype=float)


def _grid_to_json(values: np.ndarray, active: np.ndarray) -> list:
    return grid_to_json(np.where(np.asarray(active, dtype=bool), np.asarray(values, dtype=float), np.nan))


def _grid_from_json(rows, shape, name: str, source: str) -> np.ndarray:
    try:
        arr = np.array([[np.nan if v is None else v for v in row] for row in rows], dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{source}: {name} must be a grid of numbers or null") from None
    if arr.shape != shape:
        raise ConfigError(f"{source}: {name} has shape {arr.shape}, the press has {shape}")
    return arr


def job_from_dict(doc: dict, source: str = "job") -> Job:
    """Validate and build a :class:`Job` from its JSON document.

    Raises
    ------
    ConfigError
        Wrong format or version, missing keys, or grids that do not match the press.
    """
    if not isinstance(doc, dict) or doc.get("format") != JOB_FORMAT:
        raise ConfigError(
            f"{source}: not an mppf job file (format {doc.get('format') if isinstance(doc, dict) else None!r})",
            hint="make one with 'mppf plan'",
        )
    if doc.get("version") != JOB_VERSION:
        raise ConfigError(
            f"{source}: job file version {doc.get('version')!r} is not supported (this mppf reads {JOB_VERSION})",
            hint="re-plan the plate with this version of mppf",
        )
    for key in ("press", "thickness_mm", "steps"):
        if key not in doc:
            raise ConfigError(f"{source}: missing key '{key}'")
    press = press_from_dict(doc["press"], source=f"{source} [press]")
    thickness = doc["thickness_mm"]
    if isinstance(thickness, bool) or not isinstance(thickness, (int, float)) or not thickness > 0:
        raise ConfigError(f"{source}: thickness_mm must be a positive number, got {thickness!r}")
    steps_doc = doc["steps"]
    if not isinstance(steps_doc, list) or not steps_doc:
        raise ConfigError(f"{source}: 'steps' must be a non-empty list")
    steps = []
    for k, s in enumerate(steps_doc, start=1):
        if not isinstance(s, dict) or not {"upper_mm", "lower_mm", "active"} <= set(s):
            raise ConfigError(f"{source}: step {k} needs upper_mm, lower_mm and active")
        active = _grid_from_json(s["active"], press.shape, f"step {k} active", source).astype(bool)
        upper = _grid_from_json(s["upper_mm"], press.shape, f"step {k} upper_mm", source)
        lower = _grid_from_json(s["lower_mm"], press.shape, f"step {k} lower_mm", source)
        if np.any(active & (np.isnan(upper) | np.isnan(lower))):
            raise ConfigError(f"{source}: step {k} has active punches without a stroke (null)")
        steps.append(StepStrokes(upper_mm=upper, lower_mm=lower, active=active))
    known = {"format", "version", "press", "thickness_mm", "steps", "tf_press_design", "tf_press_flat",
             "punch_x_mm", "punch_y_mm"}
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
        extra={k: v for k, v in doc.items() if k not in known},
        **transforms,
    )


def _axis_from_json(values, count: int, name: str, source: str) -> np.ndarray:
    """Punch axis positions (count,) mm from the job document, checked."""
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{source}: {name} must be a list of numbers (mm), got {values!r:.60}") from None
    if arr.shape != (count,) or not np.all(np.isfinite(arr)):
        raise ConfigError(f"{source}: {name} must hold {count} finite numbers (one per punch), got shape "
                          f"{arr.shape}", hint="re-plan the plate with 'mppf plan'")
    return arr


def load_job(path) -> Job:
    """Read and validate a job file.

    Raises
    ------
    InputError
        Missing or unreadable file, invalid JSON, or an invalid job.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise InputError(f"job file {path} does not exist", hint="make one with 'mppf plan'") from None
    except (IsADirectoryError, UnicodeDecodeError, PermissionError) as exc:
        raise InputError(f"job file {path} cannot be read: {exc}") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{path}, line {exc.lineno}: not valid JSON: {exc.msg}") from None
    return job_from_dict(doc, source=str(path))


def save_job(job: Job, path) -> Path:
    """Write a job file atomically (a temporary file renamed into place)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(job.to_json())
        tmp.replace(path)
    except OSError as exc:
        raise InputError(f"cannot write job file {path}: {exc.strerror}", hint="choose a writable path") from None
    return path
