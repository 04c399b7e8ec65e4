"""Any job document, however broken, is answered with an InputError (exit 2), never an internal error.

Seeded mutations of a good job (values replaced by other types, absurd numbers, keys removed),
sealed again so that they reach the parsing and the checks behind the seal.
"""

from __future__ import annotations

import json
import random

import pytest
from panel_helpers import layout_job

from mppf.core.errors import InputError
from mppf.core.seal import load_key, seal_document
from mppf.planning.job import load_job, save_job
from mppf.planning.validate import validate_job

VALUES = [None, True, "x", [], {}, [1, 2], {"a": 1}, -1, 0, 1e300, -1e300, 3, 2.5, [[1]], [None], "", 10**20,
          10**400]


def _paths(value, path=()):
    yield path
    if isinstance(value, dict):
        for key, item in value.items():
            yield from _paths(item, path + (key,))
    elif isinstance(value, list):
        for k, item in enumerate(value[:4]):
            yield from _paths(item, path + (k,))


def _mutated(doc: dict, rng: random.Random, paths: list) -> dict:
    doc = json.loads(json.dumps(doc))
    for _ in range(rng.randint(1, 3)):
        path = rng.choice(paths)
        target = doc
        try:
            for key in path[:-1]:
                target = target[key]
            if rng.random() < 0.15 and isinstance(target, dict):
                del target[path[-1]]
            else:
                target[path[-1]] = rng.choice(VALUES)
        except (KeyError, IndexError, TypeError):
            pass
    return doc


@pytest.mark.parametrize("seed", range(3))
def test_no_mutation_of_a_job_is_an_internal_error(tmp_path, seed):
    good = json.loads(save_job(layout_job(n_steps=2), tmp_path / "good.json").read_text())
    paths = [p for p in _paths(good) if p and p[0] != "seal"]
    rng, key, path = random.Random(seed), load_key(), tmp_path / "job.json"
    answered = 0
    for _ in range(60):
        doc = _mutated(good, rng, paths)
        try:
            doc = seal_document(doc, key, sealed_by="fuzz")
            text = json.dumps(doc)
        except (ValueError, OverflowError):  # not JSON any more (a number beyond floats): written as text below
            text = json.dumps(doc, default=str)
        path.write_text(text)
        try:
            validate_job(load_job(path))
        except InputError:
            answered += 1
    assert answered > 0
