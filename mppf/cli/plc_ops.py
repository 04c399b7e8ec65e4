"""The light PLC commands' work, without click: ``mppf stop`` runs it straight from :func:`mppf.cli.main`.

STOP is the one command whose start time matters for safety: :func:`mppf.cli.main` runs a
plain ``mppf stop --plc URL [--audit PATH]`` here without importing click (or rich, numpy,
pymodbus, the planner); every other form of the command line goes through click and the
``stop`` command of :mod:`mppf.cli.press_cmd`, which calls the same :func:`stop_plc`.
"""

from __future__ import annotations


def open_audit(audit_path=None):
    """The audit log at ``audit_path`` (None: the default one)."""
    from mppf.drivers.audit import AuditLog

    return AuditLog(audit_path)


def connect_session(plc_url: str, *, audit=None, **options):
    """A connected :class:`~mppf.drivers.modbus_session.ModbusSession`: status, STOP, RESET (no numpy)."""
    from mppf.drivers.modbus_session import ModbusSession

    return ModbusSession(plc_url, audit=audit, **options)


def stop_plc(plc_url: str, audit_path=None) -> None:
    """STOP the PLC at ``plc_url`` and say what state it took it in.

    Over TCP the STOP leaves first, on a bare socket (:mod:`mppf.drivers.fast_stop`), and is
    recorded in the audit log right after; anything else (RTU, a device that is not an mppf
    PLC of this map, no answer) takes the full session, audited ahead, which says what answered.
    """
    from mppf.drivers.fast_stop import NotHere, finish_stop, stop_over_tcp

    try:
        sent = stop_over_tcp(plc_url)
    except NotHere:
        sent = None
    if sent is not None:
        from mppf.core.errors import PressFault
        from mppf.drivers.url import parse_plc_url

        with open_audit(audit_path) as audit:
            state = finish_stop(sent, audit)
        where = parse_plc_url(plc_url)
        if state.startswith("STOP NOT TAKEN"):
            raise PressFault(f"STOP sent to {where}, but the PLC did not take it (stop_request stayed 1)",
                             hint="stop the press at the machine, then check the PLC")
        print(f"STOP sent to {where}: the PLC took it (state {state})", flush=True)
        return
    with connect_session(plc_url, audit=open_audit(audit_path), heartbeat_s=None) as plc:
        plc.stop("mppf stop")
        state = plc.status().state
    print(f"STOP sent to {plc.url}: the PLC took it (state {state})", flush=True)


def stop_arguments(args: list[str]) -> tuple[str, str | None] | None:
    """``(url, audit path)`` of a plain ``stop --plc URL [--audit PATH]`` command line, else None."""
    if not args or args[0] != "stop":
        return None
    found: dict[str, str] = {}
    rest = list(args[1:])
    while rest:
        word = rest.pop(0)
        key, _, value = word.partition("=")
        if key not in ("--plc", "--audit") or key in found:
            return None  # anything else (help, errors, unknown options): click decides
        if not value:
            if not rest or rest[0].startswith("-"):
                return None
            value = rest.pop(0)
        found[key] = value
    return (found["--plc"], found.get("--audit")) if "--plc" in found else None
