"""The one exception hierarchy of mppf.

Every error a user can meet is an :class:`MppfError`. Each class also derives from
the built-in exception it resembles, so library users can catch either. The command
line maps the classes to exit codes (see ``docs/architecture.md``):

====  =======================================================
code  meaning
====  =======================================================
0     success
1     a bug in mppf (an exception that is not an MppfError)
2     bad input or usage (:class:`InputError` and subclasses)
3     link or PLC communication failure (:class:`LinkError`)
4     press fault or refusal (:class:`PressFault`, :class:`PlcError`)
130   cancelled by the operator (Ctrl-C); the press was stopped
====  =======================================================

Messages say what happened, the value seen, what was expected, and what to do; the
"what to do" part goes in ``hint``.
"""

from __future__ import annotations

EXIT_OK = 0
EXIT_BUG = 1
EXIT_INPUT = 2
EXIT_LINK = 3
EXIT_PRESS = 4
EXIT_CANCELLED = 130


class MppfError(Exception):
    """Root of all mppf errors.

    Parameters
    ----------
    message : str
        What happened, with the value seen and what was expected.
    hint : str, optional
        What the user should do about it.
    """

    exit_code = EXIT_BUG

    def __init__(self, message: str, *, hint: str | None = None):
        super().__init__(message)
        self.message = message
        self.hint = hint

    def __str__(self) -> str:
        return self.message if not self.hint else f"{self.message} ({self.hint})"


class InputError(MppfError, ValueError):
    """Bad input: a file, an option, a configuration or a value out of range."""

    exit_code = EXIT_INPUT


class FileFormatError(InputError):
    """A file that cannot be read as what it claims to be (names file and line)."""

    def __init__(self, path, message: str, *, line: int | None = None, hint: str | None = None):
        where = f"{path}" if line is None else f"{path}, line {line}"
        super().__init__(f"{where}: {message}", hint=hint)
        self.path = path
        self.line = line


class GeometryError(InputError):
    """Geometry that cannot be used: too few points, collinear, folds over, no overlap."""


class ConfigError(InputError):
    """A press description, register map or job file with missing or mistyped keys."""


class LimitError(InputError):
    """Values outside the allowed range (strokes beyond limits, plate larger than bed)."""


class LinkError(MppfError, ConnectionError):
    """The link to the PLC failed: no connection, no reply, invalid reply, lost link."""

    exit_code = EXIT_LINK


class PlcError(MppfError):
    """The PLC answered, and refused: a Modbus exception reply (the link itself is fine).

    A sibling of :class:`LinkError`, not a kind of it: a refusal exits 4 like a press
    refusal, a failed link 3.
    """

    exit_code = EXIT_PRESS


class PressFault(MppfError):
    """The press faulted or refused: e-stop, punch fault, watchdog, refusal of GO."""

    exit_code = EXIT_PRESS


class PressRefused(PressFault):
    """The PLC (or the driver's own safety checks) refused to start motion."""


class Cancelled(MppfError):
    """The operator cancelled (Ctrl-C); the press has been sent STOP."""

    exit_code = EXIT_CANCELLED
