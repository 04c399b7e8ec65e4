"""CalculiX input decks of the FE plate: the model and the steps of its press steps.

The model:

- the plate's C3D8I hexahedra (:mod:`mppf.sim.fe.mesh`), one ``*MATERIAL`` per yield-scatter bin
  (elastic, ``*PLASTIC, HARDENING=KINEMATIC`` on the steel's flow curve scaled by the bin's yield
  factor: reverse bending yields at the Bauschinger-lowered stress);
- for each punch pair over the plate a lower and an upper tip node, coincident with the plate's
  bottom / top node on the pair's axis, joined to it by a unilateral ``GAPUNI`` element along z
  whose stiffness is the punch's compliance (``1 / c_punch``): the ball pushes, never pulls;
- the plate's in-plane rigid motion held at two mid-thickness nodes (x, y at one, y at another),
  the tips free only along z.

A press step is three ``*STEP, NLGEOM`` (large deflection: bending and membrane coupled), each
giving every tip its height (``*BOUNDARY, OP=NEW``):

1. ``APPROACH`` (not before the first press step, where the flat stroke set touches the flat plate):
   the tips move to touch the plate as it lies, while the three nodes of the step before's release
   still hold it (next to no force);
2. ``LOAD``: the tips travel to the step's tip heights (parked pairs to their park heights) while
   the gaps close and open;
3. ``RELEASE``: three mid-thickness nodes far apart (:func:`hold_nodes`, fresh ones in every press
   step) are frozen where the load left them (``*BOUNDARY, FIXED``: statically determinate, they
   carry no force once the tips are gone) and every tip retracts :data:`RETRACT_MM`; the gaps open
   one by one as the plate springs back.

A run replays every press step of the plate from the flat plate (:func:`history_deck`); the
displacements of the last one's load and release are written to the .frd file.
"""

from __future__ import annotations

import numpy as np

RETRACT_MM = 300.0
"""How far the tips retract from the plate in the release step."""

FLOW_STRAINS = (0.0, 0.001, 0.002, 0.005, 0.01, 0.02, 0.04, 0.08, 0.15, 0.3, 1.0)
"""Equivalent plastic strains of the tabulated flow curve."""

YIELD_BIN = 0.005
"""Width of the yield-factor bins (one material each)."""

RELEASE_YIELD_FACTOR = 20.0
"""Factor on the flow curves while the plate is released (the release is elastic, see :func:`plastic_change`)."""

RELEASE_INCREMENT = 1.0
"""First increment of the release, share of the step (the whole step; ccx cuts it back where the gaps opening
need it): the release is elastic, so it converges in a few large increments (the P2 bow flare's second try-out
run: 172 Newton iterations instead of 323 with a first increment of 0.05, the same plate within 0.003 mm;
benchmarks/results/2026-12-06-fe-tryout-speed.md)."""

LATER_LOAD_INCREMENT = 0.02
"""First increment of the load of a press step after the first (share of the step): the tips start on the formed
plate and contacts close at once; a quarter of the step was cut back three times to 1/256 before it converged
(the P2 bow flare's second press step: 145 Newton iterations instead of 172, the same plate within 0.03 mm)."""

MAX_CUTBACKS = 9
"""Cutbacks ccx may make of one increment (its default is 5; ``*CONTROLS, PARAMETERS=TIME INCREMENTATION``).

The release retracts the tips :data:`RETRACT_MM` over the step: after 5 cutbacks by 4 its first increment still
moved them 0.29 mm, more than the compression of most gaps (their force over the punch stiffness: 29 kN at
1e5 N/mm), so every gap opened in that increment whatever its size and the whole springback load of a plate
pressed with a large stroke change came at once: "too many cutbacks" in the release of the P2, P3, K2 and K3
hull plates' second cycle (benchmarks/results/2026-12-06-fe-release.md). 9 cutbacks reach 300 mm / 4^9 =
1.1 um (the step's smallest increment, 1e-6, lies just below): the gaps open one by one again. An increment
that converges within 5 cutbacks is computed exactly as before."""

STEPS_PER_PRESS = 3
"""Steps of one press step after the first (approach, load, release); the first has two."""


def _lines(rows) -> list[str]:
    return [",".join(f"{v:.6f}" if isinstance(v, float) else str(v) for v in row) for row in rows]


