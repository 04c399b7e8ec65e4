"""Typed blocks of a job file: a frozen dataclass per block, read and written by its field declarations.

A report of the job file (:mod:`mppf.model.job_reports`, :mod:`mppf.model.job_provenance`) is a
frozen dataclass deriving from :class:`DocRecord` whose fields are declared with the helpers
below (:func:`number`, :func:`integer`, :func:`boolean`, :func:`text`, :func:`numbers`,
:func:`integers`, :func:`texts`, :func:`array`, :func:`grid`, :func:`record`, :func:`free`). Each helper says
how the field is written to JSON and checked when read, so :meth:`DocRecord.to_doc` and
:meth:`DocRecord.from_doc` need no code of their own per class.

Every field is optional (``None``: the key is absent from the file), so older job files, which
lack some reports, are read with the same classes. A value that is present must have its type:
otherwise :class:`~mppf.core.errors.ConfigError` names the block, the key and the value seen.
Writing then reading a record gives the same document (same keys, same order, same numbers), so
a job read back serialises to the bytes it was written as (its SHA-256 is its identity).
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import ClassVar

import numpy as np

from mppf.core.errors import ConfigError
from mppf.model.job_parts import grid_from_json, grid_to_json

HINT = "re-plan the plate with 'mppf plan' (a job is never edited by hand)"


def _declare(kind: str, key: str | None, spec=None):
    return dataclasses.field(default=None, metadata={"kind": kind, "key": key, "spec": spec})


def number(key: str | None = None):
    """A finite number (float), written as a JSON number."""
    return _declare("number", key)


def integer(key: str | None = None):
    """A whole number (int)."""
    return _declare("integer", key)


def boolean(key: str | None = None):
    """``true`` or ``false``."""
    return _declare("boolean", key)


def text(key: str | None = None):
    """A string."""
    return _declare("text", key)


def numbers(key: str | None = None):
    """A list (nested to any depth) of finite numbers or ``null``, held as nested tuples of float / None."""
    return _declare("numbers", key)


def integers(key: str | None = None):
    """A list of whole numbers, held as a tuple of int."""
    return _declare("integers", key)


def texts(key: str | None = None):
    """A list of strings, held as a tuple of str."""
    return _declare("texts", key)


def array(shape: tuple, key: str | None = None):
    """A float array of ``shape`` (``-1``: any length along that axis), finite; written as nested lists."""
    return _declare("array", key, shape)


def grid(key: str | None = None):
    """A (rows, cols) float array with NaN where the file has ``null`` (a parked punch), written as
    :func:`~mppf.model.job_parts.grid_to_json` writes every grid of a job (4 decimals)."""
    return _declare("grid", key)


def record(cls, key: str | None = None):
    """A nested block: an object read by ``cls`` (a :class:`DocRecord`)."""
    return _declare("record", key, cls)


def free(key: str | None = None):
    """A JSON value kept as written (a block that is truly free-form; no stage reads keys from it)."""
    return _declare("free", key)


class DocRecord:
    """Base of the typed blocks of a job file: :meth:`to_doc` and :meth:`from_doc` from the field declarations.

    A class may name a field in ``REST``: the keys of the block it does not declare are kept there
    (a dict, written after the declared keys) instead of being dropped.
    """

    REST: ClassVar[str | None] = None

    def to_doc(self) -> dict:
        """The block as a JSON object: declared keys in declaration order (absent when None), then ``REST``."""
        doc = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name == self.REST or value is None:
                continue
            doc[f.metadata["key"] or f.name] = _encode(f.metadata["kind"], value)
        if self.REST is not None:
            for key, value in (getattr(self, self.REST) or {}).items():
                doc.setdefault(key, value)
        return doc

    @classmethod
    def from_doc(cls, doc, source: str = "job"):
        """The record of a JSON object, each present value checked against its declaration.

        Raises
        ------
        ConfigError
            Not an object, or a value of another type (naming ``source``, the key and the value).
        """
        if not isinstance(doc, dict):
            raise ConfigError(f"{source} is {_shown(doc)}, not an object", hint=HINT)
        values, known = {}, set()
        for f in dataclasses.fields(cls):
            if f.name == cls.REST:
                continue
            key = f.metadata["key"] or f.name
            known.add(key)
            if doc.get(key) is not None:
                values[f.name] = _decode(f.metadata, doc[key], f"{source} {key}")
        if cls.REST is not None:
            values[cls.REST] = {k: v for k, v in doc.items() if k not in known}
        return cls(**values)


def _encode(kind: str, value):
    if kind == "number":
        return float(value)
    if kind == "integer":
        return int(value)
    if kind == "boolean":
        return bool(value)
    if kind == "numbers":
        return _nested(value)
    if kind == "integers":
        return [int(v) for v in value]
    if kind == "texts":
        return [str(v) for v in value]
    if kind == "array":
        return np.asarray(value, dtype=float).tolist()
    if kind == "grid":
        return grid_to_json(value)
    if kind == "record":
        return value.to_doc()
    return value  # text, free


def _nested(value):
    if value is None:
        return None
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_nested(v) for v in value]
    number_ = float(value)
    return number_ if math.isfinite(number_) else None


def _decode(meta: dict, value, where: str):
    kind = meta["kind"]
    if kind == "number" and _is_number(value):
        return float(value)
    if kind == "integer" and isinstance(value, int) and not isinstance(value, bool):
        return value
    if (kind == "boolean" and isinstance(value, bool)) or (kind == "text" and isinstance(value, str)):
        return value
    if kind == "numbers" and isinstance(value, list) and _all_numbers(value):
        return _tupled(value)
    if kind == "integers" and isinstance(value, list) and all(
            isinstance(v, int) and not isinstance(v, bool) for v in value):
        return tuple(value)
    if kind == "texts" and isinstance(value, list) and all(isinstance(v, str) for v in value):
        return tuple(value)
    if kind == "array":
        return _array(value, meta["spec"], where)
    if kind == "grid" and isinstance(value, list) and value and all(
            isinstance(row, list) and len(row) == len(value[0]) for row in value) and _all_numbers(value):
        return grid_from_json(value)
    if kind == "record":
        return meta["spec"].from_doc(value, where)
    if kind == "free":
        return value
    raise ConfigError(f"{where} is {_shown(value)}, not {_WANTED[kind]}", hint=HINT)


_WANTED = {"number": "a finite number", "integer": "a whole number", "boolean": "true or false",
           "text": "a string", "numbers": "a list of finite numbers (or null)",
           "integers": "a list of whole numbers", "texts": "a list of strings",
           "grid": "a grid (rows of equal length) of finite numbers or null"}


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _all_numbers(values: list) -> bool:
    return all(v is None or _is_number(v) or (isinstance(v, list) and _all_numbers(v)) for v in values)


def _tupled(values):
    if isinstance(values, list):
        return tuple(_tupled(v) for v in values)
    return None if values is None else float(values)


def _array(value, shape: tuple, where: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        arr = None
    if arr is None or arr.ndim != len(shape) or any(s not in (-1, n) for s, n in zip(shape, arr.shape)) \
            or not np.all(np.isfinite(arr)):
        wanted = " x ".join("n" if s == -1 else str(s) for s in shape)
        raise ConfigError(f"{where} is {_shown(value)}, not {wanted} finite numbers (mm)", hint=HINT)
    return arr


def _shown(value) -> str:
    try:
        text_ = json.dumps(value)
    except (TypeError, ValueError):
        text_ = repr(value)
    return text_ if len(text_) <= 60 else text_[:57] + "..."
