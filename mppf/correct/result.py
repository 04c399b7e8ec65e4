"""What the planner's stroke compensation exchanges: the corrected strokes and the model step's wanted
change. Punch grids are (rows, cols) float mm, NaN where a punch
is inactive or no value is known."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mppf.core.errors import InputError
from mppf.model.press import PressConfig


@dataclass(frozen=True, eq=False)
class Correction:
    """Corrected strokes for the next cycle.

    Attributes
    ----------
    upper_mm, lower_mm : (rows, cols) float
        Corrected tip heights (NaN where the punch is inactive).
    gain : (rows, cols) float
        The model step's gain per punch (NaN where inactive).
    applied_mm : (rows, cols) float
        Correction added to both matrices (0 where inactive or no error known).
    clipped : (rows, cols) bool
        Where the dimpling or stroke limit reduced the correction.
    notes : list of str
        What happened, for the operator and the history.
    """

    upper_mm: np.ndarray
    lower_mm: np.ndarray
    gain: np.ndarray
    applied_mm: np.ndarray
    clipped: np.ndarray
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True, eq=False)
class Step:
    """The change the springback-model step wants, before smoothing and limits.

    Attributes
    ----------
    wanted_mm : (rows, cols) float
        Change of both matrices (0 where nothing is known).
    known : (rows, cols) bool
        Punches the step acts on.
    gain : (rows, cols) float
        The gain per punch (NaN where inactive).
    notes : list of str
    """

    wanted_mm: np.ndarray
    known: np.ndarray
    gain: np.ndarray
    notes: list[str] = field(default_factory=list)


def punch_grid(press: PressConfig, values, name: str) -> np.ndarray:
    """``values`` as a (rows, cols) float array of the press's punch grid.

    Raises
    ------
    InputError
        Another shape.
    """
    arr = np.asarray(values, dtype=float)
    if arr.shape != press.shape:
        raise InputError(f"{name} has shape {arr.shape}, the press has {press.shape}")
    return arr
