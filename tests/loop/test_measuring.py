"""Measuring a cycle: the reference mark next to a scan, read and checked."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.model.press import example_press_path, load_press


def test_reference_mark_file_is_read_and_a_bad_one_refused(tmp_path):
    from mppf.measure.mark import reference_mark
    from mppf.model.job import Job
    from mppf.model.job_parts import PlateLayout, StepStrokes, reference_corner_xy

    press = load_press(example_press_path())
    active = np.zeros(press.shape, dtype=bool)
    active[:3, :3] = True
    steps = [StepStrokes(np.where(active, 20.0, np.nan), np.where(active, 0.0, np.nan), active)]
    outline = [[-500.0, -300.0], [500.0, -300.0], [500.0, 300.0], [-500.0, 300.0]]
    job = Job(press=press, thickness_mm=20.0, steps=steps, tf_press_design=np.eye(4), tf_press_flat=np.eye(4),
              layout=PlateLayout(outline, outline))
    assert np.allclose(reference_corner_xy(outline), [-500.0, -300.0])
    gx, gy = np.meshgrid(np.linspace(-500, 500, 11), np.linspace(-300, 300, 7))
    design = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    scan = tmp_path / "scan.ply"
    assert reference_mark(scan, design, job) is None  # no mark file: register without it
    Path(str(scan) + ".mark.json").write_text(json.dumps({"reference_mark_mm": [1.0, 2.0, 3.0]}))
    measured, on_design = reference_mark(scan, design, job)
    assert np.allclose(measured, [1.0, 2.0, 3.0]) and np.allclose(on_design, [-500.0, -300.0, 0.0])
    Path(str(scan) + ".mark.json").write_text(json.dumps({"reference_mark_mm": [1.0, 2.0]}))
    with pytest.raises(InputError, match="reference mark"):
        reference_mark(scan, design, job)
