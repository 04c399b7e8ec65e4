"""Benchmark: mppf registration against Open3D's ``registration_icp`` on the same clouds.

A doubly curved, asymmetric plate (3 x 1.5 m, about 140 mm deep) is sampled twice at
random: the design (target, exact) and a scan (source, 0.5 mm noise) put in a known
pose. For each size both files are written as CSV; mppf is timed on the whole job
(``read_points`` of both files + ``register_icp``), Open3D on its ICP call alone (the
arrays handed over in memory, so its file reading is not counted). Both start from the
same principal-axes start (the sign candidate nearest the truth), then from the identity.

Run:  python benchmarks/bench_register.py [--sizes 10000,50000,100000,200000]
      [--identity-sizes 50000] [--no-open3d]
(quick look, under a minute without load: ``--sizes 10000 --identity-sizes ""``).
Open3D is optional (``pip install open3d``; on Debian it needs ``apt-get install
libusb-1.0-0`` to import); without it only the mppf rows are printed.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table
from scipy.spatial.transform import Rotation

from mppf.geometry.frame import fit_frame
from mppf.geometry.read import read_points
from mppf.geometry.write import write_points
from mppf.registration.register import register_icp
from mppf.registration.starts import principal_candidates
from mppf.core.transform import apply_tf, invert_tf, make_tf, rotation_angle_deg

NOISE_MM = 0.5
POSE = make_tf(Rotation.from_euler("xyz", [12.0, -8.0, 20.0], degrees=True).as_matrix(), [250.0, -150.0, 400.0])
"""Known pose of the scanner frame relative to the design (moderate, so an identity start can work)."""

O3D_MAX_ITERATIONS = 500
O3D_MAX_DISTANCE_MM = 1000.0
O3D_PLANE_MAX_POINTS = 50000
"""Open3D point-to-plane slides on this plate until its iteration limit: only run on small clouds."""


def plate(n: int, rng: np.random.Generator) -> np.ndarray:
    """n random points on the plate z = u^2/16000 - v^2/24000 + u^3/3e8 (mm)."""
    u, v = rng.uniform(-1500, 1500, n), rng.uniform(-750, 750, n)
    return np.column_stack([u, v, u * u / 16000 - v * v / 24000 + u**3 / 3e8])


def errors(tf: np.ndarray, tf_true: np.ndarray, design: np.ndarray) -> tuple[float, float]:
    """(rotation error deg, displacement error at the design's centre mm)."""
    diff = tf @ invert_tf(tf_true)
    centre = design.mean(axis=0)
    return rotation_angle_deg(diff), float(np.linalg.norm(apply_tf(diff, centre[None])[0] - centre))


def principal_start(scan: np.ndarray, design: np.ndarray, tf_true: np.ndarray) -> np.ndarray:
    """The principal-axes candidate nearest the truth (the same start for both tools)."""
    candidates = principal_candidates(fit_frame(scan), fit_frame(design))
    return min(candidates, key=lambda tf: errors(tf, tf_true, design)[0])


@contextlib.contextmanager
def captured_stdout_fd(path: Path):
    """Redirect the C-level stdout (Open3D's debug log) into a file."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(path, "w") as sink:
        os.dup2(sink.fileno(), 1)
        try:
            yield
        finally:
            sys.stdout.flush()
            os.dup2(saved, 1)
            os.close(saved)


def run_open3d(o3d, scan, design, init, method, tmp: Path):
    reg = o3d.pipelines.registration
    src = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(scan))
    tgt = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(design))
    if method == "plane":
        tgt.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=10))
        estimation = reg.TransformationEstimationPointToPlane()
    else:
        estimation = reg.TransformationEstimationPointToPoint()
    criteria = reg.ICPConvergenceCriteria(relative_fitness=1e-6, relative_rmse=1e-6,
                                          max_iteration=O3D_MAX_ITERATIONS)
    log = tmp / "o3d.log"
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Debug)
    t0 = time.perf_counter()
    with captured_stdout_fd(log):
        result = reg.registration_icp(src, tgt, O3D_MAX_DISTANCE_MM, init, estimation, criteria)
    seconds = time.perf_counter() - t0
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Warning)
    iterations = len(re.findall(r"ICP Iteration #", log.read_text(errors="replace")))
    converged = iterations < O3D_MAX_ITERATIONS
    return np.asarray(result.transformation), seconds, iterations, float(result.inlier_rmse), converged


def run_mppf(scan_path, design_path, init, method):
    t0 = time.perf_counter()
    scan = read_points(scan_path).points
    design = read_points(design_path).points
    result = register_icp(scan, design, method=method, init=init, max_iterations=O3D_MAX_ITERATIONS)
    return result.tf, time.perf_counter() - t0, result.iterations, result.rms_mm, result.converged


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="10000,50000,100000,200000")
    parser.add_argument("--identity-sizes", default="50000")
    parser.add_argument("--no-open3d", action="store_true")
    args = parser.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",") if s]
    identity_sizes = [int(s) for s in args.identity_sizes.split(",") if s]
    console = Console(width=170)
    o3d = None
    if not args.no_open3d:
        try:
            import open3d as o3d
        except Exception as exc:  # noqa: BLE001 - optional dependency, any import failure
            console.print(f"open3d not available ({type(exc).__name__}: {exc}); mppf rows only")
    table = Table(title="registration benchmark (0.5 mm noise, known pose)")
    for col in ("points", "start", "tool / metric", "time s", "iter", "conv", "RMS mm",
                "rot err deg", "shift err mm", "time / O3D p2p"):
        table.add_column(col, justify="right" if col not in ("start", "tool / metric") else "left")
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        for n in sorted(set(sizes) | set(identity_sizes)):
            design = plate(n, rng)
            scan = apply_tf(invert_tf(POSE), plate(n, rng) + rng.normal(scale=NOISE_MM, size=(n, 3)))
            scan_path = write_points(tmp / f"scan_{n}.csv", scan)
            design_path = write_points(tmp / f"design_{n}.csv", design)
            starts = []
            if n in sizes:
                starts.append(("principal", principal_start(scan, design, POSE)))
            if n in identity_sizes:
                starts.append(("identity", np.eye(4)))
            for start_name, start_tf in starts:
                rows = []
                if o3d is not None:
                    rows.append(("Open3D point", *run_open3d(o3d, scan, design, start_tf, "point", tmp)))
                    if start_name == "principal" and n <= O3D_PLANE_MAX_POINTS:
                        rows.append(("Open3D plane", *run_open3d(o3d, scan, design, start_tf, "plane", tmp)))
                for metric in ("point", "plane"):
                    init = "principal" if start_name == "principal" else "identity"
                    rows.append((f"mppf {metric} (+read)", *run_mppf(scan_path, design_path, init, metric)))
                ref = rows[0][2] if o3d is not None else None
                for name, tf, seconds, iterations, rms, converged in rows:
                    rot, shift = errors(tf, POSE, design)
                    ratio = "" if ref is None else f"{seconds / ref:.2f}"
                    table.add_row(f"{n:,}", start_name, name, f"{seconds:.2f}", str(iterations),
                                  "yes" if converged else "no", f"{rms:.3f}", f"{rot:.4f}", f"{shift:.2f}", ratio)
                console.print(f"done: {n:,} points, {start_name} start", style="dim")
    console.print(table)
    console.print("mppf times include reading both CSV files; Open3D times are the ICP call only. "
                  "'conv' for Open3D: stopped before its iteration limit "
                  f"({O3D_MAX_ITERATIONS}). RMS: mppf the residual of its metric on the registered "
                  "subsample; Open3D inlier_rmse.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