def flow_curve(steel, yield_factor: float) -> np.ndarray:
    """Tabulated flow curve (k, 2): stress MPa, equivalent plastic strain.

    Parameters
    ----------
    steel : PlateSteel
        Its ``flow_stress_mpa(alpha, yield_factor)`` (Swift + linear hardening).
    yield_factor : float
        Local factor on the initial yield stress.
    """
    alpha = np.array(FLOW_STRAINS)
    stress = np.asarray(steel.flow_stress_mpa(alpha, np.full(len(alpha), yield_factor))[0], dtype=float)
    return np.column_stack([stress, alpha])


def materials(steel, yield_factor) -> list[tuple[str, np.ndarray]]:
    """The plate's materials: (name, flow curve (k, 2)) of each yield-factor bin, in the order of :func:`model_lines`."""
    bins = np.round((np.asarray(yield_factor) - 1.0) / YIELD_BIN).astype(int)
    return [(f"STEEL{b - bins.min()}", flow_curve(steel, 1.0 + YIELD_BIN * b)) for b in np.unique(bins)]


def plastic_change(table, factor: float) -> list[str]:
    """``*CHANGE MATERIAL`` / ``*CHANGE PLASTIC`` lines setting every flow curve to ``factor`` times its own.

    The release step raises the curves :data:`RELEASE_YIELD_FACTOR` times: its stresses stay inside
    the yield surface, so it is elastic from its first iteration (with the elastic-plastic tangent of
    the loaded plate the first Newton step of a strongly bent plate overshoots by 100 mm and ccx
    gives up); the next step restores them (back stresses and plastic strains kept). Reverse
    yielding during springback is therefore not modelled; in the next press step it is.
    """
    out = []
    for name, curve in table:
        out += [f"*CHANGE MATERIAL, NAME={name}", "*CHANGE PLASTIC, HARDENING=KINEMATIC"]
        out += [f"{factor * stress:.6f},{strain:.6g}" for stress, strain in curve]
    return out


def model_lines(mesh, steel, yield_factor, punch_stiffness_n_mm: float) -> list[str]:
    """The model definition (nodes, elements, gaps, materials, fixed supports).

    Parameters
    ----------
    mesh : PlateMesh
    steel : PlateSteel
        The plate's true steel.
    yield_factor : (e,) float
        Yield factor of each element.
    punch_stiffness_n_mm : float
        Stiffness of a ball and its punch (the gap elements), N/mm.

    Returns
    -------
    list of str
    """
    n, m = mesh.node_count, len(mesh.bottom)
    lower, upper = tip_nodes(mesh)
    out = ["*HEADING", "mppf FE plate (mppf.sim.fe)", "*NODE"]
    out += _lines([(i + 1, *map(float, p)) for i, p in enumerate(mesh.xyz_mm)])
    out += _lines([(int(lower[i]), *map(float, mesh.xyz_mm[mesh.bottom[i] - 1])) for i in range(m)])
    out += _lines([(int(upper[i]), *map(float, mesh.xyz_mm[mesh.top[i] - 1])) for i in range(m)])
    bins = np.round((np.asarray(yield_factor) - 1.0) / YIELD_BIN).astype(int)
    for b in np.unique(bins):
        ids = np.nonzero(bins == b)[0] + 1
        out.append(f"*ELEMENT, TYPE=C3D8I, ELSET=PLATE{b - bins.min()}")
        out += _lines([(int(e), *map(int, mesh.hexes[e - 1])) for e in ids])
    first_gap = len(mesh.hexes) + 1
    out.append("*ELEMENT, TYPE=GAPUNI, ELSET=GAPS")
    out += _lines([(first_gap + i, int(lower[i]), int(mesh.bottom[i])) for i in range(m)])
    out += _lines([(first_gap + m + i, int(mesh.top[i]), int(upper[i])) for i in range(m)])
    out += ["*GAP, ELSET=GAPS", f"0.,0.,0.,1.,,{punch_stiffness_n_mm:.6g}"]
    out += ["*NSET, NSET=TIPS"] + [str(int(v)) for v in np.concatenate([lower, upper])]
    out += ["*NSET, NSET=PLATEN, GENERATE", f"1,{n},1"]
    for (name, curve), b in zip(materials(steel, yield_factor), np.unique(bins)):
        out += [f"*MATERIAL, NAME={name}", "*ELASTIC", f"{steel.youngs_modulus_mpa:.6g},{steel.poisson:.6g}",
                "*PLASTIC, HARDENING=KINEMATIC"]
        out += [f"{stress:.6f},{strain:.6g}" for stress, strain in curve]
        out += [f"*SOLID SECTION, ELSET=PLATE{b - bins.min()}, MATERIAL={name}"]
    return out


