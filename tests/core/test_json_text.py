"""The fast indented JSON text of job documents is json.dumps(indent=1)'s, errors included."""

from __future__ import annotations

import json

import numpy as np
import pytest
from driver_helpers import small_job, small_press
from hypothesis import given, settings
from hypothesis import strategies as st

from mppf.core.json_text import indented_json
from mppf.planning.job import load_job, save_job

scalars = (st.none() | st.booleans() | st.integers(-10**20, 10**20)
           | st.floats(allow_nan=False, allow_infinity=False) | st.text(max_size=6))
values = st.recursive(scalars, lambda inner: (st.lists(inner, max_size=5) | st.tuples(inner, inner)
                                               | st.lists(st.floats(allow_nan=False, allow_infinity=False)
                                                          | st.none(), max_size=6)
                                               | st.dictionaries(st.text(max_size=4), inner, max_size=5)),
                      max_leaves=40)


@settings(max_examples=200, deadline=None)
@given(values)
def test_the_text_is_json_dumps_indent_1(value):
    assert indented_json(value) == json.dumps(value, indent=1, allow_nan=False)


@pytest.mark.parametrize("value", [
    {"a": [1.0, None], 2: "int key", None: 1, 1.5: [True]},  # keys that are not strings
    {"x": [np.float64(1.25), np.float64(3.0)], "y": np.float64(-0.5)},  # numpy floats
    {"rows": [[1.0, None], []], "empty": {}, "t": (1, "a")},
])
def test_unusual_values_are_written_by_json_dumps(value):
    assert indented_json(value) == json.dumps(value, indent=1, allow_nan=False)


@pytest.mark.parametrize("value", [[1.0, float("nan")], {"a": [[None, float("inf")]]}, {"a": -float("inf")},
                                   {"a": {1, 2}}, [np.int64(3)]])
def test_what_json_dumps_refuses_is_refused_with_its_error(value):
    with pytest.raises((ValueError, TypeError)) as expected:
        json.dumps(value, indent=1, allow_nan=False)
    with pytest.raises(type(expected.value), match="^" + str(expected.value).replace("(", r"\(").replace(")", r"\)")):
        indented_json(value)


def test_a_saved_job_is_the_text_of_its_document(tmp_path):
    job = small_job(small_press(), n_steps=3)
    path = save_job(job, tmp_path / "job.json")
    assert path.read_text() == job.to_json() == indented_json(job.to_dict())
    assert load_job(path).sha256() == job.sha256()
