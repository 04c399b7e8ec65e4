"""The FE plate's release after a large stroke change, with the real CalculiX (slow: one ccx run, about a minute).

``data/fe_p2_release.npz`` is the FE plate of the P2 bow flare (seed 1, true yield 265 MPa) after the
first cycle's two press steps, and the tips of the first correction's press step (110 mm RMS of stroke
change), as ``benchmarks/bench_loop.py --physics fe --mode direct`` pressed them. Its release (analysis
step 8) ended in "too many cutbacks" while ccx could cut an increment back only 5 times: the tips still
retracted 0.29 mm in the smallest first increment, every gap opened at once and the whole springback
load came in one increment (benchmarks/results/2026-12-06-fe-release.md). The deck the plate writes now
is the failing one but for the number of cutbacks (:data:`mppf.sim.fe.deck.MAX_CUTBACKS`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mppf.sim.fe.ccx import run_ccx
from mppf.sim.fe.deck import step_count
from mppf.sim.fe.plate import FEPlate
from mppf.sim.fe.results import last_of_steps, read_frd

pytestmark = pytest.mark.slow

STATE = Path(__file__).parent / "data" / "fe_p2_release.npz"


def test_release_after_a_large_stroke_change_converges():
    state = dict(np.load(STATE))
    plate = FEPlate.from_state(state)
    assert plate.steps == 2
    entry = (state["release_tips_mm"], state["release_touch_mm"])
    run = run_ccx(plate.deck([entry]))
    release = step_count(plate.steps + 1)
    assert release == 8
    _, cutbacks, _ = run.steps[release]
    assert cutbacks > 5  # more than ccx's default would have allowed: the case that failed
    steps = last_of_steps(read_frd(run.frd))
    assert steps[release].time == pytest.approx(release)  # the whole release, to its end
    loaded = steps[release - 1].values
    free = steps[release].values
    spring_mm = np.abs(free[:, 2] - loaded[:, 2])
    # the plate sprang back (not all at once nor far off): within 5 - 150 mm at most, as the hull plates do
    assert 5.0 < spring_mm.max() < 150.0
    assert np.isfinite(free).all()
