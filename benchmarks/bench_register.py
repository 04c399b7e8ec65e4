"""Benchmark: mppf registration beside Open3D point-to-point and small_gicp point-to-plane (issue 19).

Cases: three surfaces (an asymmetric doubly curved plate 3 x 1.5 m, a shallow saddle 4 mm
deep, a cylinder R 3 m), each as an EXACT moved copy (the same points, 0.3 mm noise on the
copy) and as a DIFFERENTLY SAMPLED scan (independent random points, 0.5 mm noise), at 10k,
100k and 200k source points (the target twice as dense when sampled apart), in a known pose,
from the principal-axes start and from the identity. Errors are against the known truth
(rotation deg, displacement at the source's centre mm); times are whole-process CPU times of
a fresh process for mppf (``import`` + ``register_icp``, as ``mppf register`` pays them) and the
anchors' registration call; each row's time is also given as a ratio to the anchor's from
alternating runs (mppf, anchor, mppf, anchor ...; the median ratio).

The anchors are optional (``pip install open3d small_gicp``): absent, only mppf's rows are
printed, and the table says so.

Run:  python benchmarks/bench_register.py [--sizes 10000,100000,200000] [--repeats 3]
      [--surfaces plate,saddle,cylinder] [--kinds copy,sampled] [--starts principal,identity]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mppf.core.transform import apply_tf, invert_tf, make_tf, rotation_angle_deg

POSE = make_tf(Rotation.from_euler("xyz", [12.0, -8.0, 20.0], degrees=True).as_matrix(), [250.0, -150.0, 400.0])
"""Known pose of the scan relative to the design (moderate, so that an identity start can work)."""


def surface(name: str, n: int, rng: np.random.Generator) -> np.ndarray:
    """n random points (mm) on the named surface."""
    u, v = rng.uniform(-1500, 1500, n), rng.uniform(-750, 750, n)
    if name == "plate":
        w = u * u / 16000 - v * v / 24000 + u**3 / 3e8
    elif name == "saddle":
        w = u * u / 2.8e5 - v * v / 7e4 * 0.5
    elif name == "cylinder":
        w = 3000.0 - np.sqrt(3000.0**2 - v * v)
    else:
        raise ValueError(name)
    return np.column_stack([u, v, w])


def case(name: str, kind: str, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(source = scan in its own frame, target = design); target = POSE @ source ideally."""
    rng = np.random.default_rng(seed)
    if kind == "copy":
        design = surface(name, n, rng)
        scan = apply_tf(invert_tf(POSE), design) + rng.normal(scale=0.3, size=design.shape)
    else:
        design = surface(name, 2 * n, rng)
        scan = apply_tf(invert_tf(POSE), surface(name, n, rng) + rng.normal(scale=0.5, size=(n, 3)))
    return scan, design


def errors(tf: np.ndarray, source: np.ndarray) -> tuple[float, float]:
    """(rotation error deg, displacement error at the source's centre mm) against :data:`POSE`."""
    centre = source.mean(axis=0)
    return rotation_angle_deg(tf @ invert_tf(POSE)), float(np.linalg.norm(apply_tf(tf, centre[None])[0]
                                                                            - apply_tf(POSE, centre[None])[0]))


def run_one(tool: str, path: Path, start: str) -> dict:
    """One registration in this process (the child of :func:`timed`)."""
    cpu = time.process_time()
    data = np.load(path)
    source, target = data["source"], data["target"]
    if tool == "mppf":
        from mppf.registration.register import register_icp

        result = register_icp(source, target, method="plane", init=start)
        tf, note = result.tf, result.verdict + (" (ambiguous start: symmetric)" if result.ambiguous_start else "")
    elif tool == "open3d":
        import open3d as o3d

        src, tgt = (o3d.geometry.PointCloud(o3d.utility.Vector3dVector(a)) for a in (source, target))
        init = np.eye(4) if start == "identity" else _principal(source, target)
        reg = o3d.pipelines.registration.registration_icp(
            src, tgt, 1000.0, init, o3d.pipelines.registration.TransformationEstimationPointToPoint(),
            o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=500))
        tf, note = np.asarray(reg.transformation), f"fitness {reg.fitness:.2f}"
    else:
        import small_gicp

        init = np.eye(4) if start == "identity" else _principal(source, target)
        # full clouds (a 0.25 mm voxel keeps every point of a mm cloud), one thread as mppf's CPU time is counted
        reg = small_gicp.align(target, source, init, registration_type="PLANE_ICP", max_correspondence_distance=1000.0,
                               max_iterations=100)
        tf, note = np.asarray(reg.T_target_source), f"converged {reg.converged}"
    rot, shift = errors(tf, source)
    return {"cpu_s": time.process_time() - cpu, "rot_deg": rot, "shift_mm": shift, "note": note}


