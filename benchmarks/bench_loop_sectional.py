"""Benchmark: does the loop bring plates larger than the press into tolerance, section by section?

For every bundled long plate x physics x seed: plan the plate in sections with the NOMINAL material
(springback pre-compensated, :func:`mppf.loop.plate.plan_first_cycle`), then press a simulated plate that is
not the planner's model section by section (the plate shifted under the press for each,
:meth:`mppf.sim.plate.plate.SteelPlate.place`), measure it, correct every section and press again, for up to
``--max-cycles`` cycles. Targets (issue 42): every plate in tolerance (form max <= 2.5 mm, RMS <= 1 mm)
within 5 cycles, no section border kinked by more than the tolerance.

Plates (``--plates``): the 7.5 x 2.4 m cylinder (R 20 m) and twisted plate and the 9 m KCS stern plate of
``mppf/examples/long/``, and two plates cut from the KCS hull by ``benchmarks/real_plates.py`` (``real0010``:
x 55.4-64.7 m, girth 13.4-15.3 m, 9.3 x 1.9 m; ``real0008``: x 151.7-158.4 m, girth 5.7-8.2 m, 6.7 x 2.5 m;
``real0013``, 6.9 x 2.8 m of the stern, needs more stroke than the example press has and is not used).
Physics (``--physics``): the finite-difference steel plate of :mod:`mppf.sim.plate` as
:mod:`benchmarks.bench_loop` builds it (``steel``, ``yield:1.2``...). The FE plate (CalculiX) cannot be
pressed in sections (its punch contacts are fixed to the first placement: ``FEPlate.place`` refuses), so
it is left out here.

Mode ``direct`` (the only one): the sectional loop's correction
(:func:`mppf.loop.sectional.plan_next_sections`'s: the loop's one correction, :func:`mppf.correct.step.correct_step`,
per section on its plane-free deviation, then :func:`mppf.planning.sectional.apply_section_corrections` not
blended) on the TRUE deviation: the formed mid-surface against the design placed as section 1 places it, best
plane removed over the whole plate; at each section's punches where the section places the design. No scanner.

Per cycle: form max and RMS over the whole net plate, the **border kink**: at each section's bed edge
inside the plate, the deviation's departure from the straight line through its values one pitch to
either side, ``|e(b) - (e(b - p) + e(b + p)) / 2|`` (a smooth deviation has none; a step or a kink left
where a section ended shows here), largest over the borders of all sections; and the largest deviation
more than 300 mm inside the plate's edges (``inner_max``: the simulated plate's free corners and ends beyond
the outer punches depend on its grid on long plates).

Corrections (``--correction``): ``learned`` (default) as above; ``aim``: one correction field of the whole
plate (:class:`AimedTarget`): the plate planned again every cycle with its over-bent target moved along its
normal against the deviation (``--gain``, or from the second correction ``--secant`` over the plate's measured
response). Measures (``--measure``): ``plane`` as above; ``compare``: the formed plate compared with the design
as the loop compares a scan (:func:`compared_deviation`: rigid registration, along the normal; a plate the
comparison refuses ends the run with its error, as it ends the loop). ``cylinder39`` (``--plates``): the slow
loop test's 3.9 x 1.5 m cylinder of R 10 m in two sections. ``--yield-uncertainty PCT`` plans the first press
(and the aim's replans) for a plate PCT % weaker (``LoopSettings.yield_uncertainty_pct``: under-bent);
``--biaxial`` over-bends the two principal directions together
(``mppf.planning.sectional_overbend.biaxial_loaded``); ``--blend`` blends the learned sections' corrections where they overlap (``apply_section_corrections(blend=True)``).

Variants: ``--weightless`` takes the plate's own weight off, as if it were all carried beside the press;
``--start formed`` starts every later section's steps from the plate the sections before it formed
(:func:`mppf.planning.sectional.from_formed_plate`) instead of from flat. (Each section
refined on the plate model, measured and retired: ``benchmarks/results/2026-12-06-sectional-refined.md``.)

Resumable: every finished run is written at once to ``--results`` (JSON keyed by physics, plate, seed,
max cycles, grid and ``--label``); ``--budget-s`` (default 540) stops starting new runs after that long.
``--table`` prints the tables of the file only.

Run:  python benchmarks/bench_loop_sectional.py [--plates cylinder twisted kcs_stern real0010 real0008]
          [--physics steel] [--seeds 1] [--grid-mm 150] [--weightless] [--start flat|formed]
          [--label before]
          [--results FILE.json] [--table]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_loop import (
    NOMINAL,
    RMS_TOL_MM,
    THICKNESS_MM,
    TOL_MM,
    cycle_ended,
    load_results,
    physics_parts,
    save_results,
    series_text,
)

from mppf.core.errors import MppfError
from mppf.core.grid import without_plane
from mppf.core.transform import apply_tf
from mppf.geometry.read import read_points
from mppf.geometry.unfold import unfold
from mppf.geometry.write import write_points
from mppf.loop.section_steps import placement_mm
from mppf.model.press import example_press_path, load_press

ROOT = Path(__file__).resolve().parents[1]
LONG = ROOT / "mppf" / "examples" / "long"
REAL = ROOT / "benchmarks" / ".real-plates"
PLATES = {
    "cylinder": (LONG / "long_cylinder_7500x2400_R20m.csv", LONG / "long_cylinder_7500x2400_R20m_flat.csv"),
    "twisted": (LONG / "twisted_7500x2400.csv", LONG / "twisted_7500x2400_flat.csv"),
    "kcs_stern": (LONG / "kcs_stern_bilge_9000x2400.csv", None),
    "real0010": (REAL / "real0010.csv", None),
    "real0008": (REAL / "real0008.csv", None),
}
"""name: (design, flat or None: unfolded here)."""
GENERATED = {"cylinder39": (3900.0, 1500.0, 10000.0)}
"""name: an analytic cylinder (length, width, radius mm; :func:`mppf.examples.analytic.cylinder_plate`) with its
exact flat: the slow loop test's plate (``tests/loop/test_sectional_loop.py``)."""


