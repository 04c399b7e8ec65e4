"""The planned strokes of real plates stay those computed before the contact solve was made faster.

``data/stroke_reference.npz`` holds every step's tip heights (mm, NaN where inactive) of two bundled
hull patches (one piece) and the 9 m KCS stern plate (six sections), planned by the code as it was
before the batched contact solve (``python tests/planning/test_stroke_reference.py`` writes it again:
only do so on purpose, when the plan's results are meant to change).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mppf.geometry.read import read_points
from mppf.geometry.unfold import unfold
from mppf.model.press import example_press_path, load_press
from mppf.planning.sectional import plan_plate

EXAMPLES = Path(__file__).resolve().parents[2] / "mppf" / "examples"
REFERENCE = Path(__file__).resolve().parent / "data" / "stroke_reference.npz"
PLATES = {"K1": (EXAMPLES / "hull" / "K1_midbody_bilge.csv", 20.0),
          "P3": (EXAMPLES / "hull" / "P3_stern_saddle.csv", 16.0),
          "kcs_stern": (EXAMPLES / "long" / "kcs_stern_bilge_9000x2400.csv", 20.0)}
TOLERANCE_MM = 1e-6


def planned_strokes(name: str) -> dict[str, np.ndarray]:
    """Every step's upper and lower tip heights (steps, rows, cols) of a plate, sections in order."""
    path, thickness_mm = PLATES[name]
    design = read_points(path)
    flat = unfold(design.points, design.faces).flat
    job = plan_plate(design.points, flat, load_press(example_press_path()), thickness_mm)
    steps = [s for section in job.sections for s in section.steps] if job.sections else job.steps
    return {f"{name}_upper": np.stack([s.upper_mm for s in steps]),
            f"{name}_lower": np.stack([s.lower_mm for s in steps])}


@pytest.mark.parametrize("name", list(PLATES))
def test_strokes_match_the_reference(name):
    reference = np.load(REFERENCE)
    for key, value in planned_strokes(name).items():
        expected = reference[key]
        assert value.shape == expected.shape, key
        assert np.array_equal(np.isnan(value), np.isnan(expected)), key
        both = ~np.isnan(expected)
        assert both.sum() > 50
        assert np.max(np.abs(value[both] - expected[both])) < TOLERANCE_MM, key


if __name__ == "__main__":
    REFERENCE.parent.mkdir(exist_ok=True)
    np.savez_compressed(REFERENCE, **{k: v for name in PLATES for k, v in planned_strokes(name).items()})
    print(f"wrote {REFERENCE}")
