"""Benchmark: does the loop bring the bundled hull plates into tolerance on physics it has never seen?

For every plate physics x hull plate x seed: unfold the design, plan it with the NOMINAL
material (springback pre-compensation with the planner's own model), then press a simulated
plate that is not the planner's model, measure it, correct, and press again, for up to
``--max-cycles`` cycles. Targets (issue 40): in tolerance (form max <= 2.5 mm and RMS <= 1 mm)
within 3 cycles in >= 90 % of runs, within 5 cycles in all, mean <= 2.5 cycles, no run
diverged, no cycle more than 10 % worse (form max) than the best one before it.

Plate physics (``--physics``, each a name or ``effect:factor``):

- ``steel``: the steel plate of :mod:`mppf.sim.plate` with a true yield stress of
  ``--true-yield`` (265 MPa; the planner assumes 235) and its seeded scatter;
- ``yield:F``, ``hardening:F``, ``compliance:F``, ``anisotropy:F``, ``edge:F``,
  ``response:F``: the same plate with one effect off by the factor F
  (:class:`mppf.sim.plate.mismatch.Mismatch`; ``response`` scales the whole plate's answer);
- ``fe``: the finite-element plate (:class:`mppf.sim.fe.plate.FEPlate`, CalculiX; in
  ``--mode loop`` ``plate_model="fe"`` of :mod:`mppf.sim.shop`), when ``mppf.sim.fe`` exists,
  with the true yield stress and its own seeded scatter.

Two ways to run a plate:

- ``--mode direct`` (default): the loop's correction (:func:`mppf.correct.step.correct_step`, what
  :mod:`mppf.loop.correcting` calls) on the plate in process, on the TRUE deviation (the
  formed mid-surface against the design over the net plate, best plane removed; at the
  punches and at the net edge for the correction). No scanner, no registration.
- ``--mode loop``: :func:`mppf.loop.cycle.run_loop` with the in-process press and the
  simulated scanner (:class:`mppf.sim.shop.SimulatedPlateScanner`): scans, registration,
  comparison, rescans, the history and the loop's own decisions.

Resumable parts: every finished run is written at once to ``--results`` (JSON, keyed by
physics, plate, seed, mode and max cycles); a later call with the same file skips what is
there. ``--budget-s`` (default 540) stops starting new runs after that long, so each part
ends within about 10 minutes: no cycle is started that is expected to end past the budget (its run's
last cycle times ``CYCLE_GROWTH``, or the longest first cycle of its physics in the file); a direct-mode
run that is not finished is pickled to ``--checkpoints`` and goes on from its next cycle in the next
call (an FE run takes 10-40 minutes). Call again to go on. A run that fails (an exception, the FE
solver not converging) is kept as failed with its reason and the cycles it measured (decision
``error``); it is not run again. ``--table`` prints the tables of the file only.

Run:  python benchmarks/bench_loop.py [--physics steel yield:1.2 ...] [--sweep] [--seeds 1 2 3]
          [--plates P1_midbody_bilge_smooth ...] [--mode direct|loop] [--results FILE.json]
          [--budget-s 540] [--table]
          [--yield-uncertainty PCT]  (the first press under-bent: issue 40)
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import sys
import tempfile
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from mppf.core.errors import MppfError
from mppf.core.grid import without_plane
from mppf.core.transform import apply_tf
from mppf.correct.learned import steps_towards
from mppf.correct.memory import PressedCycle
from mppf.correct.policy import outer_ring, step_plan
from mppf.correct.inputs import CorrectedPlate, CorrectionHistory
from mppf.correct.step import Tolerances, correct_step, outcome
from mppf.forming.precompensate import deviation
from mppf.geometry.read import read_points
from mppf.geometry.unfold import unfold
from mppf.geometry.write import write_points
from mppf.measure.punches import edge_deviations
from mppf.model.material import Material
from mppf.model.press import example_press_path, load_press

HULL = Path(__file__).resolve().parents[1] / "mppf" / "examples" / "hull"
PLATES = ["P1_midbody_bilge_smooth", "P2_bow_flare_smooth", "P3_stern_saddle_smooth",
          "K1_midbody_bilge", "K2_fwd_bilge_convex", "K3_stern_saddle"]
THICKNESS_MM = 20.0
NOMINAL = Material()  # what the planner and the correction assume (235 MPa)
TRUE_YIELD_MPA = 265.0  # the mill's steel: harder than nominal (plus the simulator's scatter)
TOL_MM, RMS_TOL_MM = 2.5, 1.0
WORSE_SHARE = 0.10  # a cycle whose form max is more than this share above the best before it counts as worse

SWEEP = ["yield:0.85", "yield:1.2", "hardening:0.3", "hardening:3", "compliance:0.3", "compliance:3",
         "anisotropy:0", "anisotropy:3", "edge:0.5", "edge:2", "response:0.3", "response:0.5", "response:2",
         "response:3"]
"""The model-mismatch sweep: each effect off by a factor."""


def physics_parts(physics: str, true_yield_mpa: float, first_steps: int):
    """(steel, {"scatter", "compliance", mismatch options}) of the simulated steel plate of ``physics``.

    ``response:F`` scales the plate's answer after the first cycle's ``first_steps`` steps: the first press is
    as modelled, every correction moves the plate F times what the model predicts.
    """
    from mppf.sim.plate.contact import Compliance
    from mppf.sim.plate.material import PlateSteel
    from mppf.sim.plate.mismatch import Mismatch, mismatched_parts
    from mppf.sim.plate.scatter import Scatter

    steel = PlateSteel.from_material(replace(NOMINAL, yield_stress_mpa=true_yield_mpa))
    mismatch = Mismatch()
    if physics != "steel":
        name, _, factor = physics.partition(":")
        mismatch = Mismatch.named(name, float(factor), response_after_steps=first_steps)
    steel, compliance, options = mismatched_parts(steel, Compliance(), mismatch)
    return steel, {"scatter": Scatter(), "compliance": compliance, **options}


def direct_plate(press, planned, physics: str, seed: int, true_yield_mpa: float):
    """The simulated plate of a direct-mode run: the finite-difference steel plate, or the FE plate ("fe")."""
    if physics == "fe":
        from mppf.sim.fe.plate import FEPlate
        from mppf.sim.plate.material import PlateSteel

        steel = PlateSteel.from_material(replace(NOMINAL, yield_stress_mpa=true_yield_mpa))
        return FEPlate(press, planned.job.layout.outline_mm, THICKNESS_MM, steel, seed=seed)
    from mppf.sim.plate.plate import SteelPlate

    steel, parts = physics_parts(physics, true_yield_mpa, len(planned.job.steps))
    return SteelPlate(press, planned.job.layout.outline_mm, THICKNESS_MM, steel, seed=seed, **parts)


class Planned:
    """One hull plate planned with the nominal material, and the design in press coordinates."""

    def __init__(self, press, name: str, work: Path, uncertainty_pct: float | None = None):
        from mppf.loop.plate import plan_first_cycle
        from mppf.loop.settings import LoopSettings

        design = read_points(HULL / f"{name}.csv")
        flat = read_points(write_points(work / f"{name}.flat.csv", unfold(design.points).flat))
        self.name = name
        settings = LoopSettings() if uncertainty_pct is None else LoopSettings(yield_uncertainty_pct=uncertainty_pct)
        self.job = plan_first_cycle(design, flat, press, THICKNESS_MM, material=NOMINAL, settings=settings)
        self.design_press = apply_tf(self.job.tf_press_design, design.points)
        self.design_path, self.flat = HULL / f"{name}.csv", flat


def true_deviation(press, formed, planned: Planned, active):
    """(form max, RMS) over the net plate, the deviation at the punches and at the edge beyond the outer rows."""
    p = planned.design_press
    dev = formed.height_mm(p[:, 0], p[:, 1]) - p[:, 2]
    dev = without_plane(p[:, 0], p[:, 1], dev)
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    punch = deviation(press, formed.height_mm(px, py), planned.job.layout.design_mid_mm, active)
    edge = edge_deviations(press.punch_x_mm, press.punch_y_mm, active, p[:, :2], dev)
    return float(np.nanmax(np.abs(dev))), float(np.sqrt(np.nanmean(dev**2))), punch, edge


def cycle_ended(row: dict, cycle: int, max_cycles: int, form_max_mm: float, rms_mm: float) -> bool:
    """Whether the run ends after ``cycle``: in tolerance (``row["ok_at"]`` set) or at the cycle limit; the
    decision is appended to ``row["decisions"]``."""
    if form_max_mm <= TOL_MM and rms_mm <= RMS_TOL_MM:
        row["decisions"].append("in_tolerance")
        row["ok_at"] = cycle
        return True
    if cycle == max_cycles:
        row["decisions"].append("max_cycles")
        return True
    return False


def new_row() -> dict:
    """An empty run: per cycle form max, RMS and decision (mm); filled while the run goes, kept if it fails."""
    return {"max": [], "rms": [], "decisions": [], "ok_at": None, "verdict": None, "share": [],
            "punch_rms": [], "promised_rms": [], "stroke_change_rms": [], "cycle_s": []}


@dataclass(eq=False)
class DirectRun:
    """A direct-mode run between two cycles: the plate, the next cycle's steps and what was measured.

    Pickled to a checkpoint file when a part's time is up, so that a run longer than a part goes
    on in the next part (the FE plate's runs take 10-40 minutes).
    """

    plate: object
    steps: list
    final: object
    row: dict
    cycles: list = field(default_factory=list)
    outcomes: list = field(default_factory=list)
    strokes: list = field(default_factory=list)
    promised: object = None


def run_direct(press, planned: Planned, plate, max_cycles: int, policy: bool = True, row: dict | None = None) -> dict:
    """The loop's correction (:func:`mppf.correct.step.correct_step`) on the plate in process, true deviations.

    ``policy=False``: without the step policy (every step at scale 1 from the last strokes), to measure what it
    does. ``row`` (:func:`new_row`) is filled cycle by cycle, so a run that fails keeps the cycles it measured.
    """
    run = DirectRun(plate, planned.job.steps, planned.job.steps[-1], new_row() if row is None else row)
    return continue_direct(press, planned, run, max_cycles, policy)


def continue_direct(press, planned: Planned, run: DirectRun, max_cycles: int, policy: bool = True,
                    pause=None) -> dict | None:
    """Press, measure and correct ``run`` from its next cycle on; the row, or None when ``pause`` stopped it.

    ``pause(run) -> bool`` is asked before every cycle; True stops the run there (the caller keeps ``run``).
    Besides form max and RMS the row keeps, per cycle, the RMS deviation at the punches (``punch_rms``, mm) and
    the wall time (``cycle_s``, s), per correction the RMS deviation it promised there (``promised_rms``), the
    RMS change of the final step's mid strokes it asked (``stroke_change_rms``, mm) and the plate's measured
    response to each correction (``response`` inside the outer punches, ``edge_response`` at them: measured
    over promised change, :func:`mppf.correct.policy.step_plan`).
    """
    job, row = planned.job, run.row
    active = job.steps[-1].active
    tolerances = Tolerances(TOL_MM, RMS_TOL_MM)
    for cycle in range(len(row["max"]) + 1, max_cycles + 1):
        if pause is not None and pause(run):
            return None
        t0 = time.monotonic()
        for s in run.steps:  # press the cycle's steps, measure the plate
            upper, lower = s.setpoints_mm(press)
            run.plate.press_step(upper, lower, s.active)
        form_max, rms, punch, edge = true_deviation(press, run.plate.formed, planned, active)
        row["max"].append(form_max), row["rms"].append(rms)
        row["punch_rms"].append(round(float(np.sqrt(np.nanmean(np.where(active, punch, np.nan) ** 2))), 3))
        run.cycles.append(PressedCycle([np.where(s.active, 0.5 * (s.upper_mm + s.lower_mm), np.nan)
                                        for s in run.steps], punch))
        run.outcomes.append(outcome(form_max, rms, punch, run.promised))
        run.strokes.append((run.final.upper_mm, run.final.lower_mm))
        row["response"], row["edge_response"] = _responses(run.outcomes, active)
        ended = cycle_ended(row, cycle, max_cycles, form_max, rms) or _correct(press, job, run, edge, tolerances, policy)
        row["cycle_s"].append(round(time.monotonic() - t0, 1))
        if ended:
            break
    return row


def _correct(press, job, run: DirectRun, edge_mm, tolerances: Tolerances, policy: bool) -> bool:
    """The correction after a measured cycle, into ``run``'s next steps; True when its verdict ends the run."""
    row, active = run.row, job.steps[-1].active
    plate = CorrectedPlate(press, job.layout.design_mid_mm, THICKNESS_MM, NOMINAL, active)
    step = correct_step(plate, CorrectionHistory(run.cycles, run.outcomes, run.strokes, edge_mm), tolerances,
                        policy=policy)
    row["share"].append(round(step.plan.share, 3))
    if step.verdict is not None:
        row["decisions"].append("cannot_converge")
        row["verdict"] = step.verdict.text
        return True
    row["decisions"].append("continue")
    run.promised = step.learned.predicted_mm
    row["promised_rms"].append(round(float(np.sqrt(np.nanmean(np.where(active, run.promised, np.nan) ** 2))), 3))
    run.steps = steps_towards(press, run.steps[-1].setpoints_mm(press), step.learned, active)
    new = run.steps[-1]
    change = 0.5 * (new.upper_mm + new.lower_mm - run.final.upper_mm - run.final.lower_mm)
    row["stroke_change_rms"].append(round(float(np.sqrt(np.nanmean(change[active] ** 2))), 2))
    run.final = new
    return False


def _responses(outcomes, active) -> tuple[list, list]:
    """The plate's measured response to each correction so far, inside and at the outer punches (rounded)."""
    plan = step_plan(outcomes, outer_ring(active), TOL_MM, RMS_TOL_MM)
    return [round(r, 3) for r in plan.ratios], [round(r, 3) for r in plan.edge_ratios]


def run_loop_mode(press, planned: Planned, seed: int, max_cycles: int, true_yield_mpa: float, work: Path,
                  physics: str) -> dict:
    """:func:`mppf.loop.cycle.run_loop` on the in-process press with the simulated scanner."""
    from mppf.loop.cycle import run_loop
    from mppf.loop.history import History
    from mppf.loop.options import LoopOptions, PlateInputs
    from mppf.loop.plate import record_plate
    from mppf.loop.settings import LoopSettings
    from mppf.planning.job import load_job
    from mppf.sim.plc.link import InProcessPress
    from mppf.sim.shop import SimulatedPlateScanner

    design = read_points(planned.design_path)
    plate_id = f"{planned.name}-{physics.replace(':', '-')}-s{seed}"
    with History(work / "history.sqlite") as history:
        record_plate(history, PlateInputs(design, planned.flat, press, THICKNESS_MM), planned.job, plate_id=plate_id,
                     work_dir=work / plate_id, options=LoopOptions(settings=LoopSettings(max_cycles=max_cycles)))
        job = load_job(history.cycle(plate_id, 1).job_path)
        if physics == "fe":
            options = {"plate_model": "fe", "material": replace(NOMINAL, yield_stress_mpa=true_yield_mpa)}
        else:
            steel, parts = physics_parts(physics, true_yield_mpa, len(planned.job.steps))
            options = {"steel": steel, "plate_options": parts}
        scanner = SimulatedPlateScanner.for_job(press, THICKNESS_MM, job, planned.flat.points, seed=seed, **options)
        with InProcessPress(press) as link:
            result = run_loop(history, plate_id, link, scanner)
    cycles = result.cycles
    return {"max": [c.max_abs_mm for c in cycles], "rms": [c.rms_mm for c in cycles],
            "decisions": [str(c.decision) for c in cycles], "verdict": result.verdict,
            "ok_at": next((c.cycle for c in cycles if c.decision == "in_tolerance"), None)}


def worse_cycles(maxima) -> int:
    """Cycles whose form max is more than :data:`WORSE_SHARE` above the best one before them."""
    return sum(1 for k in range(1, len(maxima)) if maxima[k] > (1.0 + WORSE_SHARE) * min(maxima[:k]))


def series_text(values) -> str:
    return " ".join(f"{v:5.2f}" for v in values)


def summary(rows: list[dict]) -> dict:
    """within 3 / within 5 / mean cycles / diverged / worse cycles of some runs."""
    ok = [r["ok_at"] for r in rows if r["ok_at"] is not None]
    return {"n": len(rows), "within3": sum(1 for v in ok if v <= 3), "within5": sum(1 for v in ok if v <= 5),
            "mean": float(np.mean(ok)) if ok else float("nan"),
            "diverged": sum(1 for r in rows if "diverged" in r["decisions"]),
            "worse": sum(worse_cycles(r["max"]) for r in rows), "cycles": sum(len(r["max"]) for r in rows)}


def report(results: dict, mode: str) -> list[tuple[str, dict]]:
    """Print the per-plate tables and the summary table of every physics in ``results``; return the summaries."""
    by_physics: dict[str, list[dict]] = {}
    for key, row in results.items():
        physics, name, seed, run_mode, _ = key.split("|")
        if run_mode == mode:
            by_physics.setdefault(physics, []).append({"plate": name, "seed": int(seed), **row})
    summaries = []
    for physics, rows in by_physics.items():
        rows.sort(key=lambda r: (PLATES.index(r["plate"]) if r["plate"] in PLATES else 99, r["seed"]))
        print(f"\n## {physics} ({mode})\n")
        for r in rows:
            print(f"{r['plate']:26s} {r['seed']:3d} ok at {str(r['ok_at']):>4s}  max {series_text(r['max']):32s} "
                  f"rms {series_text(r['rms']):32s} {r['decisions'][-1] if r['decisions'] else ''}")
            if r.get("verdict"):
                print(f"{'':36s}verdict: {r['verdict'][:200]}")
        summaries.append((physics, summary(rows)))
    print(f"\n## summary ({mode})\n")
    print("| physics | runs | within 3 | within 5 | mean cycles | diverged | cycles > 10 % worse than best |")
    print("|---|---|---|---|---|---|---|")
    total = summary([{"plate": "", "seed": 0, **r} for k, r in results.items() if k.split("|")[3] == mode])
    for physics, s in summaries + [("all", total)]:
        print(f"| {physics} | {s['n']} | {s['within3']} ({100 * s['within3'] / max(s['n'], 1):.0f} %) | "
              f"{s['within5']} ({100 * s['within5'] / max(s['n'], 1):.0f} %) | {s['mean']:.2f} | {s['diverged']} | "
              f"{s['worse']} of {s['cycles']} |")
    return summaries + [("all", total)]


def load_results(path: Path) -> dict:
    return json.loads(path.read_text()) if path.exists() else {}


def save_results(path: Path, results: dict) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(results, indent=1))
    os.replace(tmp, path)


