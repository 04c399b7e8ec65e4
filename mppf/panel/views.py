"""What each view of the panel shows, as template contexts built from the history and the jobs.

One function per view (``place``, ``live``, ``loop``, ``history``, ``plate``); each returns
a plain dict for its Jinja2 template, with the pictures already drawn as SVG text
(:mod:`mppf.panel.svg`, :mod:`mppf.panel.placement`, :mod:`mppf.panel.charts`).
"""

from __future__ import annotations

from datetime import datetime, timezone

import numpy as np

from mppf.loop.states import CycleState, Decision
from mppf.model.placement import placement_of
from mppf.panel.charts import convergence_svg
from mppf.panel.config import PanelConfig
from mppf.panel.placement import bed_svg
from mppf.panel.sources import HistoryReader, next_cycle, read_job, report_files
from mppf.panel.svg import DIVERGING, VIRIDIS, heat_map, legend, punch_name, scale_of

VERDICTS = {
    Decision.IN_TOLERANCE: ("IN TOLERANCE", "ok", "the loop is done"),
    Decision.CONTINUE: ("OUT OF TOLERANCE", "bad", "the next cycle corrects the strokes"),
    Decision.MAX_CYCLES: ("OUT OF TOLERANCE", "bad", "stopped: no cycles left (--max-cycles)"),
    Decision.DIVERGED: ("OUT OF TOLERANCE", "bad", "stopped: the deviation grows (diverged)"),
    Decision.CANNOT_CONVERGE: ("OUT OF TOLERANCE", "bad", "stopped: the correction finds no way on (see its verdict)"),
    Decision.NEEDS_REVIEW: ("NEEDS REVIEW", "review", "stopped: within the limits, but not all of it was measured "
                                                      "or set-aside points lie beyond the tolerance: a person looks"),
    Decision.BADLY_FORMED: ("OUT OF TOLERANCE", "bad", "stopped: the plate is far from its design (badly formed): "
                                                     "a person looks"),
}
"""Large-type verdict, its colour class and what follows, per decision."""

TOP_PUNCHES = 8
"""Largest punch deviations named in the loop view."""


