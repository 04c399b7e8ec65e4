"""The indented JSON text of a job document, as ``json.dumps(doc, indent=1, allow_nan=False)`` writes it.

A job file is written with one value per line (``indent=1``), for which Python's ``json`` has only
its pure-Python encoder: a generator per list and object, a call per number. :func:`indented_json`
gives the same text several times faster by joining each list's items in one step (a row of
strokes is a list of floats and nulls). Anything it does not write itself (other types, keys that
are not strings, non-finite numbers) makes it hand the whole document to ``json.dumps``, which
then writes it or raises its own error, so the text and the errors are always ``json.dumps``'s.
"""

from __future__ import annotations

import json

_ENCODE_STR = json.encoder.encode_basestring_ascii
_FLOAT_REPR = float.__repr__
_NOT_FINITE = ("nan", "inf", "-inf")
_ROW_TYPES = frozenset({float, type(None)})


class _Unusual(Exception):
    """A value :func:`indented_json` leaves to ``json.dumps``."""


def indented_json(value) -> str:
    """``json.dumps(value, indent=1, allow_nan=False)``, faster for job documents.

    Parameters
    ----------
    value : JSON value
        Dicts, lists, strings, numbers, booleans and None.

    Returns
    -------
    str

    Raises
    ------
    ValueError, TypeError
        As ``json.dumps`` raises them (non-finite numbers, values that are not JSON).
    """
    try:
        return _text(value, "\n")
    except (_Unusual, RecursionError):
        return json.dumps(value, indent=1, allow_nan=False)


def _text(value, newline: str) -> str:
    """The text of ``value`` whose container starts at the indentation of ``newline`` ("\\n" + spaces)."""
    kind = type(value)
    if kind is float:
        text = _FLOAT_REPR(value)
        if text in _NOT_FINITE:
            raise _Unusual
        return text
    if kind is str:
        return _ENCODE_STR(value)
    if value is None:
        return "null"
    if value is True:
        return "true"
    if value is False:
        return "false"
    if kind is int:
        return int.__repr__(value)
    if kind is list or kind is tuple:
        if not value:
            return "[]"
        inner = newline + " "
        if _ROW_TYPES.issuperset(map(type, value)):  # a row of strokes: floats and nulls
            items = ["null" if v is None else _FLOAT_REPR(v) for v in value]
            if "nan" in items or "inf" in items or "-inf" in items:
                raise _Unusual
        else:
            items = [_text(v, inner) for v in value]
        return "[" + inner + ("," + inner).join(items) + newline + "]"
    if kind is dict:
        if not value:
            return "{}"
        inner = newline + " "
        items = []
        for key, item in value.items():
            if type(key) is not str:
                raise _Unusual
            items.append(_ENCODE_STR(key) + ": " + _text(item, inner))
        return "{" + inner + ("," + inner).join(items) + newline + "}"
    raise _Unusual