def _principal(source, target) -> np.ndarray:
    """The principal-axes start nearest the truth (the anchors get the right one of the four)."""
    from mppf.geometry.frame import fit_frame
    from mppf.registration.starts import principal_candidates

    starts = principal_candidates(fit_frame(source), fit_frame(target))
    return min(starts, key=lambda tf: rotation_angle_deg(tf @ invert_tf(POSE)))


def timed(tool: str, path: Path, start: str) -> dict:
    """One registration in a fresh process: its errors and note (its CPU time: :func:`_child_cpu`)."""
    out = subprocess.run([sys.executable, __file__, "--child", tool, str(path), start], check=True, text=True,
                         stdout=subprocess.PIPE).stdout
    return json.loads(out.strip().splitlines()[-1])


def available() -> list[str]:
    tools = []
    for tool, module in (("open3d", "open3d"), ("small_gicp", "small_gicp")):
        try:
            __import__(module)
            tools.append(tool)
        except ImportError:
            pass
    return tools


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="10000,100000,200000")
    parser.add_argument("--surfaces", default="plate,saddle,cylinder")
    parser.add_argument("--kinds", default="copy,sampled")
    parser.add_argument("--starts", default="principal,identity")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--child", nargs=3, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(run_one(args.child[0], Path(args.child[1]), args.child[2])))
        return
    from rich.console import Console
    from rich.table import Table

    anchors = available()
    table = Table(title="registration: mppf (point-to-plane, its pin where free) beside the anchors")
    for column in ("surface", "kind", "points", "start", "tool", "CPU s", "time / anchor", "rot err deg",
                   "shift err mm", "verdict / note"):
        table.add_column(column, justify="right")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.surfaces.split(","):
            for kind in args.kinds.split(","):
                for n in (int(s) for s in args.sizes.split(",") if s):
                    path = Path(tmp) / f"{name}-{kind}-{n}.npz"
                    source, target = case(name, kind, n)
                    np.savez(path, source=source, target=target)
                    for start in args.starts.split(","):
                        _rows(table, name, kind, n, start, path, anchors, args.repeats)
    Console(width=200).print(table)
    if not anchors:
        Console(width=200).print("Open3D and small_gicp are not importable here: only mppf's rows (pip install open3d "
                        "small_gicp to compare).")


def _rows(table, name, kind, n, start, path, anchors, repeats) -> None:
    """mppf's row and the anchors' rows of one case; times from alternating runs."""
    runs = {tool: [] for tool in ["mppf", *anchors]}
    for _ in range(repeats):
        for tool in runs:  # alternating: mppf, anchor, anchor, mppf, ...
            runs[tool].append(_child_cpu(tool, path, start))
    base = min(anchors, key=lambda t: np.median([r["cpu_s"] for r in runs[t]])) if anchors else None
    for tool, rows in runs.items():
        cpu = float(np.median([r["cpu_s"] for r in rows]))
        ratio = "-" if base is None else f"{cpu / float(np.median([r['cpu_s'] for r in runs[base]])):.2f}"
        last = rows[-1]
        table.add_row(name, kind, f"{n:,}", start, tool, f"{cpu:.2f}", ratio, f"{last['rot_deg']:.4f}",
                      f"{last['shift_mm']:.3f}", str(last["note"])[:60])


def _child_cpu(tool: str, path: Path, start: str) -> dict:
    """One fresh-process run; its whole CPU time (user + system of the child, imports included)."""
    import resource

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    row = timed(tool, path, start)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    row["cpu_s"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return row


if __name__ == "__main__":
    main()
