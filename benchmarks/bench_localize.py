"""Benchmark: foot points (damped Newton-Raphson, eq. 2.11-2.17) on a fitted hull plate.

Fits the real stern saddle plate ``P3_stern_saddle.csv`` (bicubic polynomial and
bicubic B-spline), scatters 10k and 100k "scan" points over it (uniform in (u, v),
5 mm normal noise plus 2 % of outliers up to 300 mm off the surface, 50 mm beyond the
edges) and localizes them. Prints wall and CPU time (best of 3, one thread; CPU time
is the fairer figure on a shared machine), Newton iterations,
the largest eq. (2.11) residual and the number of non-converged points.

Run: ``python benchmarks/bench_localize.py`` (target: 100k points well under 1 s).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core, before numpy loads

import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import mppf  # noqa: E402
from mppf.geometry.read import read_points  # noqa: E402
from mppf.geometry.localize import foot_points  # noqa: E402
from mppf.geometry.surface import fit_plate  # noqa: E402

PLATE = Path(mppf.__file__).parent / "examples" / "hull" / "P3_stern_saddle.csv"


def scan_points(surface, n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    (u0, u1), (v0, v1) = surface.bounds
    uv = rng.uniform([u0 - 50, v0 - 50], [u1 + 50, v1 + 50], size=(n, 2))
    offset = rng.normal(scale=5.0, size=n)
    outliers = rng.random(n) < 0.02
    offset[outliers] = rng.uniform(-300.0, 300.0, size=outliers.sum())
    normals = surface.normals(uv[:, 0], uv[:, 1])
    on = np.column_stack([uv, surface.evaluate(uv[:, 0], uv[:, 1])])
    return on + offset[:, None] * normals


def main() -> None:
    pts = read_points(PLATE).points
    print(f"plate {PLATE.name}: {len(pts)} points, threads=1")
    header = f"{'surface':<22}{'points':>8}{'time s':>9}{'cpu s':>8}{'iter':>6}{'max|F| mm':>12}{'not conv.':>11}{'max|d| mm':>11}"
    print(header)
    print("-" * len(header))
    for kind in ("poly", "spline"):
        plate = fit_plate(pts, degree=3, kind=kind)
        name = f"{kind} (fit {plate.rms_mm:.2f} mm)"
        for n in (10_000, 100_000):
            query = scan_points(plate.surface, n)
            times, cpu = [], []
            for _ in range(3):
                start, start_cpu = time.perf_counter(), time.process_time()
                feet = foot_points(plate.surface, query)
                times.append(time.perf_counter() - start)
                cpu.append(time.process_time() - start_cpu)
            print(f"{name:<22}{n:>8}{min(times):>9.3f}{min(cpu):>8.3f}{feet.iterations:>6}{feet.residual_mm.max():>12.2e}"
                  f"{feet.n_failed:>11}{np.abs(feet.distance_mm).max():>11.1f}")


if __name__ == "__main__":
    main()