def tip_nodes(mesh) -> tuple[np.ndarray, np.ndarray]:
    """Node ids (m,) of the lower and upper tips (after the plate's nodes)."""
    n, m = mesh.node_count, len(mesh.bottom)
    return n + 1 + np.arange(m), n + 1 + m + np.arange(m)


def planar_holds(mesh) -> list[str]:
    """Boundary lines of the in-plane supports and the tips' x, y (every step repeats them).

    The mid-thickness node on the punch axis nearest the plate's centre is held in x and y, the
    one farthest from it on the same punch row in y only (the plate may still shrink along x as
    it bends).
    """
    xy = mesh.punch_xy_mm
    a = int(np.argmin(np.linalg.norm(xy - xy.mean(axis=0), axis=1)))
    row = np.nonzero(mesh.punch_index[:, 0] == mesh.punch_index[a, 0])[0]
    b = int(row[np.argmax(np.abs(xy[row, 0] - xy[a, 0]))])
    if b == a:  # a single pair on that row: the farthest pair, held across the line between them
        b = int(np.argmax(np.linalg.norm(xy - xy[a], axis=1)))
    along_x = abs(xy[b, 0] - xy[a, 0]) >= abs(xy[b, 1] - xy[a, 1])
    dof = "2,2" if along_x else "1,1"
    return ["TIPS,1,2,0.", f"{int(mesh.middle[a])},1,2,0.", f"{int(mesh.middle[b])},{dof},0."]


