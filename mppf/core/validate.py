"""The one numeric validator: every option, setting and file value that must be a number.

Messages follow the project's rule: what was wrong (the name), the value seen, the
allowed range, and (``hint``) what to do.
"""

from __future__ import annotations

import math
import numbers
import re
from dataclasses import dataclass

from mppf.core.errors import InputError


@dataclass(frozen=True)
class NumberRange:
    """The numbers :func:`check_number` accepts.

    Attributes
    ----------
    low, high : float, optional
        Bounds; inclusive unless ``low_open`` / ``high_open``.
    low_open, high_open : bool
        The bound itself is refused.
    integer : bool
        A whole number is required (returned as int).
    unit : str
        Unit named in the message ("mm", "s").
    """

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    integer: bool = False
    unit: str = ""

    def text(self) -> str:
        """The range in words (``"from 0 to 5 mm"``, ``"above 0"``, ``"finite"``)."""
        low, high, low_open, high_open = self.low, self.high, self.low_open, self.high_open
        u = f" {self.unit}" if self.unit else ""
        if low is not None and high is not None:
            return f"from {low:g} to {high:g}{u}" if not (low_open or high_open) else \
                f"{'above' if low_open else 'at least'} {low:g} and {'below' if high_open else 'at most'} {high:g}{u}"
        if low is not None:
            return f"{'above' if low_open else 'at least'} {low:g}{u}"
        if high is not None:
            return f"{'below' if high_open else 'at most'} {high:g}{u}"
        return "finite"

    def holds(self, number: float) -> bool:
        """Whether the finite ``number`` lies within the bounds."""
        below = self.low is not None and (number <= self.low if self.low_open else number < self.low)
        above = self.high is not None and (number >= self.high if self.high_open else number > self.high)
        return not (below or above)


def check_number(name: str, value, *, hint: str | None = None, error=InputError, **limits) -> float | int:
    """``value`` as a finite float (or int) within the range, or a clear error.

    Booleans and strings are refused even where Python would read them as numbers
    (``True`` is not a 1 mm stroke).

    Parameters
    ----------
    name : str
        What the value is, as the user knows it (``"--tolerance"``, ``"[press] rows"``).
    value : object
    hint : str, optional
        What to do; default: the allowed range.
    error : type
        The :class:`~mppf.core.errors.InputError` subclass to raise (``ConfigError`` for files).
    **limits
        The fields of :class:`NumberRange`: ``low``, ``high`` (bounds, inclusive unless
        ``low_open`` / ``high_open``), ``integer`` (a whole number, returned as int),
        ``unit`` (named in the message, "mm", "s").

    Returns
    -------
    float or int

    Raises
    ------
    InputError (or ``error``)
    """
    limits = NumberRange(**limits)
    allowed = limits.text()
    what = "a whole number" if limits.integer else "a number"
    if hint is None:
        hint = f"give {what} {allowed}" if allowed != "finite" else f"give a finite {what[2:]}"
    number = _finite(name, value, what, hint, error)
    if limits.integer:
        if number != int(number):
            raise error(f"{name} must be a whole number, got {value!r}", hint=hint)
        number = int(number)
    if not limits.holds(number):
        unit_text = f" {limits.unit}" if limits.unit else ""
        raise error(f"{name} must be {allowed}, got {value!r}{unit_text}", hint=hint)
    return number


def _finite(name: str, value, what: str, hint: str, error) -> float:
    """``value`` as a finite float; ``error`` for a bool, a non-number or an infinite or NaN value."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise error(f"{name} must be {what}, got {value!r}", hint=hint)
    try:
        number = float(value)
    except OverflowError:  # an integer beyond any float (a TOML or JSON file may hold one)
        number = math.inf
    if not math.isfinite(number):
        big = isinstance(value, int) and abs(value) >= 10**30
        shown = f"an integer of {len(str(abs(value)))} digits" if big else repr(value)
        raise error(f"{name} must be a finite number, got {shown}", hint=hint)
    return number


def check_positive(name: str, value, *, unit: str = "", hint: str | None = None, error=InputError) -> float:
    """``value`` as a finite float > 0 (see :func:`check_number`)."""
    return check_number(name, value, low=0.0, low_open=True, unit=unit, hint=hint, error=error)


SAFE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
"""A name that may become a file or folder name: letters, digits, ``. _ -``, at most 64, no leading dot."""


def check_name(name: str, value, *, hint: str = "", error=InputError) -> str:
    """``value`` if it is a safe file or folder name (:data:`SAFE_NAME`, no ``..``), else a clear error.

    Parameters
    ----------
    name : str
        What the value is ("plate id").
    value : object
    hint : str
        An example, added to the standard hint.

    Raises
    ------
    InputError (or ``error``)
        Another character (a path separator, markup, a space...), too long, or empty.
    """
    if not isinstance(value, str) or not SAFE_NAME.fullmatch(value) or ".." in value:
        raise error(f"{name} {value!r} is not allowed: it names a folder, so it may hold only letters, digits, "
                    "'.', '_' and '-'", hint="give at most 64 of those, no '..', starting with a letter or digit"
                    + (f" ({hint})" if hint else ""))
    return value


def safe_name(text: str, fallback: str = "plate") -> str:
    """``text`` made safe for :func:`check_name`: other characters become ``_`` (``P3[rev2]`` -> ``P3_rev2_``)."""
    name = re.sub(r"[^A-Za-z0-9._-]", "_", str(text)).replace("..", "_").lstrip("._-")[:64]
    return name or fallback
