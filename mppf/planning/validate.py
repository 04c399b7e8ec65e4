"""The one job validator: every check a job and its setpoints pass before anything is written.

The planner (:func:`mppf.planning.plan.plan_job`), ``mppf press`` and the press driver
(:meth:`mppf.drivers.plc_press.PlcPress.check_job` and every step's setpoints in
:meth:`~mppf.drivers.plc_press.PlcPress.run_step`) all call these functions, so a job is
held to the same rules whoever made it or edited it:

- numbers only where strokes go: finite numbers or ``null``, never booleans or strings (a
  stroke ``true`` is refused, not read as 1 mm) (:func:`check_job_document`);
- the plate no thicker than the press takes (``[forming] max_thickness_mm``);
- every active stroke within the stroke limits of its matrix, of the press description and
  of the PLC;
- the tip gap (upper minus lower) of every active pair at least the plate thickness;
- no step adding more than the dimpling limit to the height difference of neighbouring
  punches; strokes monotonic from step to step;
- parked (inactive) punches at their parking heights: no stroke in the job, park heights in
  the setpoints;
- the job's press equal to the press file when one is given, its matrix and limits those
  of the PLC when connected (:func:`validate_job`);
- its placements, marks, sections and step counts re-derived from the plan
  (:func:`mppf.planning.job_checks.check_plan`).

Before any of these, :func:`mppf.planning.job.load_job` refuses a job file whose seal does not
match (:mod:`mppf.core.seal`).

A violation raises :class:`~mppf.core.errors.LimitError` or
:class:`~mppf.core.errors.ConfigError` (exit code 2) naming the punch the way the press
labels punches (:meth:`~mppf.model.press.PressConfig.punch_label`), the value and the limit.
"""

from __future__ import annotations

import json
import math
import numbers

import numpy as np

from mppf.core.errors import ConfigError, InputError, LimitError
from mppf.model.job import Job
from mppf.model.job_parts import StepStrokes
from mppf.model.press import PressConfig
from mppf.planning.step_checks import LIMIT_TOLERANCE_MM, SIDES, StepTrack, check_step

MAX_LISTED = 10


class _Problems:
    """Collects problems; raises one error listing the first :data:`MAX_LISTED` and how many more."""

    def __init__(self):
        self.items: list[str] = []
        self.count = 0

    def add(self, texts) -> None:
        texts = list(texts)
        self.count += len(texts)
        self.items += texts[: max(0, MAX_LISTED - len(self.items))]

    def raise_if_any(self, what: str, hint: str, error=LimitError) -> None:
        if self.count:
            more = f"; and {self.count - len(self.items)} more" if self.count > len(self.items) else ""
            raise error(f"{what} ({self.count} problem(s)): " + "; ".join(self.items) + more, hint=hint)


# ------------------------------------------------------------------ the raw file ---
def check_job_document(doc, source: str = "job") -> None:
    """Refuse a job document whose strokes or activity flags are not what they claim to be.

    Every ``upper_mm`` / ``lower_mm`` entry must be ``null`` or a finite JSON number (not a
    boolean, not a string), and ``null`` for a parked punch (``active`` false: it stands at
    its park height, a stroke there would silently not be pressed); every ``active`` entry
    ``true`` or ``false``; the thickness a number. The rest of the format is
    :func:`mppf.model.job.job_from_dict`'s.

    Raises
    ------
    ConfigError
        Naming the step, the punch (row, col from 1), the value as written and what is allowed.
    """
    if not isinstance(doc, dict) or not isinstance(doc.get("steps"), list):
        return  # job_from_dict names what is missing
    label = _labeller(doc)
    problems = _Problems()
    if "thickness_mm" in doc and not _is_number(doc["thickness_mm"]):
        problems.add([f"thickness_mm is {json.dumps(doc['thickness_mm'])}, not a finite number of mm"])
    parks = _parks(doc)
    sections = doc.get("sections") if isinstance(doc.get("sections"), list) else []
    stepped = [("", doc["steps"])] + [(f"section {i} ", sec.get("steps")) for i, sec in enumerate(sections, start=1)
                                      if isinstance(sec, dict) and isinstance(sec.get("steps"), list)]
    for where, k, step in ((w, k, st) for w, steps in stepped for k, st in enumerate(steps, start=1)):
        if not isinstance(step, dict):
            continue
        active = {(r, c): value for r, c, value in _cells(step.get("active"))}
        for (r, c), value in active.items():
            if not isinstance(value, bool):
                problems.add([f"{where}step {k} punch ({label(r, c)}): active is {json.dumps(value)}, "
                              "not true or false"])
        for key in ("upper_mm", "lower_mm"):
            side = key[:5]
            for r, c, value in _cells(step.get(key)):
                if value is not None and not _is_number(value):
                    problems.add([f"{where}step {k} {side} punch ({label(r, c)}): stroke {json.dumps(value)} is not a "
                                  "finite number of mm (a stroke is a number, or null for a parked punch)"])
                elif value is not None and active.get((r, c)) is False:
                    problems.add([f"{where}step {k} {side} punch ({label(r, c)}) is parked (not active) but has a "
                                  f"stroke {value:.2f} mm; parked punches stand at park {parks.get(side, '?')} mm"])
    problems.add(f"{where} is {value} (not a finite number)" for where, value in _non_finite(
        {k: v for k, v in doc.items() if k not in ("steps", "sections", "thickness_mm")}))
    for i, sec in enumerate(sections, start=1):
        if isinstance(sec, dict):
            problems.add(f"section {i} {where} is {value} (not a finite number)"
                         for where, value in _non_finite({k: v for k, v in sec.items() if k != "steps"}))
    problems.raise_if_any(f"{source}: the job holds values that cannot be pressed",
                          "re-plan the plate with 'mppf plan'; never edit strokes by hand", ConfigError)