def plate_files(name: str, work: Path):
    """(design, flat) point clouds of a bundled plate; the real ones written by ``real_plates`` when missing."""
    if name in GENERATED:
        from mppf.examples.analytic import cylinder_plate

        design, flat = cylinder_plate(*GENERATED[name], spacing_mm=100.0)
        return (read_points(write_points(work / f"{name}.csv", design)),
                read_points(write_points(work / f"{name}.flat.csv", flat)))
    design_path, flat_path = PLATES[name]
    if not design_path.exists() and design_path.parent == REAL:
        from real_plates import write_real_batch

        write_real_batch(REAL, 14)
    design = read_points(design_path)
    if flat_path is None:
        flat_path = write_points(work / f"{name}.flat.csv", unfold(design.points).flat)
    return design, read_points(flat_path)


class Planned:
    """A long plate planned in sections with the nominal material; the design as each section places it."""

    def __init__(self, press, name: str, work: Path, start: str = "flat"):
        from mppf.loop.plate import plan_first_cycle
        from mppf.loop.settings import LoopSettings
        from mppf.planning.sectional import from_formed_plate

        self.name = name
        self.design, self.flat = plate_files(name, work)
        t0 = time.process_time()
        self.job = plan_first_cycle(self.design, self.flat, press, THICKNESS_MM, material=NOMINAL,
                                    settings=LoopSettings(yield_uncertainty_pct=YIELD_UNCERTAINTY_PCT))
        if start == "formed" and self.job.sections is not None:  # later sections from the formed plate
            self.job = from_formed_plate(self.job)
        self.plan_cpu_s = time.process_time() - t0
        if self.job.sections is None:
            raise ValueError(f"{name} fits the bed: not a sectional plate")
        self.placed = [apply_tf(s.tf_press_design, self.design.points) for s in self.job.sections]


