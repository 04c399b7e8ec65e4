"""Batch planning of N generated hull plates: wall time, per-plate time and memory.

Generates N plates (seeded) as design files with a manifest: cylinders bent along or across,
twisted plates and saddles (z = a x^2 + b y^2 + c x y), 2.5-9 m long and 1.6-2.4 m wide, so that
about half fit the example press's bed (3.45 x 2.25 m) and the rest are planned in sections. Then
:func:`mppf.planning.batch.run_batch` unfolds and plans them (a process pool on every core, as
``mppf batch``) and prints a table per kind (plates, sections, per-plate time, worker peak memory)
and the extrapolated wall time of 1000 plates. A second run over the same folder shows the resume
(every plate skipped).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_batch.py [--plates 60] [--workers 2] [--spacing 100]
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from mppf.core.transform import apply_tf
from mppf.examples.analytic import hull_pose
from mppf.geometry.write import write_points
from mppf.planning.batch import BatchOptions, read_manifest, run_batch
from mppf.planning.press import example_press_path


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
    out = [f"{'group':<14} {'plates':>6} {'failed':>6} {'sections':>8} {'wall s/plate med':>16} {'max':>6} "
           f"{'CPU s/plate med':>15} {'max':>6} {'peak RSS MB':>11}"]
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plates", type=int, default=60)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--spacing", type=float, default=100.0, help="point spacing of the generated designs (mm)")
    args = parser.parse_args()
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
