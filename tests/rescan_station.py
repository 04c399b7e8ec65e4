"""A fixed scanner station outside the loop that answers rescan requests: ``python tests/rescan_station.py FOLDER DESIGN``.

As tests/scan_station.py, it reads each scan request in FOLDER (``*.scan-request.json``) and
writes the plate as designed (its top skin, press coordinates, seeded noise) to the
request's ``scan.path``; the first scan (``rescan`` 0) with its mark file written first and
a hole of ``--hole`` mm radius around the net outline's mean corner (press mm: a clamp hides it); a
rescan (``rescan`` K >= 1) only the requested ``regions`` (their ``corners_press_mm`` box,
grown by 100 mm), in the same press frame, shifted by ``--shift`` mm along z (a plate that
moved between the scans). It prints one line per step (``request ...``, ``scan ...``, ``gone
...``) and ends after ``--requests`` requests, or when no new request came within ``--idle`` s.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from scan_station import plate_in_press, write_ply

GROW_MM = 100.0
"""The station scans a requested region's box grown by this much (an overlap with the first scan)."""


def serve(folder: Path, design: Path, request_path: Path, args) -> None:
    """Answer one request."""
    request = json.loads(request_path.read_text())
    number = int(request.get("rescan", 0))
    print(f"request {request_path.name} cycle {request['cycle']} rescan {number} regions {len(request['regions'])}",
          flush=True)
    top = plate_in_press(design, Path(request["job"]["path"]), request["plate"]["thickness_mm"])
    rng = np.random.default_rng(args.seed + 10 * request["cycle"] + number)
    scan = top + rng.normal(0.0, 0.2, top.shape)
    if number == 0:
        centre = np.mean(request["plate"]["net_outline_press_mm"], axis=0)
        scan = scan[np.hypot(*(top[:, :2] - centre).T) > args.hole]
        print(f"hole at {centre[0]:.0f} {centre[1]:.0f}", flush=True)
        corner = np.asarray(request["mark"]["corner_press_mm"], dtype=float)
        nearest = top[np.argmin(np.linalg.norm(top[:, :2] - corner, axis=1))]
        Path(request["mark"]["path"]).write_text(
            json.dumps({"reference_mark_mm": [float(corner[0]), float(corner[1]), float(nearest[2])]}))
    else:
        wanted = np.zeros(len(scan), dtype=bool)
        for region in request["regions"]:
            box = np.asarray(region["corners_press_mm"], dtype=float)
            low, high = box.min(axis=0) - GROW_MM, box.max(axis=0) + GROW_MM
            wanted |= np.all((top[:, :2] >= low) & (top[:, :2] <= high), axis=1)
        scan = scan[wanted] + [0.0, 0.0, args.shift]
    path = Path(request["scan"]["path"])
    write_ply(path, scan)
    print(f"scan {path.name} {len(scan)} points", flush=True)
    start = time.monotonic()
    while request_path.exists() and time.monotonic() - start < 60.0:
        time.sleep(0.1)
    print(f"gone {request_path.name}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("folder", type=Path)
    parser.add_argument("design", type=Path)
    parser.add_argument("--hole", type=float, default=250.0)
    parser.add_argument("--shift", type=float, default=0.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--requests", type=int, default=2)
    parser.add_argument("--idle", type=float, default=40.0)
    args = parser.parse_args()
    served: set = set()
    last = time.monotonic()
    while len(served) < args.requests and time.monotonic() - last < args.idle:
        new = [p for p in sorted(args.folder.glob("*.scan-request.json")) if p.name not in served]
        if new:
            served.add(new[0].name)
            serve(args.folder, args.design, new[0], args)
            last = time.monotonic()
        time.sleep(0.1)
    print("done", flush=True)


if __name__ == "__main__":
    main()
