"""The job as data (``mppf/model/job.py``, ``job_parts.py``): format check, reading the document, punch grids."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mppf.core.errors import ConfigError, InputError
from mppf.model.job import READ_VERSIONS, check_format, read_job_document
from mppf.model.job_parts import active_grid_to_json, checked_grid_from_json, grid_from_json, grid_to_json


@pytest.mark.parametrize(("doc", "seen"), [
    ({"format": "other", "version": 4}, "format 'other'"),
    ([1, 2], "format None"),
    ({"format": "mppf-job", "version": 9}, "version 9 is not supported"),
    ({"format": "mppf-job", "version": True}, "version True is not supported"),
    ({"format": "mppf-job"}, "version None is not supported"),
])
def test_a_document_that_is_not_a_job_this_mppf_reads_is_refused(doc, seen):
    with pytest.raises(ConfigError) as info:
        check_format(doc, "job.json")
    assert info.value.message.startswith("job.json: ") and seen in info.value.message
    assert info.value.hint


@pytest.mark.parametrize("version", READ_VERSIONS)
def test_every_version_read_passes_the_format_check(version):
    check_format({"format": "mppf-job", "version": version}, "job.json")


def test_the_document_is_read_with_its_line_on_bad_json_and_huge_integers_as_floats(tmp_path):
    path = tmp_path / "job.json"
    path.write_text('{"format": "mppf-job",\n "n": 12345678901234567890123,\n "k": 7}')
    doc = read_job_document(path)
    assert doc["k"] == 7 and isinstance(doc["k"], int) and isinstance(doc["n"], float)
    path.write_text('{"format": "mppf-job",\n "n": }')
    with pytest.raises(ConfigError, match=r"job.json, line 2: not valid JSON"):
        read_job_document(path)
    with pytest.raises(InputError, match="does not exist"):
        read_job_document(tmp_path / "missing.json")


def test_punch_grids_keep_nan_as_null_and_inactive_punches_are_null():
    values = np.array([[1.23456, np.nan], [3.0, 4.0]])
    active = np.array([[True, True], [False, True]])
    assert grid_to_json(values) == [[1.2346, None], [3.0, 4.0]]
    assert active_grid_to_json(values, active) == [[1.2346, None], [None, 4.0]]
    assert json.dumps(active_grid_to_json(values, active))  # no NaN in the file
    np.testing.assert_array_equal(grid_from_json([[1.0, None]]), [[1.0, np.nan]])
    assert grid_from_json(None) is None and grid_to_json(None) is None


def test_a_punch_grid_of_another_shape_or_not_numbers_is_named():
    with pytest.raises(ConfigError, match=r"job.json: step 1 upper_mm has shape \(1, 2\), the press has \(2, 2\)"):
        checked_grid_from_json([[1.0, 2.0]], (2, 2), "step 1 upper_mm", "job.json")
    with pytest.raises(ConfigError, match="step 1 active must be a grid of numbers or null"):
        checked_grid_from_json([["x", 2.0]], (1, 2), "step 1 active", "job.json")