def _non_finite(value, where: str = ""):
    """(JSON path, value) of every NaN or infinite number in a JSON value (``punch_x_mm[3]``)."""
    if isinstance(value, float) and not math.isfinite(value):
        yield where, value
    elif isinstance(value, dict):
        for key, item in value.items():
            yield from _non_finite(item, f"{where}.{key}" if where else str(key))
    elif isinstance(value, list):
        for k, item in enumerate(value):
            yield from _non_finite(item, f"{where}[{k}]")


def _is_number(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)


def _cells(grid):
    if isinstance(grid, list):
        for r, row in enumerate(grid):
            if isinstance(row, list):
                for c, value in enumerate(row):
                    yield r, c, value


def _parks(doc: dict) -> dict:
    press = doc.get("press") if isinstance(doc.get("press"), dict) else {}
    return {side: press[side].get("park_mm") for side in SIDES if isinstance(press.get(side), dict)}


def _labeller(doc: dict):
    matrix = doc["press"].get("matrix") if isinstance(doc.get("press"), dict) else None
    matrix = matrix if isinstance(matrix, dict) else {}
    base = matrix.get("label_base", 1) if matrix.get("label_base", 1) in (0, 1) else 1
    return lambda r, c: f"row {r + base}, col {c + base}"


# ---------------------------------------------------------------- setpoints ---
def stroke_limits(press: PressConfig, plc_limits: dict | None = None) -> dict[str, tuple[float, float]]:
    """``{side: (lo, hi)}``: the press description's limits narrowed to the PLC's (mm)."""
    out = {}
    for side in SIDES:
        axis = getattr(press, side)
        lo, hi = (axis.min_mm, axis.max_mm) if plc_limits is None else plc_limits[side]
        out[side] = (max(axis.min_mm, lo), min(axis.max_mm, hi))
    return out


