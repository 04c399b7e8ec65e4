"""Correction: the loop's one correction of the next strokes from the measured deviations (:mod:`mppf.correct.step`,
its parts one module each), the planner's virtual-cycle step and the press limits."""