CYCLE_GROWTH = 1.4
"""The next cycle of a run is expected to take up to this many times its last one (the FE plate replays every
earlier press step: its n-th step costs about n single steps)."""


def first_cycle_s(results: dict, physics: str, mode: str) -> float:
    """Wall time of the longest first cycle of ``physics`` in ``mode`` in ``results`` (s; 0 if none)."""
    times = [row["cycle_s"][0] for key, row in results.items()
             if key.split("|")[0] == physics and key.split("|")[3] == mode and row.get("cycle_s")]
    return float(max(times, default=0.0))


def run_part(args, results: dict, path: Path) -> bool:
    """Run what is not in ``results`` yet, until ``--budget-s``; True when everything asked for is done."""
    press = load_press(example_press_path())
    physics_list = list(args.physics) + (SWEEP if args.sweep else [])
    todo = [(ph, name, seed) for ph in physics_list for name in args.plates for seed in args.seeds
            if f"{ph}|{name}|{seed}|{args.mode}|{args.max_cycles}" not in results]
    if any(ph == "fe" for ph, _, _ in todo):
        try:
            import mppf.sim.fe  # noqa: F401
        except ImportError:
            print("note: mppf.sim.fe is not there: the 'fe' physics is left out", flush=True)
            todo = [t for t in todo if t[0] != "fe"]
    deadline, part = time.monotonic() + args.budget_s, {"asked": 0}
    checkpoints = args.checkpoints or Path(tempfile.gettempdir()) / f"bench-loop-{path.stem}"
    with tempfile.TemporaryDirectory(prefix="bench-loop-") as tmp:
        work, planned = Path(tmp), {}
        for physics, name, seed in todo:
            key = f"{physics}|{name}|{seed}|{args.mode}|{args.max_cycles}"
            t0, ckpt = time.monotonic(), checkpoints / (key.replace("|", "_").replace(":", "-") + ".pickle")
            run, row = None, new_row()
            try:
                if name not in planned:
                    planned[name] = Planned(press, name, work, args.yield_uncertainty)
                if args.mode == "loop":
                    row = run_loop_mode(press, planned[name], seed, args.max_cycles, args.true_yield, work, physics)
                else:
                    run = (pickle.loads(ckpt.read_bytes()) if ckpt.exists() else
                           DirectRun(direct_plate(press, planned[name], physics, seed, args.true_yield),
                                     planned[name].job.steps, planned[name].job.steps[-1], row))
                    row = run.row
                    pause = _pauser(deadline, first_cycle_s(results, physics, args.mode), ckpt, (t0, part))
                    if continue_direct(press, planned[name], run, args.max_cycles, not args.no_policy, pause) is None:
                        print(f"budget of {args.budget_s:.0f} s: {key} paused after cycle {len(row['max'])} "
                              f"(kept in {ckpt}); call again with the same --results to go on", flush=True)
                        return False
            except Exception as exc:  # noqa: BLE001 - a failed run is kept as failed with its reason, never dropped
                text = exc.message if isinstance(exc, MppfError) else str(exc)
                row["decisions"].append("error")
                row["ok_at"], row["verdict"] = None, f"{type(exc).__name__}: {text[:300]}"
            row["seconds"] = round(row.get("seconds", 0.0) + time.monotonic() - t0, 1)
            results[key] = row
            save_results(path, results)
            ckpt.unlink(missing_ok=True)
            print(f"[{physics}] {name} seed {seed}: ok at {row['ok_at']} max {series_text(row['max'])} "
                  f"rms {series_text(row['rms'])} ({row['seconds']:.0f} s)", flush=True)
    return True


