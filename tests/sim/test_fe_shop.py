"""The FE plate in the dry run's shop: pressed step by step by the simulated scanner, resumed from its file."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.core.progress import NULL_REPORTER
from mppf.core.scanner import PressedStep, ScanContext
from mppf.model.press import example_press_path, load_press
from mppf.sim.shop import STATE_FILE, SimulatedPlateScanner

T = 20.0
OUTLINE = [[-600.0, -400.0], [600.0, -400.0], [600.0, 400.0], [-600.0, 400.0]]


@pytest.fixture(scope="module")
def press():
    return load_press(example_press_path())


def _steps(press, cycle, depths_mm):
    """Steps of a cylinder along x pressed ``depth`` deep at the plate's ends."""
    x, y = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    active = (np.abs(x) <= 700) & (np.abs(y) <= 500)
    out = []
    for k, depth in enumerate(depths_mm, start=1):
        mid = T / 2 + depth * (x / 600.0) ** 2
        out.append(PressedStep(cycle, k, np.where(active, mid + T / 2, press.upper.park_mm),
                               np.where(active, mid - T / 2, press.lower.park_mm), active))
    return out


def _context(tmp_path, steps):
    last = steps[-1]
    return ScanContext(plate_id="S", work_dir=tmp_path, since_s=0.0, upper_mm=last.upper_mm, lower_mm=last.lower_mm,
                       active=last.active, steps=tuple(steps), reporter=NULL_REPORTER)


def _scanner(press):
    return SimulatedPlateScanner(press, T, OUTLINE, seed=4, plate_model="fe", noise_mm=0.0, occlusion_fraction=0.0,
                                 outlier_fraction=0.0, reference_mark=False)


def _bend(scanner):
    formed = scanner.plate.formed
    return float(formed.height_mm(np.array([525.0]), np.array([0.0]))[0] - formed.height_mm(np.array([0.0]),
                                                                                           np.array([0.0]))[0])


def test_fe_plate_without_ccx_says_how_to_install_it(press, monkeypatch):
    monkeypatch.setenv("MPPF_CCX", "ccx-that-is-not-installed")
    with pytest.raises(InputError, match="apt-get install calculix-ccx"):
        _scanner(press)


@pytest.mark.slow
def test_fe_plate_is_pressed_once_per_step_scanned_and_resumed_in_another_process(press, tmp_path):
    scanner = _scanner(press)
    first = _steps(press, 1, [20.0, 40.0])
    scan = scanner.acquire(1, _context(tmp_path, first))
    assert scan.exists() and scanner.pressed == [[1, 1], [1, 2]] and (tmp_path / STATE_FILE).exists()
    bend_1 = _bend(scanner)
    assert 0.0 < bend_1 < 40.0 * (525.0 / 600.0) ** 2  # bent, and sprang back part of the way
    # another process (a resumed dry run) takes the plate and its press steps from the work folder
    other = _scanner(press)
    other.acquire(2, _context(tmp_path, _steps(press, 2, [60.0])))
    assert other.pressed == [[1, 1], [1, 2], [2, 1]]
    assert _bend(other) > bend_1  # the plastic memory: pressed further from where it was


def test_demo_and_loop_with_fe_physics_without_ccx_exit_2_before_anything_is_done(tmp_path, capsys, monkeypatch):
    from mppf.cli import main

    monkeypatch.setenv("MPPF_CCX", "ccx-that-is-not-installed")
    assert main(["demo", "--out", str(tmp_path / "d"), "--physics", "fe"]) == 2
    assert "apt-get install calculix-ccx" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()
    design = flat = tmp_path / "unused.csv"
    assert main(["loop", str(design), str(flat), "--history", str(tmp_path / "h.sqlite"), "--physics", "fe"]) == 2
    assert "apt-get install calculix-ccx" in capsys.readouterr().err
    assert not (tmp_path / "h.sqlite").exists()
