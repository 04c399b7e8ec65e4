"""The sections of a job file, moved to :mod:`mppf.model.job_sections`; re-exported here for old imports."""

from mppf.model.job_sections import (  # noqa: F401 (re-export)
    SECTION_KEYS,
    Section,
    section_from_dict,
    sections_from_json,
)
