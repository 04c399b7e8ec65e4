"""Mesh study of the FE plate: a plate pressed to a cylinder, free curvature and cost per mesh.

A 1.5 x 1.2 m plate, 20 mm, nominal steel without scatter, every pair of the example press over
it holding the mid-surface on z = t/2 - x^2 / (2 R) (R = 4 m: well into the plastic range), punch
compliance 0.01 mm/kN, no frame compliance; after springback the radius of curvature is fitted
over the middle of the plate (x within 600 mm of the centre, y = 0). Prints a markdown table:
cells per pitch, layers, nodes, loaded and free radius, ccx wall time, and the finite-difference
plate's for reference. About 5 minutes on the shared machine.

    python3 benchmarks/bench_fe_mesh.py
"""

from __future__ import annotations

import time

import numpy as np

from mppf.model.press import example_press_path, load_press
from mppf.sim.fe.plate import FEPlate
from mppf.sim.plate.contact import Compliance
from mppf.sim.plate.material import PlateSteel
from mppf.sim.plate.plate import SteelPlate
from mppf.sim.plate.scatter import NO_SCATTER

T_MM, RADIUS_MM = 20.0, 4000.0
OUTLINE = np.array([[-750.0, -600.0], [750.0, -600.0], [750.0, 600.0], [-750.0, 600.0]])
MESHES = ((1, 2), (1, 4), (2, 2), (2, 4), (3, 4))
COMPLIANCE = Compliance(frame_mm_per_mn=0.0, punch_mm_per_kn=0.01)
STEEL = PlateSteel(transverse_yield_ratio=1.0)


def radius(formed, loaded: bool) -> float:
    """Radius of curvature (mm) of the mid-surface along y = 0, fitted for |x| <= 600 mm."""
    x = np.linspace(-600.0, 600.0, 25)
    z = formed.height_mm(x, 0 * x, loaded=loaded)
    return float(-1.0 / (2.0 * np.polyfit(x, z, 2)[0]))


def main() -> None:
    press = load_press(example_press_path())
    x, _ = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    mid = 0.5 * T_MM - x ** 2 / (2.0 * RADIUS_MM)
    tips = mid + 0.5 * T_MM, mid - 0.5 * T_MM, np.ones(press.shape, dtype=bool)
    print("| mesh | nodes | loaded R (m) | free R (m) | time (s) |")
    print("|---|---|---|---|---|")
    start = time.monotonic()
    fd = SteelPlate(press, OUTLINE, T_MM, STEEL, seed=None, scatter=NO_SCATTER, compliance=COMPLIANCE)
    formed = fd.press_step(*tips)
    print(f"| finite-difference plate (50 mm B-spline grid) | - | {radius(formed, True) / 1e3:.3f} | "
          f"{radius(formed, False) / 1e3:.3f} | {time.monotonic() - start:.1f} |", flush=True)
    for cells, layers in MESHES:
        plate = FEPlate(press, OUTLINE, T_MM, STEEL, seed=None, scatter=NO_SCATTER, compliance=COMPLIANCE,
                        cells_per_pitch=cells, layers=layers)
        formed = plate.press_step(*tips)
        print(f"| FE {cells} cell(s) per pitch, {layers} layers | {plate.mesh.node_count} | "
              f"{radius(formed, True) / 1e3:.3f} | {radius(formed, False) / 1e3:.3f} | {plate.last_seconds:.1f} |",
              flush=True)


if __name__ == "__main__":
    main()