def make_plate(press, planned: Planned, physics: str, seed: int, grid_mm: float, true_yield_mpa: float):
    """The finite-difference steel plate of the whole plate as cut, in section 1's press frame."""
    from mppf.sim.plate.plate import SteelPlate

    steel, parts = physics_parts(physics, true_yield_mpa, len(planned.job.sections[0].steps))
    return SteelPlate(press, planned.job.layout.outline_mm, THICKNESS_MM, steel, seed=seed,
                      grid_spacing_mm=grid_mm, **parts)


MEASURE = "plane"
BLEND = False
YIELD_UNCERTAINTY_PCT = 0.0
"""How a cycle's deviation is measured (``--measure``): ``plane`` (:func:`true_deviation`) or ``compare``
(:func:`compared_deviation`)."""


def press_cycle(press, plate, job, weightless: bool = False) -> None:
    """Every section's steps in order, the plate shifted under the press for each.

    ``weightless``: the plate's own weight taken off (as if a crane or roller tables carried all of it): an
    experiment that isolates what the weight of the part beyond the bed does.
    """
    for s in job.sections:
        plate.place(placement_mm(job, s.index))
        if weightless:
            plate.model.weight_n[:] = 0.0
        for step in s.steps:
            upper, lower = step.setpoints_mm(press)
            plate.press_step(upper, lower, step.active)


def true_deviation(planned: Planned, formed) -> np.ndarray:
    """(n,) mm: the formed mid-surface minus the design (as section 1 places it), best plane removed."""
    p = planned.placed[0]
    dev = formed.height_mm(p[:, 0], p[:, 1]) - p[:, 2]
    return without_plane(p[:, 0], p[:, 1], dev)


def compared_deviation(planned: Planned, formed) -> np.ndarray:
    """(n,) mm at the design points: the formed plate compared with the design as the loop compares a scan
    (:func:`mppf.measure.compare.compare`: rigid registration, deviation along the design's normal), the formed
    mid-surface sampled at the design points' x, y in section 1's frame; interpolated onto the design points,
    signed + above the design in section 1's frame."""
    from mppf.core.kdtree import KDTree
    from mppf.measure.compare import compare

    p = planned.placed[0]
    z = formed.height_mm(p[:, 0], p[:, 1])
    ok = np.isfinite(z)
    tf1 = planned.job.sections[0].tf_press_design
    measured = apply_tf(np.linalg.inv(tf1), np.column_stack([p[ok, :2], z[ok]]))
    from mppf.measure.options import CompareOptions

    cmp = compare(planned.design.points, measured, CompareOptions(rotation_hint=np.eye(4)))
    dev = np.where(cmp.is_outlier, np.nan, cmp.deviation_mm)
    uv_d = cmp.design_uv_mm
    dist, idx = KDTree(cmp.measured_uv_mm).query(uv_d, k=4)
    w = 1.0 / np.maximum(dist, 1e-6)
    vals = dev[idx]
    w = np.where(np.isfinite(vals), w, 0.0)
    out = np.sum(w * np.nan_to_num(vals), axis=1) / np.maximum(np.sum(w, axis=1), 1e-12)
    normal_up = np.sign((tf1[:3, :3] @ cmp.design_frame.tf_world_local[:3, 2])[2])
    return out * cmp.normal_sign * normal_up


INNER_MM = 300.0
"""How far inside the net plate's edges :func:`inner_max` looks."""


def inner_max(planned: Planned, dev) -> float:
    """Largest |deviation| (mm) over the plate more than :data:`INNER_MM` inside its edges (as section 1 places
    it): the simulated plate's free corners and edges beyond the outer punches left out."""
    from mppf.core.polygon import convex_outline

    p = planned.placed[0]
    corners = convex_outline(p[:, :2], "the design")  # counter-clockwise
    edge = np.roll(corners, -1, axis=0) - corners
    inward = np.column_stack([-edge[:, 1], edge[:, 0]]) / np.linalg.norm(edge, axis=1)[:, None]
    depth = np.min(np.einsum("nkj,kj->nk", p[:, None, :2] - corners[None], inward), axis=1)
    inside = depth > INNER_MM
    return float(np.nanmax(np.abs(dev[inside]))) if inside.any() else float("nan")