def check_setpoints(upper_mm, lower_mm, press: PressConfig, plc_limits: dict | None = None,
                    active=None) -> dict[str, np.ndarray]:
    """One step's setpoints of every punch, checked before they are written.

    Parameters
    ----------
    upper_mm, lower_mm : (rows, cols) float
        Tip heights of every punch (parking heights where inactive), finite numbers.
    press : PressConfig
    plc_limits : dict, optional
        The PLC's limits ``{"upper": (min, max), "lower": (min, max)}`` mm.
    active : (rows, cols) bool, optional
        Given: the inactive punches must stand at their parking heights.

    Returns
    -------
    dict of str to (rows, cols) float
        ``{"upper": ..., "lower": ...}``.

    Raises
    ------
    InputError
        Wrong shape, booleans or other non-numbers, NaN or infinite values.
    LimitError
        Setpoints beyond the limits, or parked punches away from park (lists the punches).
    """
    grids = {}
    for side, values in (("upper", upper_mm), ("lower", lower_mm)):
        grid = np.asarray(values)
        if grid.dtype == bool or not np.issubdtype(grid.dtype, np.number):
            raise InputError(f"{side} setpoints must be numbers (mm), got an array of {grid.dtype}",
                             hint="give the tip heights as floats; True is not a 1 mm stroke")
        grid = grid.astype(float)
        if grid.shape != press.shape:
            raise InputError(f"{side} setpoints have shape {grid.shape}, the press has {press.shape}")
        if not np.all(np.isfinite(grid)):
            r, c = np.argwhere(~np.isfinite(grid))[0]
            raise InputError(f"{side} setpoint of punch ({press.punch_label(r, c)}) is {grid[r, c]} (NaN or "
                             "infinite), not a finite number of mm",
                             hint="fill inactive punches with parking heights (StepStrokes.setpoints_mm)")
        grids[side] = grid
    problems = _Problems()
    for side, (lo, hi) in stroke_limits(press, plc_limits).items():
        grid = grids[side]
        problems.add(f"{side} punch ({press.punch_label(r, c)}) = {grid[r, c]:.2f} mm, limits {lo:.2f}..{hi:.2f} mm"
                     for r, c in np.argwhere((grid < lo - LIMIT_TOLERANCE_MM) | (grid > hi + LIMIT_TOLERANCE_MM)))
        if active is not None:
            park = getattr(press, side).park_mm
            away = ~np.asarray(active, bool) & (np.abs(grid - park) > LIMIT_TOLERANCE_MM)
            problems.add(f"parked {side} punch ({press.punch_label(r, c)}) = {grid[r, c]:.2f} mm, park {park:g} mm"
                         for r, c in np.argwhere(away))
    if problems.count:
        more = f"; and {problems.count - len(problems.items)} more" if problems.count > len(problems.items) else ""
        raise LimitError(f"{problems.count} setpoint(s) beyond the stroke limits, nothing was written to the PLC: "
                         + "; ".join(problems.items) + more,
                         hint="re-plan the job for this press (limits from the press description and the PLC)")
    return grids


# -------------------------------------------------------------------- steps ---
def validate_steps(steps: list[StepStrokes], press: PressConfig, thickness_mm: float,
                   plc_limits: dict | None = None, start=None) -> dict:
    """Check every step of a job before anything is written.

    Checks: the thickness at most ``press.max_thickness_mm``; active strokes finite and
    inside the limits of their matrix (the press's, narrowed to ``plc_limits``); the tip gap
    of each active pair at least the thickness (within
    :data:`mppf.planning.step_checks.GAP_TOLERANCE_MM`); no step
    adding more than ``max_neighbour_diff_mm`` to the height difference of neighbouring
    punches; strokes monotonic from step to step. Inactive punches are not checked here (they
    are parked: :func:`check_job_document`, :func:`check_setpoints`). ``start``: (upper, lower)
    (rows, cols) mm where the tips stand before the first step (a later section of a plate in sections,
    :func:`mppf.planning.section_start.section_start`); None: at the flat plate's heights.

    Returns
    -------
    dict
        ``passed`` and the measured figures: ``min_gap_mm``, ``max_neighbour_step_mm``,
        stroke ranges per matrix.

    Raises
    ------
    LimitError
        Listing the steps, punches, values and limits that violate a check.
    """
    if thickness_mm > press.max_thickness_mm:
        raise LimitError(f"the plate thickness {thickness_mm:g} mm is above the largest plate this press takes, "
                         f"[forming] max_thickness_mm {press.max_thickness_mm:g} mm",
                         hint="check the thickness, or use a press made for thicker plates")
    limits = stroke_limits(press, plc_limits)
    problems = _Problems()
    track = StepTrack.start(press, thickness_mm)
    for side, heights in zip(("upper", "lower"), start or ()):  # a later section: from the formed plate
        track.prev[side] = np.where(np.isfinite(heights), heights, track.prev[side])
    for k, step in enumerate(steps, start=1):
        check_step(k, step, press, limits, thickness_mm, problems, track)
    problems.raise_if_any("the planned strokes fail validation",
                          "give more steps (--steps), a press with longer strokes, or check the plate and thickness")
    final = steps[-1]
    act = np.asarray(final.active, bool)

    def value_range(v):
        return [float(np.min(v[act])), float(np.max(v[act]))] if act.any() else None

    return {
        "passed": True,
        "n_steps": len(steps),
        "min_gap_mm": None if not math.isfinite(track.min_gap_mm) else track.min_gap_mm,
        "max_neighbour_step_mm": track.max_step_diff_mm,
        "dimpling_limit_mm": press.max_neighbour_diff_mm,
        "upper_range_mm": value_range(final.upper_mm),
        "lower_range_mm": value_range(final.lower_mm),
        "upper_limits_mm": [press.upper.min_mm, press.upper.max_mm],
        "lower_limits_mm": [press.lower.min_mm, press.lower.max_mm],
    }


