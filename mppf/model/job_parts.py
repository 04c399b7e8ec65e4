"""The parts of a job file: the strokes of one press step and the plate's layout on the press.

Shared by the job (:mod:`mppf.model.job`) and its sections (:mod:`mppf.model.job_sections`). In memory, stroke arrays are
(rows, cols) float mm with NaN where a punch is inactive; in the file, inactive entries are ``null``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mppf.core.errors import ConfigError
from mppf.core.validate import check_number
from mppf.model.material import Material
from mppf.model.press import PressConfig


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

    The flat plate is cut with a mark on one corner of the plate AS CUT (the net outline
    grown by the trim margin: the physical corner the operator sees); the operator lays it
    in the press by the corner positions of the plan with the mark on the corner nearest
    the press's first punch (row 1, column 1), so this is where the mark is. The job
    layout, the cutter's DXF, the placement view and the comparison all take this corner
    of the outline as cut (``docs/file-formats.md``, "The reference mark").

    Parameters
    ----------
    outline_xy_mm : (k, 2) float
        An outline on the press (the outline as cut, for the mark).

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
        Where the plate's reference mark lies: :func:`reference_corner_xy` of the outline
        AS CUT (``outline_mm``, the net outline grown by the margin), the physical corner the
        operator sees. Always derived from ``outline_mm`` when a job file is read (jobs
        written before this definition stored the net outline's corner there; that value is
        not used).
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
            object.__setattr__(self, "reference_corner_mm", reference_corner_xy(self.outline_mm))
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
            mid = doc.get("design_mid_mm")
            material = doc.get("material")
            # the mark's corner is always that of the outline as cut: a stored "reference_corner_mm"
            # (older jobs stored the net outline's corner) is not read
            layout = cls(outline_mm=outline, net_outline_mm=net, margin_mm=margin,
                         design_mid_mm=grid_from_json(mid), material=None if not material else Material(**material))
        except (KeyError, TypeError, ValueError, OverflowError) as exc:
            raise ConfigError(f"{source}: the plate layout is malformed ({type(exc).__name__}: {exc})",
                              hint="re-plan the plate with 'mppf plan'") from None
        for name, poly in (("outline_mm", layout.outline_mm), ("net_outline_mm", layout.net_outline_mm)):
            if poly.shape[0] < 3 or not np.all(np.isfinite(poly)):
                raise ConfigError(f"{source}: plate {name} must be at least 3 finite (x, y) corners",
                                  hint="re-plan the plate with 'mppf plan'")
        check_number(f"{source}: plate margin_mm", layout.margin_mm, low=0.0, unit="mm",
                     hint="re-plan the plate with 'mppf plan'", error=ConfigError)
        return layout


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


def active_grid_to_json(values: np.ndarray, active: np.ndarray) -> list:
    """A (rows, cols) grid as nested lists, ``null`` where the punch is not ``active`` (or the value is NaN)."""
    return grid_to_json(np.where(np.asarray(active, dtype=bool), np.asarray(values, dtype=float), np.nan))


def checked_grid_from_json(rows, shape, name: str, source: str) -> np.ndarray:
    """A (rows, cols) float grid from nested lists (``null`` as NaN), checked to have ``shape``.

    Raises
    ------
    ConfigError
        Not a grid of numbers or null, or another shape; names ``name`` and ``source``.
    """
    try:
        arr = np.array([[np.nan if v is None else v for v in row] for row in rows], dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{source}: {name} must be a grid of numbers or null") from None
    if arr.shape != shape:
        raise ConfigError(f"{source}: {name} has shape {arr.shape}, the press has {shape}")
    return arr


def steps_to_json(steps) -> list:
    """The ``"steps"`` list of a job document (1-based ``index``, ``null`` at inactive punches)."""
    return [{"index": k + 1, "upper_mm": active_grid_to_json(s.upper_mm, s.active),
             "lower_mm": active_grid_to_json(s.lower_mm, s.active), "active": s.active.astype(bool).tolist()}
            for k, s in enumerate(steps)]


def steps_from_json(steps_doc, press: PressConfig, source: str) -> list[StepStrokes]:
    """Inverse of :func:`steps_to_json`, checked against the press's matrix.

    Raises
    ------
    ConfigError
        Not a non-empty list, a step without its grids, grids of another shape, active punches without a stroke.
    """
    if not isinstance(steps_doc, list) or not steps_doc:
        raise ConfigError(f"{source}: 'steps' must be a non-empty list")
    steps = []
    for k, s in enumerate(steps_doc, start=1):
        if not isinstance(s, dict) or not {"upper_mm", "lower_mm", "active"} <= set(s):
            raise ConfigError(f"{source}: step {k} needs upper_mm, lower_mm and active")
        active = checked_grid_from_json(s["active"], press.shape, f"step {k} active", source).astype(bool)
        upper = checked_grid_from_json(s["upper_mm"], press.shape, f"step {k} upper_mm", source)
        lower = checked_grid_from_json(s["lower_mm"], press.shape, f"step {k} lower_mm", source)
        if np.any(active & (np.isnan(upper) | np.isnan(lower))):
            raise ConfigError(f"{source}: step {k} has active punches without a stroke (null)")
        steps.append(StepStrokes(upper_mm=upper, lower_mm=lower, active=active))
    return steps
