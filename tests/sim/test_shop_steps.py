"""The dry-run shop: the simulated plate is pressed with every step the press did, each once, in
order; its state survives in the work folder (a resumed dry run goes on with the same plate); an
interrupted step takes the tips part of the way."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.core.progress import NULL_REPORTER
from mppf.core.scanner import PressedStep, ScanContext
from mppf.model.press import example_press_path, load_press
from mppf.sim.shop import INTERRUPTED_SHARE, STATE_FILE, SimulatedPlateScanner

T = 20.0
OUTLINE = [[-1200.0, -800.0], [1200.0, -800.0], [1200.0, 800.0], [-1200.0, 800.0]]


@pytest.fixture(scope="module")
def press():
    return load_press(example_press_path())


def _steps(press, cycle, depths_mm):
    """Steps of a cylinder along x pressed ``depth`` deep at the plate's ends, read back as set."""
    x, y = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    active = (np.abs(x) <= 1300) & (np.abs(y) <= 900)
    out = []
    for k, depth in enumerate(depths_mm, start=1):
        mid = depth * (x / 1200.0) ** 2
        upper = np.where(active, mid + T / 2, press.upper.park_mm)
        lower = np.where(active, mid - T / 2, press.lower.park_mm)
        out.append(PressedStep(cycle, k, upper, lower, active))
    return out


def _context(tmp_path, steps):
    last = steps[-1]
    return ScanContext(plate_id="S", work_dir=tmp_path, since_s=0.0, upper_mm=last.upper_mm, lower_mm=last.lower_mm,
                       active=last.active, steps=tuple(steps), reporter=NULL_REPORTER)


def _scanner(press, model="steel"):
    return SimulatedPlateScanner(press, T, OUTLINE, seed=4, plate_model=model, noise_mm=0.0, occlusion_fraction=0.0,
                                 outlier_fraction=0.0, reference_mark=False)


def _centre_height(scanner):
    return float(scanner.plate.formed.height_mm(np.array([0.0]), np.array([0.0]))[0])


def test_every_step_is_pressed_once_and_a_resumed_run_goes_on_with_the_same_plate(press, tmp_path):
    scanner = _scanner(press)
    first = _steps(press, 1, [40.0, 80.0])
    scanner.acquire(1, _context(tmp_path, first))
    assert scanner.pressed == [[1, 1], [1, 2]] and (tmp_path / STATE_FILE).exists()
    # the same cycle's scan asked again (a resume): nothing is pressed again
    scanner.acquire(1, _context(tmp_path, first))
    assert scanner.pressed == [[1, 1], [1, 2]]
    # another process (a resumed dry run) takes the plate from the work folder
    other = _scanner(press)
    second = _steps(press, 2, [60.0])
    other.acquire(2, _context(tmp_path, second))
    assert other.pressed == [[1, 1], [1, 2], [2, 1]]
    scanner.acquire(2, _context(tmp_path, second))  # the first one catches up from the file, presses nothing
    assert scanner.pressed == other.pressed
    assert _centre_height(scanner) == pytest.approx(_centre_height(other), abs=1e-9)


def test_an_interrupted_step_takes_the_tips_part_of_the_way(press, tmp_path):
    whole, stopped = _scanner(press), _scanner(press)
    step = _steps(press, 1, [300.0])[0]  # well past the elastic limit, also half way
    whole.acquire(1, _context(tmp_path / "a", [step]))
    interrupted = PressedStep(1, 1, step.upper_mm, step.lower_mm, step.active, complete=False)
    stopped.acquire(1, _context(tmp_path / "b", [interrupted]))
    edge = np.array([1100.0]), np.array([0.0])
    bend_whole = float(whole.plate.formed.height_mm(*edge)[0]) - _centre_height(whole)
    bend_stopped = float(stopped.plate.formed.height_mm(*edge)[0]) - _centre_height(stopped)
    assert 0.0 < bend_stopped < bend_whole
    assert 0.0 < INTERRUPTED_SHARE < 1.0


@pytest.mark.parametrize("model", ["rubber", "planner"])
def test_an_unknown_plate_model_is_refused(press, model):
    """Two plates: the steel plate and the FE plate; the planner's old plate is retired."""
    with pytest.raises(InputError, match=f"unknown simulated plate model '{model}'") as refused:
        SimulatedPlateScanner(press, T, OUTLINE, plate_model=model)
    assert refused.value.hint == "use steel or fe"
