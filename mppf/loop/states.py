"""The names of the loop: a cycle's states, a plate's statuses, the decision after a compare.

Each is a :class:`enum.StrEnum`: a member *is* its string (``CycleState.PLANNED ==
"planned"``), so the history stores and reads the same text as before and a record read
back compares equal to either.

A cycle moves through ::

    planned -> pressing -> pressed -> scanned -> compared -> corrected | done

(a rejected scan takes "scanned" back to "pressed"); "corrected" and "done" are the two ends.
"""

from __future__ import annotations

from enum import StrEnum


class CycleState(StrEnum):
    """Where a press cycle of a plate stands (see the module docstring)."""

    PLANNED = "planned"  # strokes planned, nothing sent to the press
    PRESSING = "pressing"  # a step was started: never pressed again
    PRESSED = "pressed"  # every step done (or interrupted): waiting for the scan
    SCANNED = "scanned"  # a scan file is recorded: to be compared with the design
    COMPARED = "compared"  # deviations and the decision recorded
    CORRECTED = "corrected"  # the next cycle is planned
    DONE = "done"  # the loop ended at this cycle


class Decision(StrEnum):
    """The decision after a compared cycle; all but CONTINUE end the loop."""

    CONTINUE = "continue"
    IN_TOLERANCE = "in_tolerance"
    MAX_CYCLES = "max_cycles"
    DIVERGED = "diverged"
    CANNOT_CONVERGE = "cannot_converge"  # the correction found no way on: see its verdict
    NEEDS_REVIEW = "needs_review"  # form and RMS within limits, but set-aside points beyond the tolerance or gaps
    BADLY_FORMED = "badly_formed"  # the scan is this plate, far from its design: the loop stops, a person looks


class PlateStatus(StrEnum):
    """A plate's status: "active" while its loop runs, else why it stopped (a final :class:`Decision`)."""

    ACTIVE = "active"
    IN_TOLERANCE = "in_tolerance"
    MAX_CYCLES = "max_cycles"
    DIVERGED = "diverged"
    CANNOT_CONVERGE = "cannot_converge"
    NEEDS_REVIEW = "needs_review"
    BADLY_FORMED = "badly_formed"


STATES = tuple(CycleState)
"""Cycle states in order."""

DECISIONS = tuple(Decision)
"""Decisions recorded for a compared cycle."""

PLATE_STATUSES = tuple(PlateStatus)
"""Plate statuses."""