def _age(utc: str) -> str:
    """How long ago an ISO time was, as "4 min" / "2 h 5 min"."""
    seconds = max(0.0, datetime.now(timezone.utc).timestamp() - datetime.fromisoformat(utc).timestamp())
    minutes = int(seconds // 60)
    return f"{int(seconds)} s" if minutes < 1 else f"{minutes} min" if minutes < 60 else \
        f"{minutes // 60} h {minutes % 60} min"


def _time(utc: str | None) -> str:
    return "" if not utc else utc[:19].replace("T", " ") + " UTC"


def press_of(cfg: PanelConfig, reader: HistoryReader):
    """The press description: the configured one, else the history's current plate's (None if neither)."""
    if cfg.press is not None:
        return cfg.press
    from mppf.model.press import press_from_dict

    current = reader.current()
    return None if current is None else press_from_dict(current[0].press, source="the plate history")


def place(cfg: PanelConfig, plate_id: str | None = None, section: str | None = None) -> dict:
    """"Lay the plate": the bed, the plate as cut, the corners, for the cycle about to be pressed.

    A job planned in sections shows one section at a time (``section``, 1-based, default 1):
    its placement, its marks and the punches they go over, and links to the others.
    """
    reader = HistoryReader(cfg.history_path)
    ctx = {"view": "place", "plate": None, "cycle": None, "job_path": None, "error": "", "rows": [], "bed": "",
           "section": None}
    if cfg.job_path is not None:
        ctx["job_path"] = str(cfg.job_path)
        job, ctx["error"] = read_job(cfg.job_path)
        step = 0
    else:
        current = reader.current(plate_id)
        if current is None:
            return {**ctx, "error": f"no plate in the history {cfg.history_path} yet (and no --job given)"}
        ctx["plate"], cycles = current
        cycle = next_cycle(cycles)
        ctx["cycle"], ctx["job_path"] = cycle, cycle.job_path
        job, ctx["error"] = read_job(cycle.job_path)
        step = min(cycle.steps_done, len(cycle.steps) - 1)
    if job is None:
        return ctx
    layout, steps = job.layout, job.steps
    if job.sections:
        chosen, ctx["section"], ctx["error"] = _section(job, section, cfg.base)
        layout, steps = chosen.layout, chosen.steps
    if layout is None:
        return {**ctx, "error": "the job has no plate outline (planned by an old mppf): re-plan it"}
    placement = placement_of(layout)
    step = min(step, len(steps) - 1)
    return {**ctx, "rows": placement.rows(), "mark": placement.mark_mm.tolist(), "margin_mm": placement.margin_mm,
            "job_press": job.press.name, "step": step + 1, "n_steps": len(steps),
            "size_mm": np.ptp(placement.cut_corners_mm, axis=0).tolist(),
            "bed": bed_svg(job.press, placement, active=steps[step].active, base=cfg.base)}


def _section(job, asked: str | None, base: int):
    """(the section shown, its context, an error text): ``asked`` 1-based, section 1 when absent or unknown."""
    from mppf.planning.sections import placement_text

    n, error, k = len(job.sections), "", 1
    if asked:
        try:
            k = int(asked)
        except ValueError:
            k = 0
        if not 1 <= k <= n:
            error, k = f"section {asked!r} does not exist: the job has sections 1 to {n} (section 1 shown)", 1
    chosen = job.sections[k - 1]
    previous = job.sections[k - 2] if k > 1 else None
    instruction = placement_text(chosen, previous, label=lambda r, c: f"R{r + base} C{c + base}")
    marks = [{"name": f"{k}{'ab'[i]}", "x_mm": float(x), "y_mm": float(y)}
             for i, (x, y) in enumerate(np.asarray(chosen.marks_press_mm, dtype=float)[:, :2])]
    return chosen, {"index": k, "count": n, "instruction": instruction, "marks": marks}, error


def live(cfg: PanelConfig, press) -> dict:
    """"Live press": empty heat maps (target and actual of both matrices) that the page fills."""
    ctx = {"view": "live", "press": press, "maps": [], "legends": {}}
    if press is None:
        return ctx
    empty = np.full(press.shape, np.nan)
    lo, hi = min(press.lower.min_mm, press.upper.min_mm), max(press.lower.max_mm, press.upper.max_mm)
    for side in ("upper", "lower"):
        for kind in ("target", "actual"):
            ctx["maps"].append({"side": side, "kind": kind, "svg": heat_map(
                empty, lo=lo, hi=hi, id_prefix=f"{side}-{kind}", title=f"{side} matrix: {kind} (mm)", base=cfg.base)})
        ctx["legends"][side] = legend(lo, hi, cmap=VIRIDIS, label=f"{side} tip height", id_prefix=f"{side}-scale")
    ctx["viridis"] = list(VIRIDIS)
    return ctx


def loop(cfg: PanelConfig, plate_id: str | None = None) -> dict:
    """"Loop": the plate, its cycle and state, the verdict, the deviation maps, convergence, next correction."""
    current = HistoryReader(cfg.history_path).current(plate_id)
    if current is None:
        return {"view": "loop", "plate": None, "history_path": str(cfg.history_path)}
    plate, cycles = current
    settings = plate.settings.get("loop", {})
    tol, rms_tol = settings.get("tolerance_mm"), settings.get("rms_tolerance_mm")
    last = cycles[-1]
    measured = [c for c in cycles if c.punch_deviation_mm is not None]
    lim = scale_of(*[c.punch_deviation_mm for c in measured], symmetric=True, at_least=tol or 1.0)[1]
    ctx = {"view": "loop", "plate": plate, "cycle": last, "tolerance_mm": tol, "rms_tolerance_mm": rms_tol,
           "waiting": last.state == CycleState.PRESSED, "waiting_for": _age(last.updated_utc),
           "step_text": f"step {last.step_started} of {len(last.steps)}" if last.state == CycleState.PRESSING else "",
           "dev_maps": [{"cycle": c.cycle, "svg": heat_map(c.punch_deviation_mm, lo=-lim, hi=lim, cmap=DIVERGING,
                                                            title=f"cycle {c.cycle}: deviation at the punches (mm)",
                                                            base=cfg.base)} for c in reversed(measured)],
           "dev_legend": legend(-lim, lim, cmap=DIVERGING, label="deviation (+ above the design)"),
           "convergence": convergence_svg([c.cycle for c in cycles], [c.max_abs_mm for c in cycles],
                                          [c.rms_mm for c in cycles], tolerance_mm=tol, rms_tolerance_mm=rms_tol),
           "verdict": None, "top": [], "correction": None}
    if measured:
        m = measured[-1]
        ctx["measured"] = m
        ctx["verdict"] = VERDICTS.get(m.decision, ("MEASURED", "", "")) if m.decision else ("MEASURED", "", "")
        dev = m.punch_deviation_mm
        order = [tuple(rc) for rc in np.argwhere(np.isfinite(dev))]
        order.sort(key=lambda rc: -abs(dev[rc]))
        ctx["top"] = [{"name": punch_name(r, c, cfg.base), "mm": float(dev[r, c])} for r, c in order[:TOP_PUNCHES]]
        ctx["correction"] = _correction(cycles, m.cycle, cfg.base)
    return ctx


def _correction(cycles, measured_cycle: int, base: int) -> dict | None:
    """The correction made from ``measured_cycle`` (recorded with the cycle after it), drawn."""
    after = [c for c in cycles if c.cycle == measured_cycle + 1 and c.correction]
    if not after:
        return None
    from mppf.model.job_parts import grid_from_json

    corr = after[0].correction
    applied = grid_from_json(corr.get("applied_mm"))
    if applied is None:
        return None
    lim = scale_of(applied, symmetric=True, at_least=1.0)[1]
    return {"cycle": after[0].cycle, "clipped": corr.get("clipped_punches", 0), "notes": corr.get("notes", []),
            "gain": after[0].gain, "largest_mm": float(np.nanmax(np.abs(applied))) if np.isfinite(applied).any() else 0,
            "svg": heat_map(applied, lo=-lim, hi=lim, cmap=DIVERGING,
                            title=f"cycle {after[0].cycle}: stroke correction (mm)", base=base),
            "legend": legend(-lim, lim, cmap=DIVERGING, label="correction of the lower strokes")}


def history(cfg: PanelConfig) -> dict:
    """"History": every plate with its status and last measured deviations."""
    reader = HistoryReader(cfg.history_path)
    rows = []
    for p in reader.plates():
        _, cycles = reader.plate(p.plate_id)
        done = [c for c in cycles if c.max_abs_mm is not None]
        rows.append({"plate": p, "cycles": len(cycles), "last": done[-1] if done else None,
                     "updated": _time(p.updated_utc)})
    return {"view": "history", "rows": rows, "exists": reader.exists, "history_path": str(cfg.history_path)}


def plate(cfg: PanelConfig, plate_id: str) -> dict:
    """One plate: its cycles, its events and its reports."""
    reader = HistoryReader(cfg.history_path)
    record, cycles = reader.plate(plate_id)
    return {"view": "history", "plate": record, "cycles": cycles, "events": reader.events(plate_id),
            "reports": [p.name for p in report_files(record)], "time": _time}