def section_punch_deviations(press, planned: Planned, dev) -> list[np.ndarray]:
    """Per section, (rows, cols) mm: the deviation at its active punches, where the section places the design."""
    from scipy.interpolate import LinearNDInterpolator

    gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    out = []
    for s, p in zip(planned.job.sections, planned.placed):
        at = LinearNDInterpolator(p[:, :2], dev)(gx, gy)
        out.append(np.where(s.steps[-1].active, at, np.nan))
    return out


def border_kink(press, planned: Planned, dev) -> float:
    """Largest departure of the deviation from a straight line over one pitch across a section's bed edge, mm."""
    from scipy.interpolate import LinearNDInterpolator

    worst = 0.0
    for p in planned.placed:
        field = LinearNDInterpolator(p[:, :2], dev)
        lo, hi = p[:, :2].min(axis=0), p[:, :2].max(axis=0)
        for axis, axes in ((0, press.punch_x_mm), (1, press.punch_y_mm)):
            pitch = float(axes[1] - axes[0])
            other = press.punch_y_mm if axis == 0 else press.punch_x_mm
            for edge in (axes[0], axes[-1]):
                if not lo[axis] + pitch < edge < hi[axis] - pitch:
                    continue  # the plate ends here: no border
                pts = np.zeros((len(other), 3, 2))
                pts[:, :, 1 - axis] = other[:, None]
                pts[:, :, axis] = edge + pitch * np.array([-1.0, 0.0, 1.0])
                e = field(pts.reshape(-1, 2)).reshape(-1, 3)
                kink = np.abs(e[:, 1] - 0.5 * (e[:, 0] + e[:, 2]))
                if np.isfinite(kink).any():
                    worst = max(worst, float(np.nanmax(kink)))
    return worst


def section_shapes(press, job, devs) -> list:
    """Per section, (rows, cols) mm: its deviation at its active punches without its best plane (its pose)."""
    from mppf.loop.sectional import section_shapes as shapes

    return shapes(press, [s.steps[-1].active for s in job.sections], devs)


class LearnedSections:
    """The single plate's correction (:func:`mppf.correct.step.correct_step`) per section, with its memory."""

    def __init__(self, n_sections: int):
        self.memory = [{"cycles": [], "outcomes": [], "strokes": [], "promised": None} for _ in range(n_sections)]
        self.verdicts: list[str] = []

    def correct(self, press, planned: Planned, job, dev, form: tuple[float, float]):
        """The next cycle's job from the deviation ``dev`` at the design points (mm) and (form max, RMS); None
        when a section cannot go on (as the loop, :func:`mppf.loop.sectional.plan_next_sections`)."""
        from mppf.correct.inputs import CorrectedPlate, CorrectionHistory
        from mppf.correct.memory import PressedCycle
        from mppf.correct.step import Tolerances, correct_step, outcome
        from mppf.planning.sectional import apply_section_corrections

        errors = section_shapes(press, job, section_punch_deviations(press, planned, dev))
        deltas, before = [], len(self.verdicts)
        for s, error, mem in zip(job.sections, errors, self.memory):
            final = s.steps[-1]
            act = final.active
            mem["cycles"].append(PressedCycle([np.where(st.active, 0.5 * (st.upper_mm + st.lower_mm), np.nan)
                                               for st in s.steps], error))
            mem["outcomes"].append(outcome(form[0], form[1], error, mem["promised"]))
            mem["strokes"].append((final.upper_mm, final.lower_mm))
            # no edge deviation: the loop's comparison gives one for section 1's pose only (as the loop does)
            plate = CorrectedPlate(press, s.layout.design_mid_mm, THICKNESS_MM, NOMINAL, act)
            step = correct_step(plate, CorrectionHistory(mem["cycles"], mem["outcomes"], mem["strokes"]),
                                Tolerances(TOL_MM, RMS_TOL_MM))
            if step.verdict is not None or step.learned is None:
                self.verdicts.append(f"section {s.index}: {step.verdict.text[:100] if step.verdict else 'none'}")
                deltas.append((np.zeros(press.shape), np.zeros(press.shape)))
                continue
            mem["promised"] = step.learned.predicted_mm
            deltas.append((np.where(act, step.learned.upper_mm - final.upper_mm, 0.0),
                           np.where(act, step.learned.lower_mm - final.lower_mm, 0.0)))
        if len(self.verdicts) > before:
            return None  # a section cannot go on: the loop stops with its verdict
        return apply_section_corrections(job, deltas, blend=BLEND)


