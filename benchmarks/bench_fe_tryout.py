"""Speed of the virtual try-out (``mppf tryout``) of a 3 x 2 m hull plate, and where its time goes.

Plans the bundled P2 bow flare (3.2 x 2.2 m, 20 mm steel, springback pre-compensated, the example
press; ``bench_fe.planned``), then

1. runs ``mppf tryout JOB --design --flat --steps all`` as the engineer would (its own process) and
   takes its wall time, end to end (reading, every press step on the FE plate, compare, report);
2. presses the same first cycle in this process and prints one row per ccx run: the press step,
   the analysis steps with increments / cutbacks / Newton iterations, the mesh, wall and CPU time,
   and the machine's load average (the machine is shared: the wall time depends on it, the CPU
   time much less).

    python3 benchmarks/bench_fe_tryout.py [--plate P2_bow_flare] [--skip-cli] [--skip-profile]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from bench_fe import PLATES, planned

def cli_seconds(design: Path, flat: Path, job: Path, out: Path, steps: str) -> tuple[float, int, str]:
    """Wall time, exit code and the form-max line of ``mppf tryout``."""
    start = time.monotonic()
    done = subprocess.run([sys.executable, "-m", "mppf", "tryout", str(job), "--design", str(design), "--flat",
                           str(flat), "-o", str(out), "--steps", steps], capture_output=True, text=True, check=False)
    seconds = time.monotonic() - start
    form = next((line.strip() for line in done.stdout.splitlines() if "form max" in line.lower()), "")
    return seconds, done.returncode, form


def step_names(press_step: int, count: int) -> list[str]:
    """Names of a run's analysis steps: the press steps replayed before it and its own."""
    names = []
    for k in range(press_step):
        names += (["APPROACH"] if k else []) + [f"LOAD{k + 1}", f"RELEASE{k + 1}"]
    return names[:count]


def profile(job_path: Path, flat_path: Path) -> None:
    """Press the job's first cycle on the FE plate here; one row per ccx run."""
    from mppf.geometry.read import read_points
    from mppf.planning.job import load_job
    from mppf.sim.shop import SimulatedPlateScanner

    job = load_job(job_path)
    flat = read_points(flat_path)
    scanner = SimulatedPlateScanner.for_job(job.press, job.thickness_mm, job, flat.points, seed=0, plate_model="fe")
    plate = scanner.plate
    print(f"\nmesh: {plate.mesh.node_count} nodes, {len(plate.mesh.hexes)} C3D8I, {len(plate.mesh.bottom)} pairs over "
          f"the plate, {plate.options['layers']} layers, {plate.options['cells_per_pitch']} cell(s) per pitch\n")
    print("| ccx run (press step) | analysis steps: increments / cutbacks / iterations | wall (s) | CPU (s) | load |")
    print("|---|---|---|---|---|")
    for k, step in enumerate(job.steps, start=1):
        plate.press_step(*step.setpoints_mm(job.press), np.asarray(step.active, dtype=bool))
        names = step_names(k, len(plate.last_ccx_steps))
        detail = ", ".join(f"{name} {i}/{c}/{n}" for name, (i, c, n) in zip(names, plate.last_ccx_steps.values()))
        print(f"| {k} | {detail} | {plate.last_seconds:.0f} | {plate.last_cpu_s:.0f} | {os.getloadavg()[0]:.1f} |",
              flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plate", default="P2_bow_flare", choices=PLATES)
    parser.add_argument("--out", type=Path, default=Path("/tmp/bench-fe"))
    parser.add_argument("--steps", choices=["all", "last"], default="all")
    parser.add_argument("--skip-cli", action="store_true")
    parser.add_argument("--skip-profile", action="store_true")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    design, flat, job = planned(args.plate, args.out)
    if not args.skip_cli:
        load = os.getloadavg()[0]
        seconds, code, form = cli_seconds(design, flat, job, args.out / f"{args.plate}-tryout", args.steps)
        print(f"mppf tryout {args.plate} --steps {args.steps}: {seconds:.0f} s wall end to end (exit {code}; load "
              f"{load:.1f} -> {os.getloadavg()[0]:.1f}); {form}", flush=True)
    if not args.skip_profile:
        profile(job, flat)


if __name__ == "__main__":
    main()
