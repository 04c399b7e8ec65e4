"""Mesh study of the FE plate on a hull plate's first cycle: is the FE-vs-FD form-max gap physics or the mesh?

Plans a bundled hull plate (``bench_fe.planned``: 20 mm steel, springback pre-compensated, the
example press), presses its first cycle on the FE plate with one mesh (``--cells`` element edges
between punch axes, ``--layers`` C3D8I through the thickness), scans it without noise and compares
it with the design as ``mppf compare --job`` does. Prints one markdown row: mesh, nodes, form max,
RMS, the median springback at the punch axes that pushed (loaded minus free mid-surface height, mm),
the free plate's height range, ccx wall time. One mesh per run, so that each part stays under
10 minutes on the shared machine; ``--steps last`` presses the cycle's last step only, straight
from the flat plate (one ccx run).

    python3 benchmarks/bench_fe_mesh_hull.py --plate P2_bow_flare --cells 2 --layers 4 --steps last
    python3 benchmarks/bench_fe_mesh_hull.py --plate P2_bow_flare --physics fd
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from bench_fe import PLATES, first_cycle, mppf, planned

from mppf.core.errors import MppfError


def springback_mm(plate) -> tuple[float, float]:
    """Springback at the punch axes that pushed: loaded minus free mid-surface height with its best-fit plane (the
    rigid tilt of the release) removed; its median and largest magnitude, mm."""
    formed = plate.formed
    x, y = formed.contact_xyz_mm[:, 0], formed.contact_xyz_mm[:, 1]
    back = formed.height_mm(x, y, loaded=True) - formed.height_mm(x, y, loaded=False)
    basis = np.column_stack([np.ones_like(x), x, y])
    back = back - basis @ np.linalg.lstsq(basis, back, rcond=None)[0]
    return float(np.median(np.abs(back))), float(np.abs(back).max())


def small_deflection() -> None:
    """Run every ccx deck of this process without ``NLGEOM`` (the study's physics switch, not the product's)."""
    import mppf.sim.fe.plate as fe_plate

    run = fe_plate.run_ccx

    def linear(deck: str, **kwargs):
        return run(deck.replace("*STEP, NLGEOM,", "*STEP,"), **kwargs)

    fe_plate.run_ccx = linear


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plate", default="P2_bow_flare", choices=PLATES)
    parser.add_argument("--physics", default="fe", choices=["fd", "fe"])
    parser.add_argument("--cells", type=int, default=1)
    parser.add_argument("--layers", type=int, default=4)
    parser.add_argument("--steps", choices=["all", "last"], default="last")
    parser.add_argument("--out", type=Path, default=Path("/tmp/bench-fe"))
    parser.add_argument("--header", action="store_true", help="print the table's header first")
    parser.add_argument("--small-deflection", action="store_true",
                        help="the FE plate without NLGEOM (small deflections: bending and membrane uncoupled), to "
                             "tell the membrane physics from the mesh")
    args = parser.parse_args()
    if args.small_deflection:
        small_deflection()
    args.out.mkdir(parents=True, exist_ok=True)
    if args.header:
        print("| plate | physics | mesh | pressed | nodes | form max (mm) | RMS (mm) | springback at the axes, median "
              "(mm) | springback, largest (mm) | time (s) |")
        print("|---|---|---|---|---|---|---|---|---|---|")
    design, flat, job = planned(args.plate, args.out)
    options = {"cells_per_pitch": args.cells, "layers": args.layers} if args.physics == "fe" else None
    mesh = f"{args.cells} cell(s)/pitch, {args.layers} layers" if options else "50 mm B-spline grid"
    mesh += ", small deflection" if args.small_deflection else ""
    folder = args.out / (f"{args.plate}-{args.physics}-{args.cells}x{args.layers}-{args.steps}"
                         + ("-small" if args.small_deflection else ""))
    try:
        scan, seconds = first_cycle(job, flat, args.physics, folder, 0, args.steps == "last", options)
    except MppfError as exc:
        print(f"| {args.plate} | {args.physics} | {mesh} | {args.steps} | | failed: {str(exc).split(';')[0]} | | | | |")
        return
    plate = first_cycle.plate
    nodes = plate.mesh.node_count if options else "-"
    back, most = springback_mm(plate)
    doc = json.loads(mppf("compare", str(design), str(scan), "--job", str(job), "--json").stdout or "{}")
    print(f"| {args.plate} | {args.physics} | {mesh} | {args.steps} | {nodes} | {doc.get('form_max_abs_mm', np.nan):.1f} | "
          f"{doc.get('form_rms_mm', np.nan):.1f} | {back:.1f} | {most:.0f} | {seconds:.0f} |", flush=True)


if __name__ == "__main__":
    main()
