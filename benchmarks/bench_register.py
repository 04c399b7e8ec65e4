"""Benchmark: ``mppf register`` beside Open3D point-to-point and small_gicp point-to-plane (issue 19).

Cases: three surfaces (an asymmetric doubly curved plate 3 x 1.5 m, a shallow saddle 4 mm
deep, a cylinder R 3 m), each as an EXACT moved copy (the same points, 0.3 mm noise on the
copy) and as a DIFFERENTLY SAMPLED scan (independent random points, 0.5 mm noise), at 10k,
100k and 200k source points (the target twice as dense when sampled apart), in a known pose,
from the principal-axes start and from the identity. Both clouds are written as CSV files.

Every tool runs as a whole fresh process on the same two files, and its CPU time (user +
system, imports and file reading included) is what is compared:

- mppf: the command ``mppf register SOURCE TARGET --method plane --init START`` as an operator
  runs it (its table printed); one more run with ``--json`` (not timed) gives the transform,
  the verdict and the ambiguity flag;
- the anchors: a Python process that imports numpy and the anchor only, reads the two files
  with ``numpy.loadtxt`` and registers (small_gicp ``PLANE_ICP``, every point, one thread, 100
  iterations at most; Open3D point-to-point, 500 at most), from the identity or from the
  principal-axes candidate nearest the truth (computed here, handed over in a file: the
  anchors get the right one of the four).

Bytecode: an installed package has its modules compiled (pip does it at install), a
machine with ``PYTHONDONTWRITEBYTECODE`` set compiles mppf's ~100 modules in every process
(about 0.08 s of CPU at each start). So the children run with a bytecode cache of their own
(``PYTHONPYCACHEPREFIX`` in the benchmark's temporary folder, the variable above unset),
filled by one untimed run of every command first; ``--no-bytecode-cache`` runs them in this
process's environment as it is.

Runs alternate (mppf, anchor, ..., mppf, anchor, ...); each row gives the median CPU time, the
ratio of the medians to small_gicp's, and the range of the run-by-run ratios (the scatter of
a shared machine). Errors are against the known truth (rotation deg, displacement at the
source's centre mm). The anchors are optional (``pip install open3d small_gicp``, not in the
test environment: Open3D pulls dash, whose pytest plugin breaks it); absent, only mppf's rows
are printed.

Run:  python benchmarks/bench_register.py [--sizes 10000,100000,200000] [--repeats 3]
      [--surfaces plate,saddle,cylinder] [--kinds copy,sampled] [--starts principal,identity]
      [--tools small_gicp,open3d] [--no-bytecode-cache] [--json PATH]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from mppf.core.transform import (
    apply_tf,
    invert_tf,
    make_tf,
    rotation_angle_deg,
    rotvec_to_matrix,
)

POSE = make_tf(rotvec_to_matrix(np.radians([0.0, 0.0, 20.0])) @ rotvec_to_matrix(np.radians([0.0, -8.0, 0.0]))
               @ rotvec_to_matrix(np.radians([12.0, 0.0, 0.0])), [250.0, -150.0, 400.0])
"""Known pose of the scan relative to the design: turns 12 / -8 / 20 degrees about x, y, z (in that order)
and 0.5 m off (moderate, so that an identity start can work)."""

ANCHOR_CODE = {
    "small_gicp": """
import sys, json
import numpy as np
import small_gicp
source, target = (np.loadtxt(p, delimiter=",") for p in sys.argv[1:3])
reg = small_gicp.align(target, source, np.loadtxt(sys.argv[3]), registration_type="PLANE_ICP",
                       max_correspondence_distance=1000.0, max_iterations=100, num_threads=1)
print(json.dumps({"tf": np.asarray(reg.T_target_source).tolist(), "note": f"converged {reg.converged}"}))
""",
    "open3d": """
import sys, json
import numpy as np
import open3d as o3d
source, target = (o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.loadtxt(p, delimiter=",")))
                  for p in sys.argv[1:3])
reg = o3d.pipelines.registration.registration_icp(
    source, target, 1000.0, np.loadtxt(sys.argv[3]),
    o3d.pipelines.registration.TransformationEstimationPointToPoint(),
    o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=500))
print(json.dumps({"tf": np.asarray(reg.transformation).tolist(), "note": f"fitness {reg.fitness:.2f}"}))
""",
}
"""Each anchor's whole process: numpy and the anchor imported, the two CSV files read, one registration."""


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
    centre = source.mean(axis=0)[None]
    return rotation_angle_deg(tf @ invert_tf(POSE)), float(np.linalg.norm(apply_tf(tf, centre) - apply_tf(POSE, centre)))