def hold_nodes(mesh, press_step: int) -> np.ndarray:
    """Mid-thickness node ids (3,) that hold the plate statically determinate in a press step's release.

    Near the corners of the largest triangle of punch axes over the plate; each press step takes
    the next-nearest node column to each corner, so no node is held in two releases (a
    ``*BOUNDARY, FIXED`` on a node held before froze a stale value in ccx 2.20).

    Parameters
    ----------
    mesh : PlateMesh
    press_step : int
        0 for the plate's first press step, 1 for the next...
    """
    xy = mesh.punch_xy_mm
    d = np.linalg.norm(xy[:, None, :] - xy[None, :, :], axis=2)
    a, b = np.unravel_index(np.argmax(d), d.shape)
    ab = xy[b] - xy[a]
    c = int(np.argmax(np.abs(ab[0] * (xy[:, 1] - xy[a, 1]) - ab[1] * (xy[:, 0] - xy[a, 0]))))
    mid = mesh.column[..., mesh.layers // 2]
    jj, ii = np.nonzero(mid > 0)
    columns = np.column_stack([mesh.x_mm[ii], mesh.y_mm[jj]])
    nodes = []
    for corner in xy[[a, b, c]]:
        order = np.argsort(np.linalg.norm(columns - corner, axis=1), kind="stable")
        nodes.append(int(mid[jj[order[press_step % len(order)]], ii[order[press_step % len(order)]]]))
    return np.array(nodes)


def step_lines(mesh, name: str, tips_z_mm: np.ndarray, *, holds=None, initial_increment: float = 0.25,
               max_increment: float = 0.5, output: bool = True, plastic: list[str] = ()) -> list[str]:
    """One static step: every tip to its height (``*BOUNDARY, OP=NEW``, the in-plane supports repeated).

    Parameters
    ----------
    mesh : PlateMesh
    name : str
        A comment naming the step.
    tips_z_mm : (2 m,) float
        Absolute heights of the lower tips, then the upper tips, mm (their nodes' z).
    holds : (3,) int, optional
        Nodes frozen in z where the step before left them (``*BOUNDARY, FIXED``).
    initial_increment, max_increment : float
        First and largest increment, share of the step.
    output : bool
        Write the plate's displacements (.frd) at the end of the step.
    plastic : list of str
        :func:`plastic_change` lines of the step.
    """
    lower, upper = tip_nodes(mesh)
    start = np.concatenate([mesh.xyz_mm[mesh.bottom - 1, 2], mesh.xyz_mm[mesh.top - 1, 2]])
    move = np.asarray(tips_z_mm, dtype=float) - start
    out = [f"** {name}", "*STEP, NLGEOM, INC=1000", "*STATIC", f"{initial_increment:.6g},1.,1e-6,{max_increment:.6g}",
           *plastic]
    # the approach carries next to no force: its residuals are judged against 1 N, not their own mean;
    # the other steps start their time-average force at 1 kN, so that a step with next to no force
    # (flat strokes on a flat plate) converges by the zero-force criterion (1e-5 of it)
    out += ["*CONTROLS, RESET", "*CONTROLS, PARAMETERS=FIELD"]
    out += ["0.005,0.01,,1."] if name == "APPROACH" else ["0.005,0.01,1000.,,0.02,1e-5,1e-3,1e-8"]
    # more iterations before an increment is cut back: contacts opening and closing need a few
    # and more cutbacks than ccx's default (:data:`MAX_CUTBACKS`: the release's gaps must open one by one)
    out += ["*CONTROLS, PARAMETERS=TIME INCREMENTATION", f"8,10,9,200,10,4,0,{MAX_CUTBACKS}"]
    out += ["*BOUNDARY, OP=NEW"] + planar_holds(mesh)
    out += [f"{int(node)},3,3,{dz:.6f}" for node, dz in zip(np.concatenate([lower, upper]), move)]
    if holds is not None:
        out += ["*BOUNDARY, FIXED"] + [f"{int(node)},3,3" for node in holds]
    if output:
        out += ["*NODE FILE, NSET=PLATEN, FREQUENCY=1000", "U"]
    out += ["*END STEP"]
    return out


def press_step_lines(mesh, tips_z_mm, index: int, touch_z_mm=None, *, output: bool = True,
                     table=()) -> list[str]:
    """The steps of one press step: approach (unless the first), load, release.

    Parameters
    ----------
    mesh : PlateMesh
    tips_z_mm : (2 m,) float
        The step's tip heights (absolute, lower then upper), mm.
    index : int
        Which press step of the plate this is (0: the first): picks its release holds (:func:`hold_nodes`).
    touch_z_mm : (2 m,) float, optional
        Tip heights touching the plate as the step before left it (the approach, the plate still
        held by that step's release holds); None for the first press step (the flat stroke set
        touches the flat plate).
    output : bool
        Write the displacements at the end of the load and the release.
    table : list of (name, flow curve)
        The plate's materials (:func:`materials`): the release raises their curves, the next step
        restores them (:func:`plastic_change`).
    """
    out = []
    restore = plastic_change(table, 1.0)
    if touch_z_mm is not None:
        out += step_lines(mesh, "APPROACH", touch_z_mm, holds=hold_nodes(mesh, index - 1), initial_increment=1.0,
                          output=False, plastic=restore)
        restore = []
    out += step_lines(mesh, "LOAD", tips_z_mm, output=output, plastic=restore if index > 0 else [],
                      initial_increment=0.25 if index == 0 else LATER_LOAD_INCREMENT)
    m = len(mesh.bottom)
    retracted = np.asarray(tips_z_mm, dtype=float) + np.concatenate([np.full(m, -RETRACT_MM), np.full(m, RETRACT_MM)])
    out += step_lines(mesh, "RELEASE", retracted, holds=hold_nodes(mesh, index), initial_increment=RELEASE_INCREMENT,
                      max_increment=1.0, output=output, plastic=plastic_change(table, RELEASE_YIELD_FACTOR))
    return out


def history_deck(mesh, model: list[str], history: list[tuple], table=()) -> str:
    """The deck replaying a plate's press steps from the flat plate: the model, then every step.

    Parameters
    ----------
    mesh : PlateMesh
    model : list of str
        :func:`model_lines`.
    history : list of (tips_z_mm, touch_z_mm)
        Every press step so far and the new one, in order: its tips (2 m,) and the tips touching
        the plate before it (2 m,; ignored for the first). Only the last writes displacements.
    table : list of (name, flow curve)
        The plate's materials (:func:`materials`).

    Returns
    -------
    str
    """
    out = list(model)
    for k, (tips, touch) in enumerate(history):
        out += press_step_lines(mesh, tips, k, None if k == 0 else touch, output=k == len(history) - 1,
                                table=table)
    return "\n".join(out) + "\n"


def step_count(press_steps: int) -> int:
    """Analysis steps of a deck of ``press_steps`` press steps (2 for the first, 3 for each later one)."""
    return 0 if press_steps == 0 else 2 + STEPS_PER_PRESS * (press_steps - 1)
