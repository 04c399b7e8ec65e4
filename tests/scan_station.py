"""A scanner station outside the loop, for the tests: run as ``python tests/scan_station.py FOLDER DESIGN --mode M``.

It does what docs/scanner-station.md asks of a station: watches FOLDER for a scan request
(``*.scan-request.json``), reads it (the job it names places the design on the press), and
writes the scan of the plate as designed (its top skin, press coordinates, seeded noise) to
the request's ``scan.path`` (by a temporary name renamed into place) and the reference mark
(the top skin at the request's ``mark.corner_press_mm``) in the way ``--mode`` says:

- ``early``: the mark file before the scan;
- ``late``: the mark file ``--delay`` s after the scan;
- ``header``: in the scan's header (a PLY ``comment reference_mark_mm X Y Z`` line), no mark file;
- ``none``: no mark at all.

``--bend F`` scans the plate bent F times as much as designed (its heights about its own best
plane multiplied by F: a plate a correction has badly over-formed), ``--scale S`` writes the
scan in other units (S = 0.001: metres).

It handles ``--requests`` requests (default 1), prints one line per step on stdout
(``request ...``, ``scan ...``, ``mark ...``, ``gone ...`` once the loop removed the request),
then exits.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def plate_in_press(design_path: Path, job_path: Path, thickness_mm: float, bend: float = 1.0) -> np.ndarray:
    """The design's top skin in press coordinates (the mid-surface lifted by t/2: a shallow plate), its heights about
    its own best plane multiplied by ``bend``."""
    from mppf.core.transform import apply_tf
    from mppf.geometry.frame import fit_frame
    from mppf.geometry.read import read_points
    from mppf.planning.job import load_job

    job = load_job(job_path)
    design = read_points(design_path).points
    if bend != 1.0:
        frame = fit_frame(design)
        local = frame.to_local(design)
        local[:, 2] *= bend
        design = frame.to_world(local)
    mid = apply_tf(job.tf_press_design, design)
    return mid + [0.0, 0.0, thickness_mm / 2.0]


def write_ply(path: Path, points: np.ndarray, comments=()) -> None:
    """An ASCII PLY, written to ``.name.tmp`` and renamed into place (the loop never sees half a file)."""
    lines = ["ply", "format ascii 1.0", *[f"comment {c}" for c in comments], f"element vertex {len(points)}",
             "property double x", "property double y", "property double z", "end_header"]
    lines += [f"{x:.4f} {y:.4f} {z:.4f}" for x, y, z in points]
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text("\n".join(lines) + "\n")
    tmp.replace(path)


def serve(folder: Path, design: Path, mode: str, delay_s: float, seed: int, bend: float = 1.0,
          scale: float = 1.0) -> None:
    """Answer one scan request in ``folder``."""
    request_path = _wait(lambda: sorted(folder.glob("*.scan-request.json")))[0]
    request = json.loads(request_path.read_text())
    print(f"request {request_path.name} cycle {request['cycle']}", flush=True)
    top = plate_in_press(design, Path(request["job"]["path"]), request["plate"]["thickness_mm"], bend)
    rng = np.random.default_rng(seed + request["cycle"])
    scan = top + rng.normal(0.0, 0.2, top.shape)
    corner = np.asarray(request["mark"]["corner_press_mm"], dtype=float)
    nearest = top[np.argmin(np.linalg.norm(top[:, :2] - corner, axis=1))]
    mark = [scale * float(corner[0]), scale * float(corner[1]), scale * float(nearest[2])]
    scan = scale * scan
    scan_path, mark_path = Path(request["scan"]["path"]), Path(request["mark"]["path"])
    if mode == "early":
        mark_path.write_text(json.dumps({"reference_mark_mm": mark}))
        print(f"mark {mark_path.name}", flush=True)
    header = [f"reference_mark_mm {mark[0]:.3f} {mark[1]:.3f} {mark[2]:.3f}"] if mode == "header" else []
    write_ply(scan_path, scan, header)
    print(f"scan {scan_path.name}", flush=True)
    if mode == "late":
        time.sleep(delay_s)
        mark_path.write_text(json.dumps({"reference_mark_mm": mark}))
        print(f"mark {mark_path.name} after {delay_s:g} s", flush=True)
    _wait(lambda: not request_path.exists(), timeout_s=60.0)
    print(f"gone {request_path.name}", flush=True)


def _wait(found, timeout_s: float = 60.0, poll_s: float = 0.1):
    start = time.monotonic()
    while time.monotonic() - start < timeout_s:
        value = found()
        if value:
            return value
        time.sleep(poll_s)
    print("timeout", flush=True)
    sys.exit(3)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("folder", type=Path)
    parser.add_argument("design", type=Path)
    parser.add_argument("--mode", choices=("early", "late", "header", "none"), default="early")
    parser.add_argument("--delay", type=float, default=2.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--requests", type=int, default=1)
    parser.add_argument("--bend", type=float, default=1.0)
    parser.add_argument("--scale", type=float, default=1.0)
    args = parser.parse_args()
    for _ in range(args.requests):
        serve(args.folder, args.design, args.mode, args.delay, args.seed, args.bend, args.scale)


if __name__ == "__main__":
    main()