def _pauser(deadline: float, first_s: float, ckpt: Path, started):
    """``pause(run)`` for :func:`continue_direct`: True (the run pickled to ``ckpt``) when its next cycle
    (:data:`CYCLE_GROWTH` times its last one, or ``first_s`` for a first cycle) would end past ``deadline``.

    ``started`` is (when the run started in this part, {"asked": cycles asked so far in the part}): the part's
    first cycle is always pressed, so that every part goes on."""
    t0, part = started

    def pause(run: DirectRun) -> bool:
        cycle_s = run.row["cycle_s"]
        expected_s = CYCLE_GROWTH * cycle_s[-1] if cycle_s else first_s
        part["asked"] += 1
        if part["asked"] == 1 or time.monotonic() + expected_s <= deadline:
            return False
        run.row["seconds"] = round(run.row.get("seconds", 0.0) + time.monotonic() - t0, 1)
        ckpt.parent.mkdir(parents=True, exist_ok=True)
        tmp = ckpt.with_suffix(".tmp")
        tmp.write_bytes(pickle.dumps(run))
        os.replace(tmp, ckpt)
        return True
    return pause


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--physics", nargs="+", default=["steel"])
    parser.add_argument("--sweep", action="store_true", help="add the model-mismatch sweep (SWEEP) to --physics")
    parser.add_argument("--plates", nargs="+", default=PLATES)
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    parser.add_argument("--max-cycles", type=int, default=5)
    parser.add_argument("--true-yield", type=float, default=TRUE_YIELD_MPA,
                        help="nominal yield stress of the simulated plate's steel (MPa; the planner assumes 235)")
    parser.add_argument("--mode", choices=("direct", "loop"), default="direct")
    parser.add_argument("--results", type=Path, default=Path("bench_loop_results.json"),
                        help="JSON file the runs are kept in (resumed from)")
    parser.add_argument("--budget-s", type=float, default=540.0,
                        help="end the part within about this long (s): a cycle expected to end past it is not "
                             "started; a direct-mode run is paused to a checkpoint and goes on in the next call")
    parser.add_argument("--checkpoints", type=Path, default=None,
                        help="folder of the paused runs (default: <tmp>/bench-loop-<results name>)")
    parser.add_argument("--no-policy", action="store_true",
                        help="direct mode: every correction at full size from the last strokes (the step policy off)")
    parser.add_argument("--table", action="store_true", help="only print the tables of --results")
    parser.add_argument("--yield-uncertainty", type=float, default=None,
                        help="the first press planned for yield x (1 - PCT/100) (default: the loop's default; "
                             "benchmarks/results/2026-12-06-loop-first-press.md)")
    args = parser.parse_args(argv)
    threadpool_limits(1, "blas")
    results = load_results(args.results)
    done = True if args.table else run_part(args, results, args.results)
    summaries = report(results, args.mode)
    total = summaries[-1][1]
    ok = total["n"] and total["within3"] >= 0.9 * total["n"] and total["within5"] == total["n"]
    return 0 if (ok and done) else 1


if __name__ == "__main__":
    sys.exit(main())
