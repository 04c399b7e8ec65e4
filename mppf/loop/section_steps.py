"""The steps of a cycle of a plate larger than the bed: one list for the history, each step's section.

A sectional job (:mod:`mppf.model.job_sections`, version 3) presses its sections one after another,
the plate shifted on the bed between them. The loop records the steps of all sections of a cycle as
one list, in pressing order (section 1's steps, then section 2's...), so the history's step counters
(``step_started``, ``steps_done``) say which steps of which section are done, and a resumed cycle
never presses a step recorded as done, in whichever section. :func:`section_spans` says which steps of
the list are which section's; :func:`placed_steps` tells a simulated plate where each step was pressed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.scanner import PressedStep
from mppf.model.job import Job


@dataclass(frozen=True)
class SectionStep(PressedStep):
    """A step the press did, with the section it belongs to and where the plate lay for it.

    Attributes
    ----------
    section : int
        The section (1-based pressing order).
    placement_mm : (2,) float
        Where the press's punch axes lay in the plate's frame, the press x, y of the first section
        (:func:`placement_mm`), mm; (0, 0) for the first section.
    """

    section: int = 1
    placement_mm: tuple = (0.0, 0.0)


def is_sectional(job: Job) -> bool:
    """Whether the job presses its plate in sections."""
    return job.sections is not None


def cycle_steps(job: Job) -> list:
    """Every step the cycle presses, in order: the job's steps, or every section's one after another."""
    if job.sections is None:
        return list(job.steps)
    return [step for s in job.sections for step in s.steps]


def section_spans(job: Job) -> list[tuple[int, int, int]]:
    """``(section, first, last)`` per section: its steps' 1-based positions in :func:`cycle_steps`."""
    spans, first = [], 1
    for s in job.sections:
        spans.append((s.index, first, first + len(s.steps) - 1))
        first += len(s.steps)
    return spans


def section_of_step(job: Job, step: int) -> int:
    """The section (1-based) of step ``step`` (1-based position in :func:`cycle_steps`)."""
    for index, first, last in section_spans(job):
        if first <= step <= last:
            return index
    raise IndexError(f"step {step} is not one of the job's {len(cycle_steps(job))} steps")


def placement_mm(job: Job, index: int) -> np.ndarray:
    """(2,) mm: where the press's punch axes lie, for section ``index``, in the first section's press x, y.

    A punch at press x, y ``P`` in section k touches the flat point ``inv(tf_k) P``, which lay at
    ``tf_1 inv(tf_k) P`` in section 1 (``tf`` the sections' ``tf_press_flat``; the sections differ by a
    shift, so this is ``P`` plus the shift returned).
    """
    first, section = job.sections[0], job.sections[index - 1]
    return (np.asarray(first.tf_press_flat) @ np.linalg.inv(section.tf_press_flat))[:2, 3].copy()


def placed_steps(steps, job: Job) -> tuple:
    """The pressed steps (:func:`mppf.loop.pressing.pressed_steps`) with their sections and placements.

    A single-piece job's steps are returned as they are.
    """
    if job.sections is None:
        return tuple(steps)
    shifts = {s.index: tuple(float(v) for v in placement_mm(job, s.index)) for s in job.sections}
    placed = []
    for step in steps:
        k = section_of_step(job, step.step)
        placed.append(SectionStep(step.cycle, step.step, step.upper_mm, step.lower_mm, step.active, step.complete,
                                  section=k, placement_mm=shifts[k]))
    return tuple(placed)