class AimedTarget:
    """The whole plate's over-bent target moved along its normal against the deviations measured so far.

    One correction field for the whole plate (:func:`mppf.planning.sectional.plan_sectional`'s
    ``target_offset_mm``): every cycle the plate is planned again with the target moved by
    ``-gain x deviation`` more (the deviation at the design points along their normal), so every section presses
    the same correction where sections meet. ``secant`` > 0: from the second correction on the step is
    ``secant / rho`` of the deviation, ``rho`` the plate's measured response to the target's moves (least squares
    of the deviation's changes on the offset's, one number, held to 0.2-5).
    """

    def __init__(self, planned: Planned, gain: float = 0.7, secant: float = 0.0):
        from mppf.geometry.surface import fit_plate

        self.gain, self.secant = gain, secant
        self.offset = np.zeros(len(planned.design.points))
        self.history, self.rho, self.rhos = [], 1.0, []
        self.verdicts: list[str] = []
        # the design normal's z in section 1's frame (its sense: the design fit's +z), to take a vertical
        # deviation along the normal
        fitted = fit_plate(planned.design.points, degree=4, kind="poly")
        uv = fitted.frame.to_local(planned.design.points)[:, :2]
        rot = planned.job.sections[0].tf_press_design[:3, :3] @ fitted.frame.tf_world_local[:3, :3]
        self.nz = (fitted.surface.normals(uv[:, 0], uv[:, 1]) @ rot.T)[:, 2]

    def correct(self, press, planned: Planned, job, dev, form):
        """The next cycle's job (None when it cannot be planned: the reason in ``verdicts``)."""
        from mppf.loop.settings import LoopSettings
        from mppf.model.plan_options import PlanOptions
        from mppf.planning.sectional import plan_sectional

        dev = np.nan_to_num(dev) * (self.nz if MEASURE == "plane" else np.sign(self.nz))  # along the normal
        if self.history:
            pairs = list(zip(self.history, self.history[1:] + [(self.offset, dev)]))
            num = sum(float(np.dot(e1 - e0, a1 - a0)) for (a0, e0), (a1, e1) in pairs)
            den = sum(float(np.dot(a1 - a0, a1 - a0)) for (a0, _), (a1, _) in pairs)
            self.rho = float(np.clip(num / den, 0.2, 5.0)) if den > 0 else self.rho
        self.rhos.append(round(self.rho, 3))
        self.history.append((self.offset.copy(), dev.copy()))
        step = self.gain if len(self.history) == 1 or self.secant == 0 else self.secant / self.rho
        self.offset = self.offset - step * dev
        settings = LoopSettings(yield_uncertainty_pct=YIELD_UNCERTAINTY_PCT)
        options = PlanOptions(material=NOMINAL, springback=True, yield_uncertainty_pct=settings.yield_uncertainty_pct,
                              margin_mm=settings.margin_mm)
        try:
            return plan_sectional(planned.design.points, planned.flat.points, press, THICKNESS_MM, options,
                                  target_offset_mm=self.offset)
        except MppfError as exc:
            self.verdicts.append(f"replan: {exc.message[:150]}")
            return None


