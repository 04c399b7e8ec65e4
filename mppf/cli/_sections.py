"""Pressing a plate in sections (``mppf press`` on a version-3 job): place, confirm, press, shift.

Called by :mod:`mppf.cli.press_cmd` after the one job validator (which checks every section's
steps) for a job with ``sections``. Between sections the operator shifts the plate and places it
by the section's marks (:func:`mppf.planning.sections.placement_text`); on a real press they
confirm the placement at the terminal (``--yes`` skips it, as it skips the motion question); a dry
run shows the placements and goes on. See ``docs/sections.md``.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import click

from mppf.core.errors import InputError, PressRefused


@dataclass(frozen=True)
class SectionRun:
    """How ``mppf press`` presses a sectional job (its options).

    Attributes
    ----------
    job_name : str
        For the questions.
    dry_run, yes : bool
        As in ``mppf press``.
    timeout_s : float or None
        Motion timeout per step (s).
    section, step : int or None
        Only this section (1-based) and, in it, only this step.
    """

    job_name: str
    dry_run: bool
    yes: bool = False
    timeout_s: float | None = None
    section: int | None = None
    step: int | None = None


def select_sections(job, section: int | None) -> list:
    """The sections to press: all in order, or only ``section`` (1-based).

    Raises
    ------
    InputError
        The job has no such section.
    """
    n = len(job.sections)
    if section is None:
        return list(job.sections)
    if not 1 <= section <= n:
        raise InputError(f"--section {section} does not exist: the job has sections 1..{n}")
    return [job.sections[section - 1]]


def confirm_placement(text: str, yes: bool, dry_run: bool) -> None:
    """On a real press, the operator confirms that the plate lies by the section's marks.

    Raises
    ------
    PressRefused
        No terminal to ask at (without ``--yes``), or the operator answered no: nothing more is pressed.
    """
    if yes or dry_run:
        return
    if not sys.stdin.isatty():
        raise PressRefused(f"refusing to press the next section without confirmation ({text}): stdin is not a terminal",
                           hint="run it at a terminal to confirm each placement, or add --yes")
    if not click.confirm(f"{text}. Is the plate placed and the press clear?", default=False, err=True):
        raise PressRefused("the operator did not confirm the placement: the remaining sections were not pressed",
                           hint="press the remaining sections later with --section N")


def press_sections(plc, job, run: SectionRun, *, show_result, echo, make_reporter, placement_lines=None) -> int:
    """Press a sectional job section by section; returns the number of steps pressed.

    Parameters
    ----------
    plc : PressLink
        Connected, the job already checked by ``plc.check_job``.
    job : Job
        With ``sections``.
    run : SectionRun
        The options: dry run or not, ``--yes``, the motion timeout, only one section or step.
    show_result : callable(step_label, result)
        Prints the result of one step (``press_cmd``'s table).
    echo : callable(str)
        Prints a line for the operator.
    make_reporter : callable() -> Reporter
        The progress reporter of one step.
    placement_lines : callable(Job) -> list of str, optional
        Where the plate lies for a single-piece job (e.g. the corners of ``mppf press``'s placement
        output); given, its lines for each section (:func:`mppf.planning.sections.section_job`) are
        printed after the marks.
    """
    from mppf.planning.sections import placement_text, section_job

    # the plan's own warnings (a section that steps at its border with the plate formed before it) first
    for warning in (job.sectional.warnings or ()) if job.sectional is not None else ():
        echo(f"warning: {warning}")
    plan = [(s, _steps_of(s, run.step)) for s in select_sections(job, run.section)]
    _check_plan(plc, job, plan)  # every setpoint is checked before anything moves
    if not run.dry_run:
        from mppf.cli.press_policy import confirm_motion, press_description

        confirm_motion(plc, f"job {run.job_name}, {len(plan)} section(s), on {press_description(plc)}", run.yes)
    pressed = 0
    previous = None if run.section is None else (job.sections[run.section - 2] if run.section > 1 else None)
    for s, ks in plan:
        text = placement_text(s, previous, job.press.punch_label)
        echo(text)
        for line in placement_lines(section_job(job, s.index)) if placement_lines else []:
            echo(line)
        confirm_placement(text, run.yes, run.dry_run)
        for k in ks:
            reporter = make_reporter()
            reporter.info(f"section {s.index} of {len(job.sections)}, step {k} of {len(s.steps)}")
            result = plc.run_step(*s.steps[k - 1].setpoints_mm(job.press), reporter=reporter,
                                  timeout_s=run.timeout_s)
            show_result(f"{k} of section {s.index}", result)
            pressed += 1
        previous = s
    return pressed


def _check_plan(plc, job, plan) -> None:
    """Check every setpoint of the ``(section, step numbers)`` pairs of ``plan`` against the PLC's limits."""
    for s, ks in plan:
        for k in ks:
            plc.check_setpoints(*s.steps[k - 1].setpoints_mm(job.press), active=s.steps[k - 1].active)


def _steps_of(section, step: int | None) -> list[int]:
    n = len(section.steps)
    if step is None:
        return list(range(1, n + 1))
    if not 1 <= step <= n:
        raise InputError(f"--step {step} does not exist in section {section.index}: it has steps 1..{n}")
    return [step]
