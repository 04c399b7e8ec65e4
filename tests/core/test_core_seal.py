"""The seal's fast canonical form gives the bytes of its definition, so every seal stays the same."""

from __future__ import annotations

import hashlib
import hmac
import json

import numpy as np
import pytest
from driver_helpers import small_job, small_press
from hypothesis import given, settings
from hypothesis import strategies as st

from mppf.core.seal import (
    _reference_canonical,
    canonical,
    document_parts,
    seal_document,
    verify_document,
)
from mppf.examples.analytic import cylinder_plate
from mppf.model.press import example_press_path, load_press
from mppf.planning.sectional import plan_plate

KEY = bytes(range(32))

scalars = (st.none() | st.booleans() | st.integers(-10**15, 10**15)
           | st.floats(allow_nan=False, allow_infinity=False) | st.text(max_size=6))
values = st.recursive(scalars, lambda inner: (st.lists(inner, max_size=5) | st.tuples(inner, inner)
                                               | st.dictionaries(st.text(max_size=4) | st.integers(0, 3), inner,
                                                                 max_size=5)), max_leaves=40)


@settings(max_examples=150, deadline=None)
@given(values)
def test_the_canonical_form_is_its_definition(value):
    assert canonical(value) == _reference_canonical(value).encode()


@settings(max_examples=100, deadline=None)
@given(st.lists(st.lists(st.floats(allow_nan=False, allow_infinity=False) | st.none(), max_size=6), max_size=6))
def test_a_grid_and_the_same_list_met_twice(grid):
    doc = {"upper_mm": grid, "again": grid, "steps": [{"index": 1, "upper_mm": grid}] * 2}
    assert canonical(doc) == _reference_canonical(doc).encode()


@pytest.mark.parametrize("value", [
    [1.0, float("nan")], {"b": [2.0], "a": {"x": float("inf")}}, [[1.0, None], [2.0, -float("inf")]],
    {"a": 1, "b": [np.float64(np.nan)]}, {"a": [1.0], "b": {1, 2}}, [1.0, np.int64(3)],
])
def test_a_value_that_is_not_plain_json_is_refused_as_the_definition_does(value):
    with pytest.raises(ValueError) as expected:
        _reference_canonical(value)
    with pytest.raises(ValueError) as got:
        canonical(value)
    assert str(got.value) == str(expected.value)


def test_numpy_floats_and_int_keys_are_written_as_the_definition_writes_them():
    value = {"x": [np.float64(1.5), 2, True], 3: "three", "3": "string three", "n": np.float64(2.0)}
    assert canonical(value) == _reference_canonical(value).encode()


def _reference_seal_macs(doc: dict) -> dict:
    """The part HMACs of a sealed document computed from the definition of the canonical form."""
    def mac(name, value):
        return hmac.new(KEY, name.encode() + b"\0" + _reference_canonical(value).encode(), hashlib.sha256).hexdigest()

    body = {k: v for k, v in doc.items() if k != "seal"}
    macs = {name: mac(name, value) for name, value in document_parts(body).items()}
    return {"parts": macs, "content_mac": mac("content", body),
            "mac": mac("job", {**body, "seal": {k: v for k, v in doc["seal"].items() if k != "mac"}})}


@pytest.mark.parametrize("sectional", [False, True])
def test_the_seal_of_a_planned_job_is_the_one_of_the_definition(sectional):
    if sectional:  # a 7.5 m cylinder in sections on the example press
        design, flat = cylinder_plate(7500.0, 2400.0, 20000.0, spacing_mm=150.0)
        job = plan_plate(design, flat, load_press(example_press_path()), 20.0)
        assert job.sections
    else:
        job = small_job(small_press(), n_steps=3)
    doc = json.loads(json.dumps(job.to_dict()))  # as read back from the file
    sealed = seal_document(doc, KEY, sealed_by="test")
    expected = _reference_seal_macs(sealed)
    assert sealed["seal"]["parts"] == expected["parts"]
    assert (sealed["seal"]["content_mac"], sealed["seal"]["mac"]) == (expected["content_mac"], expected["mac"])
    assert seal_document(job.to_dict(), KEY, sealed_by="test") == sealed  # from memory: ints and floats alike
    verify_document(sealed, "job", KEY)
