"""``mppf loop`` on a plate larger than the bed: a dry run presses it in sections; bad input exits 2."""

from __future__ import annotations

import numpy as np

from mppf.cli import main
from mppf.examples.analytic import cylinder_plate
from mppf.loop.history import History
from mppf.model.press import example_press_path


def _plate(folder, length_mm: float, radius_mm: float, spacing_mm: float = 100.0):
    design, flat = cylinder_plate(length_mm, 1500.0, radius_mm, spacing_mm=spacing_mm)
    np.savetxt(folder / "design.csv", design, delimiter=",")
    np.savetxt(folder / "flat.csv", flat, delimiter=",")
    return folder / "design.csv", folder / "flat.csv"


def _args(design, flat, home, *extra):
    return ["loop", str(design), str(flat), "--press", str(example_press_path()), "--thickness", "20",
            "--history", str(home / "history.sqlite"), "--time-scale", "200", *extra]


def test_a_dry_run_presses_a_plate_larger_than_the_bed_in_sections(tmp_path, capsys):
    design, flat = _plate(tmp_path, 3900.0, 10000.0)
    code = main(_args(design, flat, tmp_path, "--max-cycles", "1"))
    err = capsys.readouterr().err
    assert "does not fit" not in err and "Traceback" not in err
    assert "section 2: place the plate with mark 2a" in err and "(section 2 of 2, step 1 of" in err
    with History(tmp_path / "history.sqlite") as history:
        (plate,) = history.plates()
        (cycle,) = history.cycles(plate.plate_id)
    assert cycle.state == "done" and cycle.decision == "max_cycles" and code != 2
    assert cycle.steps_done == len(cycle.steps) > 2
    assert [s["index"] for s in cycle.comparison["sections"]] == [1, 2]


def test_a_plate_too_long_for_the_sections_exits_2_with_one_message(tmp_path, capsys):
    design, flat = _plate(tmp_path, 75000.0, 5e6, spacing_mm=250.0)
    assert main(_args(design, flat, tmp_path)) == 2
    err = capsys.readouterr().err
    assert "would need more than 20 sections" in err and "Traceback" not in err
    with History(tmp_path / "history.sqlite") as history:
        assert history.plates() == []
