"""Each section's springback strokes refined on the plate model, as a single piece's (docs/sections.md item 4;
a study switch, ``mppf.planning.sectional.REFINE_SECTIONS``, off by default).

A 4.2 x 2.4 m cylinder (R 20 m, exact development, steel 20 mm) in 2 x 2 sections: the plate model's predicted
plate after each section's refined strokes is closer to the design at its punches than after the over-bent
target's contact alone; where a section lies over plate formed before, it presses the earlier section's change.
"""

from __future__ import annotations

import numpy as np
import pytest

from mppf.examples.analytic import cylinder_plate
from mppf.forming.precompensate import deviation, predict_mid_heights
from mppf.model.material import MATERIALS
from mppf.model.plan_options import PlanOptions
from mppf.planning import sectional
from mppf.planning.sectional import plan_plate
from mppf.planning.sectional_refine import section_outline
from mppf.planning.sections import index_offset, shifted
from plan_helpers import press  # noqa: F401 (fixture)

T_MM = 20.0
STEEL = MATERIALS["steel"]


class _Lines:
    def __init__(self):
        self.lines = []

    def info(self, message: str) -> None:
        self.lines.append(message)

    def progress(self, *args, **kwargs) -> None:
        pass


@pytest.fixture(scope="module")
def plans(press):
    design, flat = cylinder_plate(4200.0, 2400.0, 20000.0, spacing_mm=100.0)
    options = PlanOptions(springback=True, material=STEEL)
    contact = plan_plate(design, flat, press, T_MM, options)  # the default: the target's contact
    lines = _Lines()
    sectional.REFINE_SECTIONS = True
    try:
        refined = plan_plate(design, flat, press, T_MM, options, reporter=lines)
    finally:
        sectional.REFINE_SECTIONS = False
    return {"contact": contact, "refined": refined, "lines": lines.lines}


def _predicted_max(press, section, outline):
    final = section.steps[-1]
    mid = predict_mid_heights(press, final.upper_mm, final.lower_mm, final.active, outline, T_MM, STEEL)
    return float(np.nanmax(np.abs(deviation(press, mid, section.layout.design_mid_mm, final.active))))


def test_the_outline_is_clipped_to_the_bed_and_its_reach(press):
    half = np.array(press.bed_size_mm) / 2.0
    long_plate = np.array([[-4000.0, -1000.0], [4000.0, -1000.0], [4000.0, 1000.0], [-4000.0, 1000.0]])
    clipped = section_outline(press, long_plate, 500.0)
    assert np.allclose(clipped.min(axis=0), [-half[0] - 500.0, -1000.0])
    assert np.allclose(clipped.max(axis=0), [half[0] + 500.0, 1000.0])
    small = long_plate * 0.1
    assert np.allclose(np.sort(section_outline(press, small, 500.0), axis=0), np.sort(small, axis=0))


@pytest.mark.slow
def test_every_section_is_refined_on_the_plate_model(press, plans):
    contact, refined = plans["contact"], plans["refined"]
    assert len(refined.sections) == 4
    zone = refined.sectional.transition_zone_mm
    reach = zone + refined.layout.margin_mm + press.trim_allowance_mm
    for before, after in zip(contact.sections, refined.sections):
        outline = section_outline(press, after.layout.outline_mm, reach)
        was, now = _predicted_max(press, before, outline), _predicted_max(press, after, outline)
        assert was > 3.0, before.index  # the over-bent target alone is off on the plate model
        # section 1 is refined alone; a later one presses the earlier sections' change over the formed plate
        assert now < (0.2 if after.index == 1 else 1.0) * was, (after.index, was, now)
    report = refined.reports.springback_doc()["refinement"]
    assert report["virtual_cycles"] >= 4 and report["predicted_max_mm"] < report["history_mm"][0]
    assert sum("refining the springback strokes" in line for line in plans["lines"]) == 4


@pytest.mark.slow
def test_over_formed_plate_a_section_presses_the_earlier_change(press, plans):
    """Deep inside plate formed before (own weight 0) a section's refinement change is the earlier section's
    (section 2, whose only earlier section is section 1)."""
    contact, refined = plans["contact"], plans["refined"]
    compared = 0
    for k in (1,):
        s, c = refined.sections[k], contact.sections[k]
        act, own = s.steps[-1].active, s.own_weight
        change = s.steps[-1].upper_mm - c.steps[-1].upper_mm
        assert np.nanmax(np.abs(change[act])) > 1.0  # the refinement changed the strokes
        first = refined.sections[0]
        offset = index_offset(press, -s.plate_centre_mm, -first.plate_centre_mm)
        earlier = shifted(first.steps[-1].upper_mm - contact.sections[0].steps[-1].upper_mm, offset, np.nan)
        deep = act & (own == 0.0) & np.isfinite(earlier) & shifted(first.own_weight == 1.0, offset, False)
        if deep.any():
            compared += int(deep.sum())
            assert np.abs(change[deep] - earlier[deep]).max() < 1e-6, s.index
    assert compared > 20