def run_direct(press, planned: Planned, plate, max_cycles: int, weightless: bool = False,
               correction: str = "learned", gain: tuple = (0.7, 0.0)) -> dict:
    """Press, measure the true deviation, correct every section; up to ``max_cycles`` cycles."""
    job = planned.job
    row = {"max": [], "rms": [], "kink": [], "decisions": [], "ok_at": None, "verdict": None,
           "steps": [], "sections": len(job.sections), "plan_cpu_s": round(planned.plan_cpu_s, 2)}
    learned = {"learned": lambda: LearnedSections(len(job.sections)),
               "aim": lambda: AimedTarget(planned, *gain)}[correction]()
    for cycle in range(1, max_cycles + 1):
        press_cycle(press, plate, job, weightless)
        dev = (compared_deviation if MEASURE == "compare" else true_deviation)(planned, plate.formed)
        row["max"].append(float(np.nanmax(np.abs(dev)))), row["rms"].append(float(np.sqrt(np.nanmean(dev ** 2))))
        row["kink"].append(border_kink(press, planned, dev))
        row.setdefault("inner_max", []).append(inner_max(planned, dev))
        row["steps"].append([len(s.steps) for s in job.sections])
        if cycle_ended(row, cycle, max_cycles, row["max"][-1], row["rms"][-1]):
            break
        job = learned.correct(press, planned, job, dev, (row["max"][-1], row["rms"][-1]))
        row["verdict"] = "; ".join(learned.verdicts) or None
        if hasattr(learned, "rhos"):
            row["rho"] = learned.rhos
        row["decisions"].append("continue" if job is not None else "cannot_converge")
        if job is None:
            break
    return row


def report(results: dict) -> None:
    """One row per run: per cycle form max / RMS / border kink / form max 300 mm inside the edges."""
    print("\n| plate | physics | seed | label | sections | cycle: form max / RMS / border kink / max 300 mm inside "
          "the edges (mm) | in tol. at | s |")
    print("|---|---|---|---|---|---|---|---|")
    for key, r in sorted(results.items()):
        physics, name, seed, _, grid, how, label = key.split("|")
        inner = r.get("inner_max") or [float("nan")] * len(r["max"])
        cycles = ", ".join(f"{k}: {m:.1f} / {s:.2f} / {b:.2f} / {i:.1f}" for k, (m, s, b, i) in
                           enumerate(zip(r["max"], r["rms"], r["kink"], inner), start=1))
        end = r["decisions"][-1] if r["decisions"] else ""
        why = f" ({r['verdict'][:120]})" if r.get("verdict") else ""
        print(f"| {name} | {physics} (grid {grid}) | {seed} | {label}, {how} | {r.get('sections', '')} | {cycles} "
              f"| {r['ok_at'] or end}{why} | {r.get('seconds', '')} |")


def run_part(args, results: dict) -> bool:
    """Run what is not in ``results`` yet, until ``--budget-s``; True when everything asked for is done."""
    press = load_press(example_press_path())
    todo = [(ph, name, seed) for ph in args.physics for name in args.plates for seed in args.seeds
            if _key(ph, name, seed, args) not in results]
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="bench-sectional-") as tmp:
        planned = {}
        for physics, name, seed in todo:
            if time.monotonic() - started > args.budget_s:
                print(f"budget of {args.budget_s:.0f} s spent: call again with the same --results to go on")
                return False
            t0 = time.monotonic()
            try:
                planned.setdefault(name, Planned(press, name, Path(tmp), args.start))
                plate = make_plate(press, planned[name], physics, seed, args.grid_mm, args.true_yield)
                row = run_direct(press, planned[name], plate, args.max_cycles, args.weightless, args.correction,
                                 (args.gain, args.secant))
            except MppfError as exc:  # a failed run counts as not in tolerance
                row = {"max": [], "rms": [], "kink": [], "decisions": ["error"], "ok_at": None,
                       "verdict": f"{type(exc).__name__}: {exc.message[:200]}"}
            row["seconds"] = round(time.monotonic() - t0, 1)
            results[_key(physics, name, seed, args)] = row
            save_results(args.results, results)
            print(f"[{physics}] {name} seed {seed}: ok at {row['ok_at']} max {series_text(row['max'])} "
                  f"rms {series_text(row['rms'])} kink {series_text(row['kink'])} ({row['seconds']:.0f} s)"
                  + (f" {row['verdict']}" if row.get("verdict") else ""), flush=True)
    return True


