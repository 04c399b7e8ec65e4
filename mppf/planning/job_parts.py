"""The parts of a job file, moved to :mod:`mppf.model.job_parts`; re-exported here for old imports."""

from mppf.model.job_parts import (  # noqa: F401 (re-export)
    PlateLayout,
    StepStrokes,
    active_grid_to_json,
    checked_grid_from_json,
    grid_from_json,
    grid_to_json,
    reference_corner_xy,
    steps_from_json,
    steps_to_json,
)
