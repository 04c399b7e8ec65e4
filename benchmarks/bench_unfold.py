"""Benchmark of ``mppf.geometry.unfold``: the real hull patches and a 200 x 200 grid.

Run: ``python benchmarks/bench_unfold.py [--repeat N]``. Prints one row per plate:
points, triangles, wall and CPU time (best of N; CPU time is the fairer figure on a
shared machine), Gauss-Newton iterations, RMS and max strain.
Targets (issue 4): a 61 x 41 hull patch well under a second, 200 x 200 under 10 s.
On a busy machine run it with ``OPENBLAS_NUM_THREADS=1``: multi-threaded BLAS on two
shared cores multiplies the wall time (the figures in docs/ are measured that way).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from mppf.geometry.read import read_points
from mppf.geometry.unfold import unfold

HULL = Path(__file__).resolve().parents[1] / "mppf" / "examples" / "hull"


def saddle_grid(n: int = 200, radius_u_mm: float = 30600.0, radius_v_mm: float = -26400.0) -> np.ndarray:
    """An n x n grid over a 3.0 x 2.0 m saddle with the principal radii of plate P3."""
    u, v = np.meshgrid(np.linspace(-1500.0, 1500.0, n), np.linspace(-1000.0, 1000.0, n), indexing="ij")
    w = u ** 2 / (2 * radius_u_mm) + v ** 2 / (2 * radius_v_mm)
    return np.column_stack([u.ravel(), v.ravel(), w.ravel()])


def run(name: str, points: np.ndarray, repeat: int) -> dict:
    best, best_cpu, result = np.inf, np.inf, None
    for _ in range(repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        result = unfold(points)
        best = min(best, time.perf_counter() - start)
        best_cpu = min(best_cpu, time.process_time() - start_cpu)
    return {"plate": name, "points": result.n_points, "triangles": len(result.faces), "time_s": best,
            "cpu_s": best_cpu,
            "iterations": result.iterations, "rms_pct": result.rms_strain_pct, "max_pct": result.max_strain_pct}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs per plate; the best time is shown")
    args = parser.parse_args()
    rows = [run(path.name, read_points(path).points, args.repeat) for path in sorted(HULL.glob("*.csv"))]
    rows.append(run("saddle grid 200 x 200", saddle_grid(), max(1, args.repeat // 2)))
    header = (f"{'plate':<30} {'points':>7} {'triangles':>9} {'time s':>7} {'cpu s':>6} {'iter':>5} "
              f"{'RMS %':>8} {'max %':>8}")
    print(header)
    print("-" * len(header))
    for r in rows:
        print(f"{r['plate']:<30} {r['points']:>7} {r['triangles']:>9} {r['time_s']:>7.2f} {r['cpu_s']:>6.2f} "
              f"{r['iterations']:>5} {r['rms_pct']:>8.4f} {r['max_pct']:>8.4f}")


if __name__ == "__main__":
    main()
