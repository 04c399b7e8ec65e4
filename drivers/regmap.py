"""The register map of the press PLC, loaded from ``drivers/register_map.toml``.

The driver and the simulated PLC both use this module; no register number, command,
state or result code appears anywhere else. The classes are :mod:`mppf.drivers.regmap_model`'s
(re-exported here); this module loads and checks them. The encodings both sides share (int32 counts,
word order, CRC, chunking) are :mod:`mppf.drivers.codec`; ``docs/register-map.md`` is
:meth:`RegisterMap.render_markdown` of the packaged map (:mod:`mppf.drivers.regmap_doc`;
``python -m mppf.drivers.regmap > docs/register-map.md``).

This module imports neither pymodbus nor numpy (``mppf stop`` loads it).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from mppf.core.errors import ConfigError
from mppf.drivers.regmap_model import ACCESS, TYPES, Code, CodeTable, Field, RegisterMap

__all__ = ["ACCESS", "TYPES", "Code", "CodeTable", "Field", "RegisterMap", "default_map_path", "load_register_map",
           "register_map_from_dict"]

# ---------------------------------------------------------------------------------
# Loading
# ---------------------------------------------------------------------------------
def default_map_path() -> Path:
    """Path of the packaged ``register_map.toml``."""
    return Path(__file__).with_name("register_map.toml")


def _need(table: dict, key: str, kind, where: str):
    if key not in table:
        raise ConfigError(f"{where}: missing key {key!r}", hint="see drivers/register_map.toml")
    value = table[key]
    if kind is int and (isinstance(value, bool) or not isinstance(value, int)):
        raise ConfigError(f"{where}: {key} must be a whole number, got {value!r}")
    if kind is float and (isinstance(value, bool) or not isinstance(value, (int, float))):
        raise ConfigError(f"{where}: {key} must be a number, got {value!r}")
    if kind is str and not isinstance(value, str):
        raise ConfigError(f"{where}: {key} must be a string, got {value!r}")
    if kind is list and not isinstance(value, list):
        raise ConfigError(f"{where}: {key} must be a list, got {value!r}")
    return value


def _load_fields(data: dict, src: str) -> dict:
    fields: dict[str, Field] = {}
    for i, entry in enumerate(data.get("register", [])):
        where = f"{src}: [[register]] #{i + 1}"
        field = Field(*(_need(entry, key, kind, where) for key, kind in (
            ("name", str), ("address", int), ("count", int), ("type", str), ("access", str), ("group", str),
            ("description", str))))
        where = f"{src}: register {field.name!r}"
        if field.name in fields:
            raise ConfigError(f"{where} is defined twice")
        if field.type not in TYPES:
            raise ConfigError(f"{where}: type {field.type!r} is not one of {TYPES}")
        if field.access not in ACCESS:
            raise ConfigError(f"{where}: access {field.access!r} is not one of {ACCESS}")
        if field.address < 0 or field.count < 1 or field.end > 65536:
            raise ConfigError(f"{where}: registers {field.address}..{field.end - 1} outside 0..65535")
        fixed = {"uint16": 1, "int32": 2, "uint32": 2}.get(field.type)
        if fixed is not None and field.count != fixed:
            raise ConfigError(f"{where}: a {field.type} takes {fixed} register(s), count is {field.count}")
        if field.type in ("int32", "uint32", "int32_array") and field.address % 2:
            raise ConfigError(f"{where}: 32-bit values must start at an even address, got {field.address}")
        fields[field.name] = field
    ordered = sorted(fields.values(), key=lambda f: f.address)
    for a, b in zip(ordered, ordered[1:]):
        if b.address < a.end:
            raise ConfigError(
                f"{src}: registers {a.name!r} ({a.address}..{a.end - 1}) and {b.name!r} "
                f"({b.address}..{b.end - 1}) overlap"
            )
    return {f.name: f for f in ordered}


CODE_FIELDS = {"from": "from_states"}
"""Keys of a code table entry whose :class:`Code` field has another name."""


def _table(data: dict, key: str, what: str, src: str, extra: tuple = ()) -> CodeTable:
    entries = []
    for i, entry in enumerate(data.get(key, [])):
        where = f"{src}: [[{key}]] #{i + 1}"
        text_key = "text" if "text" in entry else "does" if "does" in entry else "entered"
        fields = {CODE_FIELDS.get(k, k): tuple(_need(entry, k, list, where)) if k in ("commands", "checks")
                  else _need(entry, k, str, where) for k in extra}
        entries.append(Code(_need(entry, "code", int, where), _need(entry, "name", str, where),
                            _need(entry, text_key, str, where), **fields))
    if not entries:
        raise ConfigError(f"{src}: no [[{key}]] entries")
    return CodeTable(what, entries, src)


REQUIRED_REGISTERS = (
    "magic", "map_version", "rows", "cols", "scan_time_max_ms", "watchdog_ms", "position_tolerance", "command",
    "command_counter", "command_master", "command_crc", "command_sequence", "heartbeat_master", "heartbeat_counter",
    "stop_request", "stop_master", "status_word", "state", "fault_code", "ack_counter", "ack_master", "ack_command",
    "result_code", "owner_master", "validated_crc", "validated_sequence", "motion_sequence", "motion_crc",
    "plc_heartbeat", "refused_writes", "last_sequence", "stop_count", "last_stop_master", "stop_cause",
    "command_auth", "heartbeat_auth", "owner_ack_counter", "owner_ack_command", "owner_result_code", "claim_reply",
    "positioning_timeout_ms", "rest_speed", "rest_time_ms", "dimpling_limit", "tip_gap_min", "refused_setpoint_writes",
)
REQUIRED_BITS = ("ready", "busy", "in_position", "fault", "estop", "remote_enabled", "owned", "lease_ok",
                 "setpoints_locked")


def _check_consistency(rmap: RegisterMap, src: str) -> None:
    """Every register, bit and code the driver and the PLC program use is there and coherent."""
    for name in REQUIRED_REGISTERS:
        rmap[name]  # raises ConfigError naming the missing register
    n = rmap.max_rows * rmap.max_cols
    for side in ("upper", "lower"):
        for block, need in ((f"{side}_setpoints", 2 * n), (f"{side}_actuals", 2 * n),
                            (f"{side}_fault_bits", -(-n // 16))):
            if rmap[block].count < need:
                raise ConfigError(f"{src}: block {block!r} has {rmap[block].count} registers, "
                                  f"{rmap.max_rows} x {rmap.max_cols} punches need {need}")
    for name in REQUIRED_BITS:
        if name not in rmap.status_bits:
            raise ConfigError(f"{src}: [[status_bit]] lacks {name!r}")
    for first, last in (("command", "command_sequence"), ("heartbeat_counter", "heartbeat_auth"),
                        ("stop_request", "stop_master")):
        fields = [f for f in rmap.fields.values() if rmap[first].address <= f.address < rmap[last].end]
        if sum(f.count for f in fields) != rmap[last].end - rmap[first].address:
            raise ConfigError(f"{src}: {first}..{last} must be contiguous (one request)")
    precedence = [r.name for r in rmap.results]
    for command in rmap.commands:
        checks = list(command.checks)
        unknown = [c for c in checks if c not in rmap.results]
        if unknown:
            raise ConfigError(f"{src}: command {command.name} checks unknown results {unknown}")
        if checks != sorted(checks, key=precedence.index):
            raise ConfigError(f"{src}: the checks of {command.name} are not in the order of [[result]]")
    for state in rmap.states:
        unknown = [c for c in state.commands if c not in rmap.commands]
        if unknown or state.setpoints not in ("accept", "refuse"):
            raise ConfigError(f"{src}: state {state.name}: unknown commands {unknown} or setpoints "
                              f"{state.setpoints!r} (accept or refuse)")
    if rmap.max_write_registers % 2 or rmap.max_read_registers % 2:
        raise ConfigError(f"{src}: [map] max_write_registers and max_read_registers must be even")


def register_map_from_dict(data: dict, source: str = "register map") -> RegisterMap:
    """Build and validate a :class:`RegisterMap` from the TOML layout.

    Raises
    ------
    ConfigError
        Missing or mistyped keys, overlapping registers, blocks too small for the
        declared matrix size, or a required register/command/state/bit missing.
    """
    head = data.get("map")
    if not isinstance(head, dict):
        raise ConfigError(f"{source}: missing table [map]")
    where = f"{source}: [map]"
    bits = {}
    texts = {}
    for i, entry in enumerate(data.get("status_bit", [])):
        w = f"{source}: [[status_bit]] #{i + 1}"
        name = _need(entry, "name", str, w)
        bits[name], texts[name] = _need(entry, "bit", int, w), _need(entry, "text", str, w)
    timing = data.get("timing", {})
    rmap = RegisterMap(
        name=_need(head, "name", str, where),
        version=_need(head, "version", int, where),
        magic=_need(head, "magic", int, where),
        max_rows=_need(head, "max_rows", int, where),
        max_cols=_need(head, "max_cols", int, where),
        count_mm=float(_need(head, "count_mm", float, where)),
        max_write_registers=_need(head, "max_write_registers", int, where),
        max_read_registers=_need(head, "max_read_registers", int, where),
        illegal_address=_need(head, "illegal_address", int, where),
        fields=_load_fields(data, source),
        commands=_table(data, "command", "command", source, ("from", "arguments", "checks")),
        states=_table(data, "state", "state", source, ("setpoints", "commands")),
        results=_table(data, "result", "result", source),
        faults=_table(data, "fault", "fault", source, ("punches",)),
        stop_causes=_table(data, "stop_cause", "stop cause", source),
        status_bits=bits,
        status_texts=texts,
        timing={k: _need(timing, k, int, f"{source}: [timing]") for k in timing},
        source=source,
    )
    _check_consistency(rmap, source)
    return rmap


_CACHE: dict[str, RegisterMap] = {}


def load_register_map(path=None) -> RegisterMap:
    """Load a register map (default: the packaged ``register_map.toml``, read once per process).

    Raises
    ------
    ConfigError
        The file is missing, not TOML, or not a valid map.
    """
    path = default_map_path() if path is None else Path(path)
    key = str(path.resolve())
    if key in _CACHE:
        return _CACHE[key]
    try:
        with path.open("rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(f"register map {path} does not exist") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"register map {path}: not valid TOML: {exc}") from None
    _CACHE[key] = register_map_from_dict(data, source=str(path))
    return _CACHE[key]


if __name__ == "__main__":  # pragma: no cover - documentation generator
    print(load_register_map().render_markdown(), end="")