def principal_nearest_truth(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The principal-axes start nearest the truth (the anchors get the right one of the four)."""
    from mppf.geometry.frame import fit_frame
    from mppf.registration.starts import principal_candidates

    starts = principal_candidates(fit_frame(source), fit_frame(target))
    return min(starts, key=lambda tf: rotation_angle_deg(tf @ invert_tf(POSE)))


def mppf_command(files: dict, start: str, as_json: bool) -> list[str]:
    """The ``mppf register`` command line of one case (the ``mppf`` next to this Python)."""
    exe = shutil.which("mppf", path=str(Path(sys.executable).parent)) or shutil.which("mppf")
    if exe is None:
        raise SystemExit("the mppf command is not installed next to this Python (pip install -e .)")
    return [exe, "register", files["source"], files["target"], "--method", "plane", "--init", start,
            *(["--json"] if as_json else [])]


def child_env(tmp: str | None) -> dict | None:
    """The children's environment: with a bytecode cache in ``tmp`` (see the module's doc), or None (this one's)."""
    if tmp is None:
        return None
    env = {key: value for key, value in os.environ.items() if key != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPYCACHEPREFIX"] = str(Path(tmp) / "pycache")
    return env


def child_cpu(command: list[str], env: dict | None = None) -> tuple[float, str]:
    """Run one fresh process; (its CPU seconds, user + system, imports included; its stdout)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run(command, check=True, text=True, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                         env=env).stdout
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), out


def available(wanted: list[str]) -> list[str]:
    """The anchors of ``wanted`` that this Python can import."""
    tools = []
    for tool in wanted:
        try:
            __import__(tool)
            tools.append(tool)
        except ImportError:
            pass
    return tools


def run_case(files: dict, source: np.ndarray, start: str, anchors: list[str], repeats: int,
             env: dict | None = None) -> dict:
    """Times (alternating runs) and errors of every tool on one case: {tool: {"cpu": [...], ...}}."""
    commands = {"mppf": mppf_command(files, start, as_json=False)}
    for tool in anchors:
        commands[tool] = [sys.executable, "-c", ANCHOR_CODE[tool], files["source"], files["target"], files[start]]
    rows = {tool: {"cpu": []} for tool in commands}
    _, out = child_cpu(mppf_command(files, start, as_json=True), env)  # untimed: the result, the bytecode cache
    for command in list(commands.values())[1:] if env is not None else []:  # the anchors' bytecode cache
        child_cpu(command, env)
    for _ in range(repeats):
        for tool, command in commands.items():
            cpu, tool_out = child_cpu(command, env)
            rows[tool]["cpu"].append(cpu)
            if tool != "mppf":
                rows[tool]["result"] = json.loads(tool_out.strip().splitlines()[-1])
    data = json.loads(out)
    rows["mppf"]["result"] = {"tf": data["transform"], "note": data["verdict"][:40]
                              + (" (ambiguous start: symmetric)" if data["ambiguous_start"] else ""),
                              "verdict": data["verdict"], "ambiguous_start": data["ambiguous_start"]}
    for row in rows.values():
        row["rot_deg"], row["shift_mm"] = errors(np.asarray(row["result"]["tf"]), source)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="10000,100000,200000")
    parser.add_argument("--surfaces", default="plate,saddle,cylinder")
    parser.add_argument("--kinds", default="copy,sampled")
    parser.add_argument("--starts", default="principal,identity")
    parser.add_argument("--tools", default="small_gicp,open3d", help="anchors to run when importable")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-bytecode-cache", dest="bytecode_cache", action="store_false",
                        help="run the children in this environment as it is (see the module's doc on bytecode)")
    parser.add_argument("--json", dest="json_path", default=None,
                        help="also write every case's CPU times, transforms, errors and notes to this JSON file")
    args = parser.parse_args()
    from rich.console import Console
    from rich.table import Table

    anchors = available([t for t in args.tools.split(",") if t])
    table = Table(title="registration, whole processes: mppf register (point-to-plane, its pin where free) "
                        "beside the anchors")
    for column in ("surface", "kind", "points", "start", "tool", "CPU s", "/ small_gicp", "run ratios",
                   "rot err deg", "shift err mm", "verdict / note"):
        table.add_column(column, justify="right")
    cases = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.surfaces.split(","):
            for kind in args.kinds.split(","):
                for n in (int(s) for s in args.sizes.split(",") if s):
                    source, target = case(name, kind, n)
                    files = {role: str(Path(tmp) / f"{name}-{kind}-{n}-{role}.csv") for role in ("source", "target")}
                    np.savetxt(files["source"], source, delimiter=",", fmt="%.4f")
                    np.savetxt(files["target"], target, delimiter=",", fmt="%.4f")
                    for start, tf0 in (("principal", principal_nearest_truth(source, target)), ("identity", np.eye(4))):
                        files[start] = str(Path(tmp) / f"{name}-{kind}-{n}-{start}.txt")
                        np.savetxt(files[start], tf0)
                    for start in args.starts.split(","):
                        rows = run_case(files, source, start, anchors, args.repeats,
                                        child_env(tmp if args.bytecode_cache else None))
                        _add_rows(table, (name, kind, f"{n:,}", start), rows)
                        cases.append({"surface": name, "kind": kind, "points": n, "start": start, "tools": rows})
    Console(width=220).print(table)
    if args.json_path:
        Path(args.json_path).write_text(json.dumps(cases, indent=1))
    if not anchors:
        Console(width=220).print("Open3D and small_gicp are not importable here: only mppf's rows (pip install "
                                 "open3d small_gicp to compare).")


def _add_rows(table, labels: tuple, rows: dict) -> None:
    """One table row per tool; ratios to small_gicp (of the medians, and the range run by run)."""
    base = rows.get("small_gicp")
    for tool, row in rows.items():
        cpu = float(np.median(row["cpu"]))
        ratio = scatter = "-"
        if base is not None:
            ratio = f"{cpu / float(np.median(base['cpu'])):.2f}"
            runs = np.array(row["cpu"]) / np.array(base["cpu"])
            scatter = f"{runs.min():.2f} - {runs.max():.2f}"
        table.add_row(*labels, tool, f"{cpu:.2f}", ratio, scatter, f"{row['rot_deg']:.4f}", f"{row['shift_mm']:.3f}",
                      str(row["result"]["note"])[:60])


if __name__ == "__main__":
    main()
