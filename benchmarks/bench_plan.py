"""Planning time of the stroke planner for 10 x 10, 24 x 16 and 32 x 32 punch matrices.

Plans the real hull patch K3 (stern saddle, 61 x 41 points, 3.0 x 2.0 m, 20 mm) on
presses of each size (pitch chosen so the plate fits the bed), and prints a table:

- contact: the exact ball contact of every punch of both matrices (one solve),
- plan: :func:`mppf.planning.plan.plan_job` from design and flat points (surface fit,
  registration, contact with offset/tilt optimisation, steps, validation),
- plan + unfold: the same including :func:`mppf.geometry.unfold.unfold` of the design.

File reading is excluded. Best of ``--repeat`` runs, wall clock and CPU time of this
process (the CPU figure is the one to compare on a machine shared with other work).
On a busy machine run it with ``OPENBLAS_NUM_THREADS=1``: multi-threaded BLAS on two
shared cores multiplies the wall time (the figures in docs/ are measured that way).

    python benchmarks/bench_plan.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import mppf
from mppf.model.press import load_press, example_press_path, press_from_dict
from mppf.planning.contact import PlacedSurface, tip_heights
from mppf.geometry.read import read_points
from mppf.planning.plan import plan_job
from mppf.geometry.surface import fit_plate
from mppf.geometry.unfold import unfold

PLATE = Path(mppf.__file__).parent / "examples" / "hull" / "K3_stern_saddle.csv"
THICKNESS_MM = 20.0
SIZES = [(10, 10), (16, 24), (32, 32)]


def press_of(rows: int, cols: int):
    """The example press resized to rows x cols, its bed just larger than a 3.3 x 2.2 m plate."""
    doc = load_press(example_press_path()).to_dict()
    pitch_x = 3300.0 / (cols - 1)
    pitch_y = 2200.0 / (rows - 1)
    doc["matrix"].update(rows=rows, cols=cols, pitch_x_mm=pitch_x, pitch_y_mm=pitch_y,
                         tip_radius_mm=min(60.0, 0.45 * min(pitch_x, pitch_y)))
    return press_from_dict(doc)


def best_of(repeat: int, func):
    """(best wall-clock s, best CPU s of this process, result) over ``repeat`` runs."""
    wall, cpu = [], []
    for _ in range(repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        result = func()
        wall.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    return min(wall), min(cpu), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    design = read_points(PLATE).points
    flat = unfold(design).flat
    fitted = fit_plate(design, degree=4)
    print(f"plate {PLATE.name}: {len(design)} points, thickness {THICKNESS_MM:g} mm; best of {args.repeat}")
    print(f"{'matrix':>9} {'punches':>8} {'active':>7} {'contact s':>10} {'plan s':>8} {'plan cpu s':>11} "
          f"{'plan+unfold s':>14} {'cpu s':>6} {'steps':>6}")
    for rows, cols in SIZES:
        press = press_of(rows, cols)
        job = plan_job(design, flat, press, THICKNESS_MM)
        placed = PlacedSurface(fitted.surface, job.tf_press_design @ fitted.frame.tf_world_local)
        gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
        t_contact, _, _ = best_of(args.repeat, lambda: tip_heights(
            placed, gx.ravel(), gy.ravel(), tip_radius_mm=press.tip_radius_mm, thickness_mm=THICKNESS_MM))
        t_plan, c_plan, job = best_of(args.repeat, lambda: plan_job(design, flat, press, THICKNESS_MM))
        t_full, c_full, _ = best_of(args.repeat, lambda: plan_job(design, unfold(design).flat, press, THICKNESS_MM))
        print(f"{rows:>4} x {cols:<3} {2 * rows * cols:>8} {2 * int(job.steps[-1].active.sum()):>7} "
              f"{t_contact:>10.3f} {t_plan:>8.3f} {c_plan:>11.3f} {t_full:>14.3f} {c_full:>6.3f} {len(job.steps):>6}")


if __name__ == "__main__":
    main()
