"""Correction: the next strokes from the measured deviations, one module per strategy, and the press limits."""
