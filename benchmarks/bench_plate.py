"""Benchmark: the simulated steel plate (mppf.sim.plate) pressed on the example press.

A 3 x 2 m plate cut with a 100 mm trim margin (3.2 x 2.2 m, 20 mm, seeded scatter,
compliant press) on the example press (24 x 16 punches at 150 mm, all pairs under the plate
active) is formed in one cycle of three steps towards a target shape (the strokes of
1/3, 2/3 and all of it: a cylinder R = 3 m, a saddle R = 4 m / -8 m and a strong bowl
R = 2 m / 4 m), at several grid spacings. Prints a table per shape: grid spacing,
unknowns, build time, wall and CPU time per step (mean and worst), Newton iterations per
step (load increments + unloading), peak traced memory of a cycle and the size of the
saved state.

One BLAS thread (set before numpy loads), the fair setting on a shared machine.

    python benchmarks/bench_plate.py [--spacings 100 75 50 25] [--steps 3]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core, before numpy loads

import argparse  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402

import numpy as np  # noqa: E402

from mppf.model.press import example_press_path, load_press  # noqa: E402
from mppf.sim.plate.plate import SteelPlate  # noqa: E402

THICKNESS_MM = 20.0
OUTLINE = np.array([[-1600.0, -1100.0], [1600.0, -1100.0], [1600.0, 1100.0], [-1600.0, 1100.0]])
SHAPES = {  # (kx, ky): curvatures of the target mid-surface along press x and y, 1/mm
    "cylinder R 3 m": (1 / 3000.0, 0.0),
    "saddle R 4 m / -8 m": (1 / 4000.0, -1 / 8000.0),
    "bowl R 2 m / 4 m": (1 / 2000.0, 1 / 4000.0),
}


def tips(press, kx: float, ky: float):
    """(upper, lower) tips holding the mid-surface on t/2 + kx x^2/2 + ky y^2/2 (ball geometry), mm."""
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    mid = 0.5 * THICKNESS_MM + 0.5 * kx * px**2 + 0.5 * ky * py**2
    s = np.sqrt(1.0 + (kx * px) ** 2 + (ky * py) ** 2)
    r = press.tip_radius_mm
    return mid - r + (r + 0.5 * THICKNESS_MM) * s, mid + r - (r + 0.5 * THICKNESS_MM) * s


def cycle(press, spacing_mm: float, shape, steps: int, seed: int = 1, *, memory: bool = False) -> dict:
    """Build one plate and press a cycle of ``steps`` steps; timings and counts (traced memory: slower)."""
    if memory:
        tracemalloc.start()
    start = time.perf_counter()
    plate = SteelPlate(press, OUTLINE, THICKNESS_MM, seed=seed, grid_spacing_mm=spacing_mm)
    build = time.perf_counter() - start
    active = np.ones(press.shape, dtype=bool)
    wall, cpu, iterations = [], [], []
    for k in range(1, steps + 1):
        upper, lower = tips(press, shape[0] * k / steps, shape[1] * k / steps)
        start, start_cpu = time.perf_counter(), time.process_time()
        formed = plate.press_step(upper, lower, active)
        wall.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
        iterations.append("+".join(str(i) for i in plate.last_iterations))
    peak = 0.0
    if memory:
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
    state_bytes = sum(np.asarray(v).nbytes for v in plate.state_dict().values())
    force_mn = np.nansum(formed.lower_force_n) / 1e6
    return {"dofs": plate.grid.n_dof, "build": build, "wall": wall, "cpu": cpu, "iterations": iterations,
            "peak_mb": peak / 2**20, "state_mb": state_bytes / 2**20, "force_mn": force_mn,
            "frame_mm": float(plate.frame_mm.max()), "ratio": formed.mean_ratio}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spacings", type=float, nargs="+", default=[100.0, 75.0, 50.0, 25.0])
    parser.add_argument("--steps", type=int, default=3)
    args = parser.parse_args()
    press = load_press(example_press_path())
    print(f"plate {np.ptp(OUTLINE[:, 0]):.0f} x {np.ptp(OUTLINE[:, 1]):.0f} mm, {THICKNESS_MM:.0f} mm, "
          f"{press.name}, {args.steps} steps per cycle, one BLAS thread")
    for name, shape in SHAPES.items():
        print(f"\n{name}")
        print(f"{'grid mm':>8} {'unknowns':>8} {'build s':>8} {'step s':>8} {'worst s':>8} {'cpu s':>7} "
              f"{'peak MB':>8} {'state MB':>8} {'force MN':>8} {'frame mm':>8} {'Ri/Rf':>6}  iterations per step")
        for spacing in args.spacings:
            r = cycle(press, spacing, shape, args.steps)
            r["peak_mb"] = cycle(press, spacing, shape, args.steps, memory=True)["peak_mb"]
            print(f"{spacing:8.0f} {r['dofs']:8d} {r['build']:8.2f} {np.mean(r['wall']):8.2f} {max(r['wall']):8.2f} "
                  f"{np.mean(r['cpu']):7.2f} {r['peak_mb']:8.1f} {r['state_mb']:8.1f} {r['force_mn']:8.2f} "
                  f"{r['frame_mm']:8.2f} {r['ratio']:6.3f}  {'  '.join(r['iterations'])}")


if __name__ == "__main__":
    main()
