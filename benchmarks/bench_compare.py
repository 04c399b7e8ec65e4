"""Benchmark: ``mppf.measure.compare.compare`` of a dense scan against its design (issue 13: 200k points < 5 s, < 1 GB).

The analytic, asymmetric, doubly curved 3 x 2 m plate of the tests (``tests/scan_helpers.py``)
is the design (61 x 41 grid, 50 mm); the scan is that plate with a 5 mm bump, 0.3 mm noise and
0.5 % scanner artefacts 5-50 mm off, in an arbitrary pose. Each size runs in a fresh process
(``--one N``), so that its peak memory (``ru_maxrss``) is its own; the whole ``compare`` call
is timed (wall clock and this process's CPU time: on a busy machine the CPU time says more),
and its stages are profiled on request (``--profile``).

Run:  python benchmarks/bench_compare.py [--sizes 12000,50000,200000] [--profile]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time

import numpy as np
from scipy.spatial.transform import Rotation

from mppf.core.transform import apply_tf, make_tf, rotation_angle_deg

TIME_TARGET_S = 5.0
MEMORY_TARGET_MB = 1024.0
POSE = make_tf(Rotation.from_euler("xyz", [20, -40, 70], degrees=True).as_matrix(), [500.0, -2000.0, 300.0])


def height(u, v):
    return u**2 / (2 * 6000.0) - v**2 / (2 * 15000.0) + u**3 / 3e7 + u * v / 20000.0


def case(n: int, seed: int = 1):
    """(design (2501, 3), scan (n, 3), true artefact mask (n,))."""
    uu, vv = np.meshgrid(np.linspace(-1500, 1500, 61), np.linspace(-1000, 1000, 41))
    design = np.column_stack([uu.ravel(), vv.ravel(), height(uu, vv).ravel()])
    rng = np.random.default_rng(seed)
    u, v = rng.uniform(-1480, 1480, n), rng.uniform(-980, 980, n)
    rise = 5.0 * np.exp(-((u - 400.0) ** 2 + (v - 200.0) ** 2) / (2 * 150.0**2))
    pts = np.column_stack([u, v, height(u, v) + rise]) + rng.normal(0.0, 0.3, (n, 3))
    artefact = rng.random(n) < 0.005
    pts[artefact, 2] += rng.choice([-1.0, 1.0], artefact.sum()) * rng.uniform(5.0, 50.0, artefact.sum())
    return design, apply_tf(POSE, pts), artefact


def one(n: int, profile: bool) -> dict:
    """Run one size in this process: time, peak memory, figures."""
    from mppf.measure.compare import compare

    design, scan, artefact = case(n)
    start, cpu = time.perf_counter(), time.process_time()
    if profile:
        import cProfile
        import pstats

        prof = cProfile.Profile()
        c = prof.runcall(compare, design, scan)
        pstats.Stats(prof, stream=sys.stderr).sort_stats("cumulative").print_stats(25)
    else:
        c = compare(design, scan)
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {"n": n, "seconds": seconds, "cpu_s": cpu, "peak_mb": peak_mb, "form_max_mm": c.form_max_abs_mm, "rms_mm": c.rms_mm,
            "turn_error_deg": rotation_angle_deg(c.transform @ POSE), "found": int((c.is_outlier & artefact).sum()),
            "artefacts": int(artefact.sum()), "false": int((c.is_outlier & ~artefact).sum()), "verdict": c.verdict.kind}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="12000,50000,200000")
    parser.add_argument("--one", type=int, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--profile", action="store_true", help="profile each compare (stderr)")
    args = parser.parse_args()
    if args.one is not None:
        print(json.dumps(one(args.one, args.profile)))
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"mppf compare (targets: {TIME_TARGET_S:g} s, {MEMORY_TARGET_MB:.0f} MB at 200k points)")
    for column in ("points", "time s", "CPU s", "peak MB", "form max mm (5.0)", "RMS mm", "turn error deg",
                   "artefacts set aside", "false", "verdict"):
        table.add_column(column, justify="right")
    for n in (int(s) for s in args.sizes.split(",") if s):
        cmd = [sys.executable, __file__, "--one", str(n)] + (["--profile"] if args.profile else [])
        r = json.loads(subprocess.run(cmd, check=True, text=True, stdout=subprocess.PIPE).stdout)
        table.add_row(f"{r['n']:,}", f"{r['seconds']:.2f}", f"{r['cpu_s']:.2f}", f"{r['peak_mb']:.0f}", f"{r['form_max_mm']:.2f}",
                      f"{r['rms_mm']:.3f}", f"{r['turn_error_deg']:.4f}", f"{r['found']} of {r['artefacts']}",
                      str(r["false"]), r["verdict"])
    Console(width=180).print(table)


if __name__ == "__main__":
    main()
