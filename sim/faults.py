"""Injectable faults of the simulated PLC and the ``--fault`` spec grammar.

=========================  ===============================================================
spec                       fault
=========================  ===============================================================
``stuck:M:R:C[@P]``        punch of matrix M (``upper``/``lower``), row R, col C (0-based)
                           stops at P % of every move (default 50); no fault bit by itself
``estop[@T]``              e-stop pressed now, or after T s of motion of the next GO
``overpressure[@T]``       overpressure fault now, or after T s of motion of the next GO
``freeze[@T]``             PLC program halts (no scan: heartbeat and status frozen, punches
                           stop, writes land in memory unacted), now or after T s of motion
``local[@T]``              the remote-enable key switch turned to local (a motion stops),
                           now or after T s of motion
``slow:MS[@T]``            every reply is delayed by MS milliseconds, now or from T s of motion
``drop[:D][@T]``           connections closed and nothing answered for D s (default 2),
                           now or after T s of motion
``restart[@T]``            PLC restart (registers back to power-on state), now or after T s
                           of motion
=========================  ===============================================================

Every ``@T`` is a time from the start of motion: T simulated seconds into the motion of the
current or next GO (they scale with the time scale like the motion itself). The durations
(``drop:D``, ``slow:MS``) are wall-clock.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from mppf.core.errors import InputError

KINDS = ("stuck", "estop", "overpressure", "freeze", "slow", "drop", "restart", "local")
GRAMMAR = (
    "stuck:upper|lower:ROW:COL@PERCENT, estop@T, overpressure@T, freeze@T, local@T, slow:MS@T, drop:DURATION@T, "
    "restart@T (the @... parts and :DURATION may be left out; T = seconds into the motion)"
)


@dataclass(frozen=True)
class FaultSpec:
    """A parsed fault: ``kind`` and the keyword arguments of ``SimHandle.inject`` (``mppf.sim.plc.host``)."""

    kind: str
    params: dict = field(default_factory=dict)


def _number(text: str, what: str, spec: str, *, integer: bool = False, minimum: float = 0.0) -> float:
    try:
        value = int(text) if integer else float(text)
    except ValueError:
        kind = "a whole number" if integer else "a number"
        raise InputError(f"fault spec {spec!r}: {what} must be {kind}, got {text!r}", hint=f"grammar: {GRAMMAR}") from None
    if not value >= minimum or value != value or value in (float("inf"),):
        raise InputError(f"fault spec {spec!r}: {what} must be >= {minimum}, got {text!r}", hint=f"grammar: {GRAMMAR}")
    return value


def parse_fault_spec(spec: str) -> FaultSpec:
    """Parse one ``--fault`` spec (grammar in the module docstring).

    Raises
    ------
    InputError
        An unknown fault or a malformed value; the message names the spec and the grammar.
    """
    text = spec.strip()
    at = None
    if "@" in text:
        text, at = text.split("@", 1)
    parts = text.split(":")
    kind = parts[0].lower()
    args = parts[1:]
    bad_arity = InputError(f"fault spec {spec!r}: wrong number of ':' fields for {kind!r}", hint=f"grammar: {GRAMMAR}")
    if kind == "stuck":
        if len(args) != 3:
            raise bad_arity
        matrix = args[0].lower()
        if matrix not in ("upper", "lower"):
            raise InputError(f"fault spec {spec!r}: matrix must be 'upper' or 'lower', got {args[0]!r}", hint=f"grammar: {GRAMMAR}")
        params = {
            "matrix": matrix,
            "row": int(_number(args[1], "ROW", spec, integer=True)),
            "col": int(_number(args[2], "COL", spec, integer=True)),
        }
        if at is not None:
            percent = _number(at, "PERCENT", spec)
            if percent > 100:
                raise InputError(f"fault spec {spec!r}: PERCENT must be 0..100, got {at!r}", hint=f"grammar: {GRAMMAR}")
            params["percent"] = percent
        return FaultSpec("stuck", params)
    if kind in ("estop", "overpressure", "freeze", "local", "restart"):
        if args:
            raise bad_arity
        return FaultSpec(kind, {} if at is None else {"after_s": _number(at, "T", spec)})
    if kind == "slow":
        if len(args) != 1:
            raise bad_arity
        params = {"delay_ms": _number(args[0], "MS", spec)}
        if at is not None:
            params["after_s"] = _number(at, "T", spec)
        return FaultSpec("slow", params)
    if kind == "drop":
        if len(args) > 1:
            raise bad_arity
        params = {}
        if args:
            params["duration_s"] = _number(args[0], "DURATION", spec)
        if at is not None:
            params["after_s"] = _number(at, "T", spec)
        return FaultSpec("drop", params)
    raise InputError(f"unknown fault {kind!r} in spec {spec!r}", hint=f"known faults: {GRAMMAR}")
