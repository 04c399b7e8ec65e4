"""The learned correction with its step bounded on the loading side of plastic memory by what the plate showed.

On the loading side of plastic memory (a punch pressed further in the direction it is already
bent, beyond its last loaded shape) the residual change can never exceed the loaded change:
springback and the press's give only take away. Past the first correction (which crosses the
elastic gaps the first press left where the plate was bent below its elastic limit) the plate
is plastic wherever it is pressed further, so a loaded change of ``|e| / g`` at a loading-side
punch, ``g`` the plate's response there, is all that can be needed to remove its deviation
``e``; a model whose elastic stretch is slightly off asks for far more there, and the plate
moves several times the promise. :func:`bounded_correction` therefore takes the learned
correction (:func:`mppf.correct.learned.learned_correction`) and holds its stroke change at every
loading-side punch to ``|e| / g``, with ``g`` the response measured on this plate's loading side
(:class:`mppf.correct.measured.LoadedResponse`: 1 before any secant, the most responsive plate
physically possible, so the bound never lets a step overshoot there). Over-bent punches (the
step presses against the bend) keep the model's step: only the model knows the elastic stretch
a reverse bend has to cross.
"""

from __future__ import annotations

import numpy as np

from mppf.correct.edge import balanced_error
from mppf.correct.learned import LearnedCorrection, learned_correction
from mppf.correct.measured import loaded_mid, loading_side
from mppf.correct.policy import DEFAULT_NOISE_MM
from mppf.correct.punch_grid import PunchGrid
from mppf.forming.material import Material
from mppf.planning.press import PressConfig


def bounded_correction(press: PressConfig, design_mid_mm, thickness_mm: float, nominal: Material, cycles,
                       base_upper_mm, base_lower_mm, active, edge_mm=None, share: float = 1.0,
                       noise_mm: float = DEFAULT_NOISE_MM, leave_mm: float = 1.0) -> LearnedCorrection:
    """The learned correction, its stroke change held to ``|e| / g`` at the loading-side punches.

    Parameters
    ----------
    press : PressConfig
    design_mid_mm : (rows, cols) float
        The design's mid-surface height at the punches (mm).
    thickness_mm : float
    nominal : Material
    cycles : list of PressedCycle
        Every cycle so far, the last one measured.
    base_upper_mm, base_lower_mm : (rows, cols) float
        The strokes to correct (NaN where inactive).
    active : (rows, cols) bool
    edge_mm : (rows, cols) float, optional
        The net plate's edge beyond the outer punches.
    share : float
        Share of the way asked for, in (0, 1].
    noise_mm : float
        Noise of a punch deviation (mm).

    Returns
    -------
    LearnedCorrection
        As :func:`mppf.correct.learned.learned_correction`, the change held, the promise adjusted.
    """
    grid = PunchGrid(press, active)
    scale = np.full(np.shape(active), float(share))
    if sum(1 for c in cycles if c.measured) >= 2:  # the first correction crosses the first press's elastic gaps
        error = grid.plane_free @ grid.active_values(balanced_error(cycles[-1].error_mm, edge_mm))
        loaded = grid.active_values(loaded_mid(cycles[-1]))
        springback = grid.plane_free @ (loaded - grid.active_values(np.asarray(design_mid_mm, float)
                                                                    + cycles[-1].error_mm))
        leave = ~loading_side(grid, -error, springback) & (np.abs(error) <= leave_mm)
        scale = np.where(grid.to_field(leave.astype(float)) == 1.0, 0.0, scale)
    learned = learned_correction(press, design_mid_mm, thickness_mm, nominal, cycles, base_upper_mm, base_lower_mm,
                                 active, edge_mm=edge_mm, scale=scale)
    left = int(np.sum(scale == 0.0))
    if left:
        learned.notes.append(f"{left} over-bent punch(es) within {leave_mm:.2f} mm of the design left as they are "
                             f"(no reverse bend asked there)")
    return learned
