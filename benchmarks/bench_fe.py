"""The FE plate against the finite-difference plate on the bundled hull plates' first cycle.

For each plate: unfold, plan (20 mm steel, springback pre-compensated, the example press), press
the job's first cycle (every step, the tips where the job sets them) on the finite-difference
steel plate (``fd``) and on the FE plate computed by CalculiX (``fe``), scan each without noise
and compare it with the design as ``mppf compare --job`` does. Prints one markdown row per plate
and physics: steps, stroke range, form max, RMS, wall time. Runs in parts (``--plates``) so that
each part stays under 10 minutes on a shared machine.

    python3 benchmarks/bench_fe.py --plates P2_bow_flare --out /tmp/bench-fe
    python3 benchmarks/bench_fe.py --plates K1_midbody_bilge P1_midbody_bilge --physics fe
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from mppf.core.errors import MppfError

HULL = Path(__file__).resolve().parents[1] / "mppf" / "examples" / "hull"
PLATES = ("K1_midbody_bilge", "K2_fwd_bilge_convex", "K3_stern_saddle", "P1_midbody_bilge", "P2_bow_flare",
          "P3_stern_saddle")
THICKNESS_MM = 20.0


def mppf(*args: str) -> subprocess.CompletedProcess:
    """Run the mppf command line (its own process, as an engineer would)."""
    return subprocess.run([sys.executable, "-m", "mppf", *args], check=False, capture_output=True, text=True)


def planned(name: str, out: Path) -> tuple[Path, Path, Path]:
    """Design, flat and first-cycle job of a bundled plate (unfolded and planned once)."""
    design, flat, job = HULL / f"{name}.csv", out / f"{name}.flat.csv", out / f"{name}.job.json"
    if not job.exists():
        mppf("unfold", str(design), "-o", str(flat))
        done = mppf("plan", str(design), str(flat), "--thickness", str(THICKNESS_MM), "--springback",
                    "--material", "steel", "-o", str(job))
        if done.returncode != 0:
            raise SystemExit(f"mppf plan {name} failed: {done.stderr}")
    return design, flat, job


def first_cycle(job_path: Path, flat_path: Path, physics: str, folder: Path, seed: int,
                last_only: bool = False, options: dict | None = None) -> tuple[Path, float]:
    """The scan of the plate pressed with the job's first cycle (or its last step only), and the seconds it took.

    ``options``: the plate's options (the FE plate's ``cells_per_pitch``, ``layers``)."""
    from mppf.core.progress import NULL_REPORTER
    from mppf.core.scanner import PressedStep, ScanContext
    from mppf.geometry.read import read_points
    from mppf.planning.job import load_job
    from mppf.sim.shop import PHYSICS, STATE_FILE, SimulatedPlateScanner

    job = load_job(job_path)
    flat = read_points(flat_path)
    scanner = SimulatedPlateScanner.for_job(job.press, job.thickness_mm, job, flat.points, seed=seed,
                                            plate_model=PHYSICS[physics], noise_mm=0.0, occlusion_fraction=0.0,
                                            outlier_fraction=0.0, plate_options=options)
    steps = tuple(PressedStep(1, k, *step.setpoints_mm(job.press), np.asarray(step.active, dtype=bool))
                  for k, step in enumerate(job.steps, start=1))
    if last_only:
        steps = steps[-1:]
    folder.mkdir(parents=True, exist_ok=True)
    (folder / STATE_FILE).unlink(missing_ok=True)  # a plate pressed by an earlier run is not pressed again
    context = ScanContext(plate_id=physics, work_dir=folder, since_s=0.0, upper_mm=steps[-1].upper_mm,
                          lower_mm=steps[-1].lower_mm, active=steps[-1].active, steps=steps, reporter=NULL_REPORTER)
    start = time.monotonic()
    scan = scanner.acquire(1, context)
    first_cycle.plate = scanner.plate  # for the studies that look into the pressed plate
    return scan, time.monotonic() - start


def stroke_range(job_path: Path) -> tuple[int, float, float]:
    """Steps of the job and the lowest lower / highest upper tip of its active pairs, mm."""
    from mppf.planning.job import load_job

    job = load_job(job_path)
    lows = [np.nanmin(s.lower_mm[s.active]) for s in job.steps]
    highs = [np.nanmax(s.upper_mm[s.active]) for s in job.steps]
    return len(job.steps), float(min(lows)), float(max(highs))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plates", nargs="+", default=list(PLATES), choices=PLATES)
    parser.add_argument("--physics", nargs="+", default=["fd", "fe"], choices=["fd", "fe"])
    parser.add_argument("--out", type=Path, default=Path("/tmp/bench-fe"))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", choices=["all", "last"], default="all",
                        help="every step of the first cycle, or only its last one from the flat plate")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    print("| plate | steps | strokes lower..upper (mm) | physics | pressed | form max (mm) | RMS (mm) | time (s) |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.plates:
        design, flat, job = planned(name, args.out)
        steps, low, high = stroke_range(job)
        for physics in args.physics:
            folder = args.out / f"{name}-{physics}-{args.steps}"
            try:
                scan, seconds = first_cycle(job, flat, physics, folder, args.seed, args.steps == "last")
            except MppfError as exc:  # a run that does not converge is a result of the table too
                print(f"| {name} | {steps} | {low:.0f} .. {high:.0f} | {physics} | {args.steps} | failed: "
                      f"{str(exc).split(';')[0]} | | |", flush=True)
                continue
            result = mppf("compare", str(design), str(scan), "--job", str(job), "--json")
            doc = json.loads(result.stdout) if result.stdout.strip().startswith("{") else {}
            print(f"| {name} | {steps} | {low:.0f} .. {high:.0f} | {physics} | {args.steps} | "
                  f"{doc.get('form_max_abs_mm', float('nan')):.1f} | {doc.get('form_rms_mm', float('nan')):.1f} | "
                  f"{seconds:.0f} |", flush=True)


if __name__ == "__main__":
    main()