# ---------------------------------------------------------------------- job ---
def _flat_keys(press: PressConfig) -> dict:
    """``{"[table] key": value}`` of a press description."""
    out = {}
    for table, block in press.to_dict().items():
        if isinstance(block, dict):
            out.update({f"[{table}] {key}": value for key, value in block.items()})
        else:
            out[table] = block
    return out


def press_differences(job_press: PressConfig, press_file: PressConfig, source: str) -> list[str]:
    """Each key whose value differs between two press descriptions, as ``"[forming] speed_mm_s is ..."``."""
    mine, theirs = _flat_keys(job_press), _flat_keys(press_file)
    return [f"{key} is {mine[key]!r} in the job, {theirs[key]!r} in {source}"
            for key in mine if mine[key] != theirs[key]]


def validate_job(job: Job, *, press_file: PressConfig | None = None, plc_shape: tuple[int, int] | None = None,
                 plc_limits: dict | None = None, press_source: str = "the press file") -> dict:
    """Every check of a job: its press against the press file and the PLC, then its steps.

    Parameters
    ----------
    job : Job
    press_file : PressConfig, optional
        The press description the job must have been planned for (every key equal).
    plc_shape : (int, int), optional
        The PLC's matrix (rows, cols).
    plc_limits : dict, optional
        The PLC's stroke limits ``{"upper": (min, max), "lower": (min, max)}`` mm: the job's
        press may not reach beyond them.
    press_source : str
        How to name ``press_file`` in messages (its path).

    Returns
    -------
    dict
        The report of :func:`validate_steps`.

    Raises
    ------
    ConfigError
        The job's press differs from the press file, or has another matrix than the PLC.
    LimitError
        The job's press reaches beyond the PLC's limits, or a step fails :func:`validate_steps`.
    """
    from mppf.planning.job_checks import check_plan

    press = job.press
    if press_file is not None and press_file != press:
        raise ConfigError(f"the job was planned for another press than {press_source}: "
                          + "; ".join(press_differences(press, press_file, press_source)[:MAX_LISTED]),
                          hint="plan the plate for this press, or give the press file the job was planned for")
    if plc_shape is not None and tuple(plc_shape) != press.shape:
        raise ConfigError(f"the job is for {press.rows} x {press.cols} punches, the PLC drives "
                          f"{plc_shape[0]} x {plc_shape[1]}", hint="use the job planned for this press")
    check_plan(job)  # placements, marks, sections and step counts re-derived from the plan
    if plc_limits is not None:
        _check_plc_limits(press, plc_limits)
    report = validate_steps(job.steps, press, job.thickness_mm, plc_limits)
    report.update(_validate_sections(job, plc_limits))
    return report


def _check_plc_limits(press: PressConfig, plc_limits: dict) -> None:
    """Refuse a press whose stroke limits reach beyond the PLC's.

    Parameters
    ----------
    press : PressConfig
        The job's press.
    plc_limits : dict
        ``{"upper": (min, max), "lower": (min, max)}`` mm, the PLC's stroke limits.

    Raises
    ------
    LimitError
        Every limit of the press beyond the PLC's by more than 0.005 mm, listed.
    """
    problems = _Problems()
    for side in SIDES:
        axis, (lo, hi) = getattr(press, side), plc_limits[side]
        for key, value, limit, beyond in (("min_mm", axis.min_mm, lo, axis.min_mm < lo - 0.005),
                                          ("max_mm", axis.max_mm, hi, axis.max_mm > hi + 0.005)):
            if beyond:
                problems.add([f"[{side}] {key} {value:g} mm of the job's press is beyond the PLC's limit {limit:g} mm"])
    problems.raise_if_any("the job's press reaches beyond the PLC's stroke limits",
                          "plan the plate with the press description of this press (its limits are the PLC's)")


def _validate_sections(job: Job, plc_limits: dict | None) -> dict:
    """``{"section k": report of validate_steps}`` of every section in pressing order (``{}``: one piece).

    ``plc_limits`` as :func:`validate_job`. Raises LimitError when a section's steps fail, the
    message prefixed with ``section k:``.
    """
    from mppf.planning.section_start import section_start

    reports = {}
    for k, section in enumerate(job.sections or []):
        try:
            reports[f"section {section.index}"] = validate_steps(
                section.steps, job.press, job.thickness_mm, plc_limits,
                section_start(job.sections, k, job.press, job.thickness_mm))
        except LimitError as exc:
            raise LimitError(f"section {section.index}: {exc.message}", hint=exc.hint) from None
    return reports
