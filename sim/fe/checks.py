"""Closed-form check of the FE plate through its thickness: a wide plate bent to a cylinder and released.

A strip of the plate (length ``length_mm`` along x, one element wide, ``layers`` C3D8I through the
thickness, the material of :func:`mppf.sim.fe.deck.model_lines`) is bent to a uniform curvature
``kappa`` by rotating its end face (x = L: u_x = -kappa L (z - t/2), x = 0 held by symmetry),
``wide=True`` holding u_y = 0 everywhere (plane strain: the middle of a wide plate), then released
(the end face free). The residual curvature is read from the end face's rotation. Small
displacements (no NLGEOM): the check is of the through-thickness law (integration through the thickness, the
plastic flow and the elastic unloading), the closed form of docs/simulator-fe.md.
"""

from __future__ import annotations

import numpy as np
from mppf.sim.fe.ccx import run_ccx
from mppf.sim.fe.deck import flow_curve
from mppf.sim.fe.results import last_of_steps, read_frd


def bending_deck(steel, thickness_mm: float, kappa_per_mm: float, *, layers: int = 4, length_mm: float = 100.0,
                 width_mm: float = 100.0, wide: bool = True) -> str:
    """The deck of the strip bent to ``kappa_per_mm`` (step 1) and released (step 2)."""
    z = np.linspace(0.0, thickness_mm, layers + 1)
    nodes = [(x, y, zz) for zz in z for y in (0.0, width_mm) for x in (0.0, length_mm)]
    ids = np.arange(len(nodes)).reshape(layers + 1, 2, 2) + 1
    out = ["*NODE"] + [f"{i + 1},{x:.6f},{y:.6f},{zz:.6f}" for i, (x, y, zz) in enumerate(nodes)]
    out.append("*ELEMENT, TYPE=C3D8I, ELSET=STRIP")
    for k in range(layers):
        c = ids[k:k + 2]
        out.append(f"{k + 1}," + ",".join(str(int(v)) for v in (c[0, 0, 0], c[0, 0, 1], c[0, 1, 1], c[0, 1, 0],
                                                                  c[1, 0, 0], c[1, 0, 1], c[1, 1, 1], c[1, 1, 0])))
    out += ["*MATERIAL, NAME=STEEL", "*ELASTIC", f"{steel.youngs_modulus_mpa:.6g},{steel.poisson:.6g}",
            "*PLASTIC, HARDENING=KINEMATIC"] + [f"{s:.6f},{a:.6g}" for s, a in flow_curve(steel, 1.0)]
    out += ["*SOLID SECTION, ELSET=STRIP, MATERIAL=STEEL"]
    left, right = ids[:, :, 0].ravel(), ids[:, :, 1].ravel()
    fixed = ["*BOUNDARY"] + [f"{int(n)},1,1,0." for n in left] + [f"{int(ids[0, 0, 0])},3,3,0."]
    fixed += [f"{int(n)},2,2,0." for n in ids.ravel()] if wide else [f"{int(ids[0, 0, 0])},2,2,0."]
    out += fixed
    bend = [f"{int(n)},1,1,{-kappa_per_mm * length_mm * (nodes[n - 1][2] - 0.5 * thickness_mm):.8f}" for n in right]
    out += ["*STEP, INC=1000", "*STATIC", "0.1,1.,1e-6,0.1", "*BOUNDARY"] + bend
    out += ["*NODE FILE", "U", "*RESTART, WRITE", "*END STEP"]
    out += ["*STEP, INC=1000", "*STATIC", "0.1,1.,1e-6,0.1", "*BOUNDARY, OP=NEW"] + fixed[1:]
    out += ["*NODE FILE", "U", "*RESTART, WRITE", "*END STEP"]
    return "\n".join(out) + "\n"


def residual_curvature(steel, thickness_mm: float, kappa_per_mm: float, **options) -> float:
    """Curvature of the strip after it is bent to ``kappa_per_mm`` and released (ccx), 1/mm."""
    run = run_ccx(bending_deck(steel, thickness_mm, kappa_per_mm, **options))
    free = last_of_steps(read_frd(run.frd))[2]
    length = options.get("length_mm", 100.0)
    layers = options.get("layers", 4)
    z = np.repeat(np.linspace(0.0, thickness_mm, layers + 1), 4)
    on_right = np.zeros(len(z), dtype=bool)
    on_right[1::2] = True  # x = L is every second node
    u = np.zeros(len(z))
    u[free.nodes - 1] = free.values[:, 0]
    slope = np.polyfit(z[on_right] - 0.5 * thickness_mm, u[on_right], 1)[0]
    return -slope / length


def moment_curvature_residual(steel, thickness_mm: float, kappa_per_mm: float, *, wide: bool = True) -> float:
    """Closed-form residual curvature of an elastic-perfectly-plastic plate, 1/mm.

    ``M(kappa) = M_p (1 - (kappa_e / kappa)^2 / 3)`` for ``kappa > kappa_e``, elastic below;
    unloading is elastic: ``kappa_r = kappa - M / (E' I)``. Wide plate (plane strain):
    ``E' = E / (1 - nu^2)`` and the plane-strain yield stress ``2 sy / sqrt(3)``; a strip:
    ``E`` and ``sy``. Per unit width, ``I = t^3 / 12``, ``M_p = sy' t^2 / 4``,
    ``kappa_e = 2 sy' / (E' t)``.
    """
    e = steel.youngs_modulus_mpa / (1.0 - steel.poisson ** 2) if wide else steel.youngs_modulus_mpa
    sy = steel.yield_stress_mpa * (2.0 / np.sqrt(3.0) if wide else 1.0)
    kappa_e = 2.0 * sy / (e * thickness_mm)
    if kappa_per_mm <= kappa_e:
        return 0.0
    moment = sy * thickness_mm ** 2 / 4.0 * (1.0 - (kappa_e / kappa_per_mm) ** 2 / 3.0)
    return kappa_per_mm - moment / (e * thickness_mm ** 3 / 12.0)
