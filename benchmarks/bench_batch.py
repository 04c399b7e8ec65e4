"""Batch planning of N generated hull plates: wall time, per-plate time and memory.

Generates N plates (seeded) as design files with a manifest: cylinders bent along or across,
twisted plates and saddles (z = a x^2 + b y^2 + c x y), 2.5-9 m long and 1.6-2.4 m wide, so that
about half fit the example press's bed (3.45 x 2.25 m) and the rest are planned in sections. Then
:func:`mppf.planning.batch.run_batch` unfolds and plans them (a process pool on every core, as
``mppf batch``) and prints a table per kind (plates, sections, per-plate time, worker peak memory)
and the extrapolated wall time of 1000 plates. A second run over the same folder shows the resume
(every plate skipped).

With ``--real N`` it plans N real hull plates instead (:mod:`real_plates`: cut from the KCS hull IGES
and the bundled hull data, cached in ``benchmarks/.real-plates/``) in resumable parts: each run plans
parts of ``--part`` plates until ``--budget-min`` minutes are spent, keeps every row, the parts' wall
times, the machine's load and each run's wall and CPU (pool start and imports included) in
``.real-plates/<tag>.json``, and prints the table over all plates planned so far and the total wall
and CPU of the runs; run it again to go on.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_batch.py [--plates 60] [--workers 2] [--spacing 100]
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_batch.py --real 1000 [--part 100] [--budget-min 9] [--tag after]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from mppf.core.transform import apply_tf
from mppf.examples.analytic import hull_pose
from mppf.geometry.write import write_points
from mppf.model.press import example_press_path
from mppf.planning.batch import BatchOptions, planning_pool, read_manifest, run_batch


def generated_plate(rng, spacing_mm: float):
    """(kind, design points): one random hull-like plate in a random hull pose."""
    length = rng.uniform(2500.0, 9000.0)
    width = rng.uniform(1600.0, 2400.0)
    nx, ny = int(length // spacing_mm) + 1, int(width // spacing_mm) + 1
    x, y = np.meshgrid(np.linspace(-length / 2, length / 2, nx), np.linspace(-width / 2, width / 2, ny))
    x, y = x.ravel(), y.ravel()
    kind = rng.choice(["cylinder", "twisted", "saddle"])
    if kind == "cylinder":  # bent across (a bilge) or along, radius 4-30 m
        radius = rng.uniform(4000.0, 30000.0) if rng.random() < 0.5 else rng.uniform(15000.0, 40000.0)
        s = y if radius < 15000.0 else x
        z = radius - np.sqrt(radius ** 2 - s ** 2)
    elif kind == "twisted":
        z = 4.0 * rng.uniform(20.0, 80.0) * x * y / (length * width)
    else:
        a, b = rng.uniform(-1.0, 1.0, 2) / 40000.0
        z = a * x ** 2 + b * y ** 2
    tf = hull_pose(rng.uniform(0.0, 90.0), rng.uniform(-50000.0, 50000.0, 3))
    return str(kind), apply_tf(tf, np.column_stack([x, y, z])), (length, width)


def write_batch(folder: Path, n: int, spacing_mm: float, seed: int = 18) -> tuple[Path, dict]:
    """Design files and a manifest of n plates; their kinds by name."""
    rng = np.random.default_rng(seed)
    lines, kinds = ["name,design,thickness_mm,material"], {}
    for k in range(n):
        kind, points, _ = generated_plate(rng, spacing_mm)
        name = f"plate{k:04d}"
        write_points(folder / f"{name}.csv", points)
        lines.append(f"{name},{name}.csv,{rng.choice([12, 16, 20, 25])},steel")
        kinds[name] = kind
    manifest = folder / "plates.csv"
    manifest.write_text("\n".join(lines) + "\n")
    return manifest, kinds


def table(rows: list[dict], kinds: dict, wall_s: float, workers: int) -> str:
    """The benchmark table (text)."""
    out = [(f"{'group':<14} {'plates':>6} {'failed':>6} {'sections':>8} {'wall s/plate med':>16} {'max':>6} "
            f"{'CPU s/plate med':>15} {'max':>6} {'peak RSS MB':>11}")]
    groups = {"all": rows, "one piece": [r for r in rows if r.get("sections") == 1],
              "in sections": [r for r in rows if (r.get("sections") or 0) > 1]}
    for kind in sorted(set(kinds.values())):
        groups[kind] = [r for r in rows if kinds[r["plate"]] == kind]
    for name, group in groups.items():
        ok = [r for r in group if r["status"] == "planned"]
        times = [r["time_s"] for r in ok] or [0.0]
        cpu = [r["cpu_s"] for r in ok] or [0.0]
        rss = max((r.get("peak_rss_mb") or 0.0 for r in ok), default=0.0)
        out.append(f"{name:<14} {len(group):>6} {len(group) - len(ok):>6} "
                   f"{sum(r.get('sections') or 0 for r in ok):>8} "
                   f"{statistics.median(times):>16.2f} {max(times):>6.2f} "
                   f"{statistics.median(cpu):>15.2f} {max(cpu):>6.2f} {rss:>11.0f}")
    n = max(len(rows), 1)
    per_plate = wall_s / n
    cpu_total = sum(r.get("cpu_s") or 0.0 for r in rows)
    out.append(f"wall {wall_s:.1f} s for {len(rows)} plates on {workers} worker(s): {per_plate:.3f} s per plate; "
               f"1000 plates would take about {1000 * per_plate / 60:.1f} min at this machine's load")
    out.append(f"CPU {cpu_total:.1f} s in the workers ({cpu_total / n:.3f} s per plate): 1000 plates on {workers} "
               f"idle core(s) would take about {1000 * cpu_total / n / workers / 60:.1f} min")
    return "\n".join(out)


REAL_CACHE = Path(__file__).resolve().parent / ".real-plates"


def run_real(n: int, workers: int, part: int, budget_min: float, tag: str) -> None:
    """Plan n real hull plates in parts until the budget is spent; rows, parts and runs kept in <tag>.json.

    The parts of one run share one pool (:func:`planning_pool`): its workers start and import once,
    as in one ``mppf batch`` of every plate. The run's CPU (the workers' from their start, imports
    included, and this process's) is counted when the pool has stopped.
    """
    from real_plates import write_real_batch

    manifest, kinds = write_real_batch(REAL_CACHE, n)
    plates = read_manifest(manifest)
    state_path = REAL_CACHE / f"{tag}.json"
    state = json.loads(state_path.read_text()) if state_path.exists() else {"rows": {}, "parts": []}
    options = BatchOptions(press_path=str(example_press_path()), out_dir=str(REAL_CACHE / f"jobs-{tag}"),
                           workers=workers)
    todo = [p for p in plates if p.name not in state["rows"]]
    started, cpu_started, load_started, planned = time.perf_counter(), _children_cpu_s(), os.getloadavg()[0], 0
    with planning_pool(workers) as pool:
        while todo and time.perf_counter() - started < budget_min * 60.0:
            chunk, todo = todo[:part], todo[part:]
            load_before, t0 = os.getloadavg()[0], time.perf_counter()
            rows = run_batch(chunk, options, pool=pool)
            wall = time.perf_counter() - t0
            state["parts"].append({"plates": len(chunk), "wall_s": round(wall, 2), "workers": workers,
                                   "task_cpu_s": round(sum(r.get("cpu_s") or 0.0 for r in rows), 2),
                                   "load_before": round(load_before, 2), "load_after": round(os.getloadavg()[0], 2)})
            # a plate whose job an interrupted part finished is skipped by the batch: kept as planned, marked
            state["rows"].update({r["plate"]: ({**r, "status": "planned", "resumed": True}
                                               if r["status"] == "skipped" else r) for r in rows})
            planned += len(chunk)
            state_path.write_text(json.dumps(state, indent=1))
            print(f"part {len(state['parts'])}: {len(chunk)} plates in {wall:.1f} s, load {load_before:.1f} -> "
                  f"{os.getloadavg()[0]:.1f}; {len(state['rows'])} of {n} done", flush=True)
    if planned:
        state.setdefault("runs", []).append({
            "plates": planned, "wall_s": round(time.perf_counter() - started, 2), "workers": workers,
            "cpu_s": round(_children_cpu_s() - cpu_started, 2), "load_before": round(load_started, 2),
            "load_after": round(os.getloadavg()[0], 2)})
        state_path.write_text(json.dumps(state, indent=1))
    real_report(state, kinds, workers, n)


def _children_cpu_s() -> float:
    """CPU seconds of this process's finished children (the pool's workers) and of itself."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def real_report(state: dict, kinds: dict, workers: int, n: int) -> None:
    """The table over every real plate planned so far, the parts' rate and load, the runs' wall and CPU."""
    rows = [r for name, r in state["rows"].items() if name in kinds]
    wall = sum(p["wall_s"] for p in state["parts"])
    print(table(rows, kinds, wall, workers))
    for row in rows:
        if row["status"] == "failed":
            print(f"  failed {row['plate']} ({kinds[row['plate']]}): {row['reason'][:150]}")
    loads = [x for p in state["parts"] for x in (p["load_before"], p["load_after"])]
    resumed = sum(bool(r.get("resumed")) for r in rows)
    if resumed:
        print(f"{resumed} plate(s) planned in an interrupted part (their CPU counted, their wall time not)")
    if state["parts"]:
        print(f"{len(rows)} of {n} plates in {len(state['parts'])} part(s): {len(rows) / max(wall, 1e-9):.2f} plates/s "
              f"wall; machine load (1-min average) {min(loads):.1f}-{max(loads):.1f} during the parts")
    runs = state.get("runs", [])
    if runs:
        run_wall, run_cpu = sum(r["wall_s"] for r in runs), sum(r["cpu_s"] for r in runs)
        print(f"total: {sum(r['plates'] for r in runs)} plates in {len(runs)} run(s): wall {run_wall:.1f} s "
              f"({run_wall / 60:.2f} min, pool start included), CPU {run_cpu:.1f} s (workers from their start, "
              f"imports included, and the benchmark's process; {run_cpu / max(len(rows), 1):.3f} s per plate)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plates", type=int, default=60)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--spacing", type=float, default=100.0, help="point spacing of the generated designs (mm)")
    parser.add_argument("--real", type=int, default=0, help="plan this many real hull plates instead (resumable)")
    parser.add_argument("--part", type=int, default=100, help="plates per part of --real")
    parser.add_argument("--budget-min", type=float, default=9.0, help="stop starting parts after this (min)")
    parser.add_argument("--tag", default="after", help="name of the --real results file and jobs folder")
    args = parser.parse_args()
    if args.real:
        run_real(args.real, args.workers, args.part, args.budget_min, args.tag)
        return
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        manifest, kinds = write_batch(folder, args.plates, args.spacing)
        plates = read_manifest(manifest)
        options = BatchOptions(press_path=str(example_press_path()), out_dir=str(folder / "jobs"),
                               workers=args.workers)
        started = time.perf_counter()
        rows = run_batch(plates, options)
        wall = time.perf_counter() - started
        print(table(rows, kinds, wall, args.workers))
        for row in rows:
            if row["status"] == "failed":
                print(f"  failed {row['plate']} ({kinds[row['plate']]}): {row['reason'][:150]}")
        started = time.perf_counter()
        again = run_batch(plates, options)
        print(f"resume: {sum(r['status'] == 'skipped' for r in again)} of {len(again)} skipped in "
              f"{time.perf_counter() - started:.1f} s")


if __name__ == "__main__":
    main()
