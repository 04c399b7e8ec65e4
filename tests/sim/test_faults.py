"""The ``--fault`` spec grammar of the simulated PLC (mppf.sim.faults): every kind parsed, bad specs refused
with one message naming the field."""

from __future__ import annotations

import re

import pytest
from mppf.sim.faults import GRAMMAR, KINDS, parse_fault_spec

from mppf.core.errors import InputError


@pytest.mark.parametrize(
    "spec, kind, params",
    [
        ("stuck:upper:3:5@40", "stuck", {"matrix": "upper", "row": 3, "col": 5, "percent": 40.0}),
        ("estop", "estop", {}),
        ("estop@2.0", "estop", {"after_s": 2.0}),
        ("overpressure@1.5", "overpressure", {"after_s": 1.5}),
        ("freeze@2", "freeze", {"after_s": 2.0}),
        ("slow:50", "slow", {"delay_ms": 50.0}),
        ("drop@3", "drop", {"after_s": 3.0}),
        ("drop:0.5@3", "drop", {"duration_s": 0.5, "after_s": 3.0}),
        ("restart@1", "restart", {"after_s": 1.0}),
        ("local@0.5", "local", {"after_s": 0.5}),
        ("slow:80@2", "slow", {"delay_ms": 80.0, "after_s": 2.0}),
    ],
)
def test_fault_spec_grammar(spec, kind, params):
    parsed = parse_fault_spec(spec)
    assert (parsed.kind, parsed.params) == (kind, params)


BAD_SPECS = [
    ("stuck:side:1:2", "matrix must be 'upper' or 'lower'"),
    ("stuck:upper:1", "wrong number of ':' fields"),
    ("stuck:upper:1:2@120", "PERCENT must be 0..100"),
    ("slow:fast", "MS must be a number"),
    ("estop@-1", "T must be >= 0"),
    ("meteor", "unknown fault 'meteor'"),
]
"""Fault specs that are refused, and words of the message (also what ``mppf sim --fault`` prints: test_sim_plc)."""


@pytest.mark.parametrize("spec, message", BAD_SPECS)
def test_a_bad_spec_is_refused_naming_what_is_wrong(spec, message):
    with pytest.raises(InputError) as caught:
        parse_fault_spec(spec)
    assert message in str(caught.value) and spec.split(":")[0].split("@")[0] in str(caught.value)


def test_every_kind_is_in_the_grammar_the_help_prints():
    assert all(re.search(rf"(^|, ){kind}[:@]", GRAMMAR) for kind in KINDS), GRAMMAR
