"""The typed data every stage shares: the press description, the job with its parts and sections.

Below every stage but :mod:`mppf.core` (``docs/architecture.md``, "Layers"): the model imports
only :mod:`mppf.core`, so geometry, forming, planning, the drivers, the loop and the panel all
take these types from one place. Its modules: :mod:`mppf.model.press` (:class:`PressConfig`),
:mod:`mppf.model.job` (:class:`Job` and its JSON), :mod:`mppf.model.job_parts`
(:class:`StepStrokes`, :class:`PlateLayout`, the punch-grid JSON helpers),
:mod:`mppf.model.job_sections` (:class:`Section`), :mod:`mppf.model.job_reports` (the planner's
reports, :class:`PlanReports`), :mod:`mppf.model.job_provenance` (the sectional summary, a section's
transition, the batch and loop provenance, the seal), :mod:`mppf.model.job_record` (how those typed
blocks are read and written), :mod:`mppf.model.material`
(:class:`Material`), :mod:`mppf.model.placement` (where to lay the plate).
"""
