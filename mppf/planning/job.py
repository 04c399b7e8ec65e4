"""The job file: the planned strokes of a plate, the contract between planner and press.

A job is JSON, versioned (``"format": "mppf-job"``, ``"version": 2``; version-1 files are
read too); see ``docs/file-formats.md``. In memory, stroke arrays are (rows, cols) float mm with NaN
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

from mppf.core.errors import ConfigError, InputError
from mppf.core.transform import tf_from_list, tf_to_list
from mppf.core.validate import check_number
from mppf.forming.material import Material
from mppf.planning.press import PressConfig, press_from_dict

JOB_FORMAT = "mppf-job"
JOB_VERSION = 2
READ_VERSIONS = (1, 2)
"""Job file versions this mppf reads (version 1: the plate layout in loose top-level keys)."""


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


def reference_corner_xy(outline_xy_mm) -> np.ndarray:
    """The plate's reference corner on the press: the outline corner with the smallest x + y.

    The flat plate is cut with a mark on one corner; the operator lays it in the press
    by the corner positions of the plan with the mark on the corner nearest the press's
    first punch (row 1, column 1), so this is where the mark is.

    Parameters
    ----------
    outline_xy_mm : (k, 2) float
        An outline on the press.

    Returns
    -------
    (2,) float, press x, y in mm
    """
    outline = np.asarray(outline_xy_mm, dtype=float).reshape(-1, 2)
    return outline[int(np.argmin(outline[:, 0] + outline[:, 1]))].copy()


@dataclass(frozen=True, eq=False)
class PlateLayout:
    """Where the plate lies on the press and what the later stages need to know of it.

    Written by the planner, read by the press's placement output, the loop, the
    comparison and the simulated plate. Lengths in mm, press coordinates.

    Attributes
    ----------
    outline_mm : (k, 2) float
        The plate as cut (net outline grown by the trim margin), counter-clockwise.
    net_outline_mm : (j, 2) float
        The net plate (the design's outline seen from above), counter-clockwise.
    margin_mm : float
        Width of the trim margin (0: the plate is cut to its net outline).
    reference_corner_mm : (2,) float
        Where the plate's reference mark lies (:func:`reference_corner_xy` of the net outline).
    design_mid_mm : (rows, cols) float or None
        The design's mid-surface height at each active punch axis, as the tips would hold
        it (NaN at inactive punches); None for jobs planned before it was recorded.
    material : Material or None
        The nominal material the plate was planned with (None: no springback planning).
    """

    outline_mm: np.ndarray
    net_outline_mm: np.ndarray
    margin_mm: float = 0.0
    reference_corner_mm: np.ndarray | None = None
    design_mid_mm: np.ndarray | None = None
    material: Material | None = None

    def __post_init__(self):
        object.__setattr__(self, "outline_mm", np.asarray(self.outline_mm, dtype=float).reshape(-1, 2))
        object.__setattr__(self, "net_outline_mm", np.asarray(self.net_outline_mm, dtype=float).reshape(-1, 2))
        object.__setattr__(self, "margin_mm", float(self.margin_mm))
        if self.reference_corner_mm is None:
            object.__setattr__(self, "reference_corner_mm", reference_corner_xy(self.net_outline_mm))
        else:
            object.__setattr__(self, "reference_corner_mm", np.asarray(self.reference_corner_mm, dtype=float))
        if self.design_mid_mm is not None:
            object.__setattr__(self, "design_mid_mm", np.asarray(self.design_mid_mm, dtype=float))

    def to_dict(self) -> dict:
        """The ``"plate"`` block of a version-2 job file."""
        m = self.material
        return {
            "outline_mm": self.outline_mm.tolist(),
            "net_outline_mm": self.net_outline_mm.tolist(),
            "margin_mm": self.margin_mm,
            "reference_corner_mm": self.reference_corner_mm.tolist(),
            "design_mid_mm": grid_to_json(self.design_mid_mm),
            "material": None if m is None else {"youngs_modulus_mpa": m.youngs_modulus_mpa, "poisson": m.poisson,
                                                "yield_stress_mpa": m.yield_stress_mpa},
        }

    @classmethod
    def from_dict(cls, doc: dict, source: str = "job") -> PlateLayout:
        """Inverse of :meth:`to_dict` (also the loose keys of a version-1 job).

        Raises
        ------
        ConfigError
            Missing or malformed outlines, margin or material.
        """
        try:
            outline = np.asarray(doc["outline_mm"], dtype=float)
            net = np.asarray(doc.get("net_outline_mm") or doc["outline_mm"], dtype=float)
            margin = doc.get("margin_mm", 0.0)
            corner = doc.get("reference_corner_mm")
            mid = doc.get("design_mid_mm")
            material = doc.get("material")
            layout = cls(outline_mm=outline, net_outline_mm=net, margin_mm=margin,
                         reference_corner_mm=None if corner is None else np.asarray(corner, dtype=float),
                         design_mid_mm=grid_from_json(mid), material=None if not material else Material(**material))
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"{source}: the plate layout is malformed ({type(exc).__name__}: {exc})",
                              hint="re-plan the plate with 'mppf plan'") from None
        for name, poly in (("outline_mm", layout.outline_mm), ("net_outline_mm", layout.net_outline_mm)):
            if poly.shape[0] < 3 or not np.all(np.isfinite(poly)):
                raise ConfigError(f"{source}: plate {name} must be at least 3 finite (x, y) corners",
                                  hint="re-plan the plate with 'mppf plan'")
        check_number(f"{source}: plate margin_mm", layout.margin_mm, low=0.0, unit="mm",
                     hint="re-plan the plate with 'mppf plan'", error=ConfigError)
        return layout


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
    extra : dict
        The planner's reports (registration, validation, pose, input hashes, plate
        corners, springback...), stored as-is.
    """

    press: PressConfig
    thickness_mm: float
    steps: list[StepStrokes]
    tf_press_design: np.ndarray = field(default_factory=lambda: np.eye(4))
    tf_press_flat: np.ndarray = field(default_factory=lambda: np.eye(4))
    punch_x_mm: np.ndarray | None = None
    punch_y_mm: np.ndarray | None = None
    layout: PlateLayout | None = None
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
        if self.layout is not None:
            doc["plate"] = self.layout.to_dict()
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
    if doc.get("version") not in READ_VERSIONS:
        raise ConfigError(
            f"{source}: job file version {doc.get('version')!r} is not supported (this mppf reads "
            f"{', '.join(str(v) for v in READ_VERSIONS)})",
            hint="re-plan the plate with this version of mppf",
        )
    for key in ("press", "thickness_mm", "steps"):
        if key not in doc:
            raise ConfigError(f"{source}: missing key '{key}'")
    press = press_from_dict(doc["press"], source=f"{source} [press]")
    thickness = check_number(f"{source}: thickness_mm", doc["thickness_mm"], low=0.0, low_open=True, unit="mm",
                             hint="re-plan the plate with 'mppf plan'", error=ConfigError)
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
             "punch_x_mm", "punch_y_mm", "plate"}
    layout = _layout_from_doc(doc, source)
    if doc["version"] == 1:  # the loose layout keys of version 1 now live in the layout
        known |= set(V1_LAYOUT_KEYS)
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
        extra={k: v for k, v in doc.items() if k not in known},
        **transforms,
    )


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