def _key(physics: str, name: str, seed: int, args) -> str:
    physics = physics + ("-weightless" if args.weightless else "") + ("-formed" if args.start == "formed" else "") \
        + ("-compare" if args.measure == "compare" else "") + ("-blend" if args.blend else "") \
        + (f"-yu{args.yield_uncertainty:g}" if args.yield_uncertainty else "") + ("-biaxial" if args.biaxial else "")
    return f"{physics}|{name}|{seed}|{args.max_cycles}|{args.grid_mm:g}|{args.correction}|{args.label}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plates", nargs="+", default=list(PLATES), choices=list(PLATES) + list(GENERATED))
    parser.add_argument("--physics", nargs="+", default=["steel"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[1])
    parser.add_argument("--max-cycles", type=int, default=5)
    parser.add_argument("--grid-mm", type=float, default=150.0, help="cell size of the simulated plate's grid (mm)")
    parser.add_argument("--true-yield", type=float, default=265.0, help="the simulated steel's yield stress (MPa)")
    parser.add_argument("--start", choices=("flat", "formed"), default="flat",
                        help="where later sections' steps start: flat (as planned) or the formed plate "
                             "(mppf.planning.sectional.from_formed_plate)")
    parser.add_argument("--correction", choices=("learned", "aim"), default="learned",
                        help="learned: the loop's, per section; aim: the whole plate's target moved (AimedTarget)")
    parser.add_argument("--gain", type=float, default=0.7, help="aim: the share of the deviation corrected")
    parser.add_argument("--yield-uncertainty", type=float, default=0.0,
                        help="the first press planned for a plate this many %% weaker (under-bent): LoopSettings'")
    parser.add_argument("--biaxial", action="store_true",
                        help="over-bend the two principal directions together (mppf.planning.sectional_overbend.BIAXIAL)")
    parser.add_argument("--blend", action="store_true", help="learned: blend the sections' corrections where they "
                        "overlap (apply_section_corrections(blend=True))")
    parser.add_argument("--secant", type=float, default=0.0,
                        help="aim: from the second correction on, this share of the deviation over the plate's "
                             "measured response (0: --gain every cycle)")
    parser.add_argument("--weightless", action="store_true",
                        help="take the plate's own weight off (as if all of it were carried beside the press)")
    parser.add_argument("--label", default="now", help="names the code measured (e.g. before, after)")
    parser.add_argument("--results", type=Path, default=Path("bench_loop_sectional.json"))
    parser.add_argument("--budget-s", type=float, default=540.0, help="start no new run after this long (s)")
    parser.add_argument("--table", action="store_true", help="only print the tables of --results")
    parser.add_argument("--measure", choices=("plane", "compare"), default="plane",
                        help="the deviation: plane (formed minus design, best plane removed) or compare (as the loop "
                             "compares a scan: rigid registration, along the normal)")
    args = parser.parse_args(argv)
    global MEASURE, BLEND, YIELD_UNCERTAINTY_PCT
    MEASURE, BLEND, YIELD_UNCERTAINTY_PCT = args.measure, args.blend, args.yield_uncertainty
    if args.biaxial:
        import mppf.planning.sectional_overbend as overbend

        overbend.BIAXIAL = True
    threadpool_limits(1, "blas")
    results = load_results(args.results)
    done = True if args.table else run_part(args, results)
    report(results)
    ok = all(r["ok_at"] is not None and (r["kink"] or [0.0])[-1] <= TOL_MM for r in results.values())
    return 0 if (ok and done) else 1


if __name__ == "__main__":
    sys.exit(main())
