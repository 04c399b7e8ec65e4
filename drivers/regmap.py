"""The register map of the press PLC, loaded from ``drivers/register_map.toml``.

The driver and the simulated PLC both use this module; no register number appears
anywhere else. The encodings both sides share (int32 counts, word order, CRC, chunking)
are :mod:`mppf.drivers.codec`; ``docs/register-map.md`` is
:meth:`RegisterMap.render_markdown` of the packaged map (:mod:`mppf.drivers.regmap_doc`;
``python -m mppf.drivers.regmap > docs/register-map.md``).

This module does not import pymodbus.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

from mppf.core.errors import ConfigError, LimitError

TYPES = ("uint16", "int32", "uint32", "int32_array", "bit_array")
ACCESS = ("ro", "rw")


@dataclass(frozen=True)
class Field:
    """One named register or block of registers.

    Attributes
    ----------
    name : str
    address : int
        First register (0-based protocol address, holding registers).
    count : int
        Number of 16-bit registers.
    type : str
        ``uint16``, ``int32``, ``uint32``, ``int32_array`` or ``bit_array``.
    access : str
        ``ro`` (the master may only read) or ``rw``.
    group : str
    description : str
    """

    name: str
    address: int
    count: int
    type: str
    access: str
    group: str
    description: str

    @property
    def end(self) -> int:
        """One past the last register."""
        return self.address + self.count

    @property
    def writable(self) -> bool:
        """True if the master may write it."""
        return self.access == "rw"


@dataclass(frozen=True)
class FaultCode:
    """A fault or refusal code of ``fault_code`` / ``refusal_code``."""

    code: int
    name: str
    kind: str
    text: str


@dataclass(frozen=True)
class RegisterMap:
    """The register map.

    Attributes
    ----------
    name : str
    version : int
        Map version, also in register ``map_version``.
    magic : int
        Value of the int32 at ``magic`` (0x4D505046, "MPPF").
    max_rows, max_cols : int
        Largest matrix the setpoint blocks hold.
    count_mm : float
        Millimetres per count of a position register (0.01).
    max_write_registers, max_read_registers : int
        Chunk sizes for FC16 writes and FC3 reads (even: no int32 is split).
    fields : dict of str to Field
        Registers by name, in address order.
    commands : dict of str to int
        Command codes (``GO``, ``STOP``, ``RESET``...).
    status_bits : dict of str to int
        Bit numbers in ``status_word``.
    fault_codes : dict of int to FaultCode
    exceptions : dict of str to int
        Modbus exception codes the PLC replies with (``read_only``, ``refused``).
    source : str
        Path of the TOML file.
    """

    name: str
    version: int
    magic: int
    max_rows: int
    max_cols: int
    count_mm: float
    max_write_registers: int
    max_read_registers: int
    fields: dict
    commands: dict
    status_bits: dict
    fault_codes: dict
    exceptions: dict
    source: str = ""

    # -- look-ups ------------------------------------------------------------------
    def __getitem__(self, name: str) -> Field:
        try:
            return self.fields[name]
        except KeyError:
            raise ConfigError(
                f"register map {self.source}: no register named {name!r}",
                hint=f"known registers: {', '.join(self.fields)}",
            ) from None

    def command(self, name: str) -> int:
        """Code of command ``name`` (``"GO"``, ``"STOP"``, ``"RESET"``)."""
        try:
            return self.commands[name]
        except KeyError:
            raise ConfigError(f"register map {self.source}: no command named {name!r}") from None

    def fault(self, name: str) -> int:
        """Code of fault/refusal ``name`` (e.g. ``"CRC_MISMATCH"``)."""
        for code, entry in self.fault_codes.items():
            if entry.name == name:
                return code
        raise ConfigError(f"register map {self.source}: no fault code named {name!r}")

    def fault_text(self, code: int) -> str:
        """Readable text of a fault or refusal code (unknown codes are named as such)."""
        entry = self.fault_codes.get(int(code))
        if entry is None:
            return f"unknown fault code {int(code)}"
        return entry.text if entry.code == 0 else f"{entry.name}: {entry.text}"

    def status_flags(self, word: int) -> dict[str, bool]:
        """Decode ``status_word`` into ``{bit name: bool}``."""
        return {name: bool((int(word) >> bit) & 1) for name, bit in self.status_bits.items()}

    def status_word(self, **flags: bool) -> int:
        """Encode status flags (names of :attr:`status_bits`) into ``status_word``."""
        word = 0
        for name, value in flags.items():
            if name not in self.status_bits:
                raise ConfigError(f"register map {self.source}: no status bit named {name!r}")
            if value:
                word |= 1 << self.status_bits[name]
        return word

    # -- layout --------------------------------------------------------------------
    def check_shape(self, rows: int, cols: int) -> None:
        """Raise :class:`LimitError` unless ``rows x cols`` fits the setpoint blocks."""
        if not (1 <= rows <= self.max_rows and 1 <= cols <= self.max_cols):
            raise LimitError(
                f"matrix of {rows} x {cols} punches does not fit the register map "
                f"(at most {self.max_rows} x {self.max_cols})",
                hint="check rows and cols of the press description",
            )

    def punch_index(self, row: int, col: int, cols: int) -> int:
        """Index of a punch in the blocks: ``row * cols + col`` (row-major, packed)."""
        return row * cols + col

    def words_in_use(self, rows: int, cols: int) -> int:
        """Registers of one setpoint/actual block used by a ``rows x cols`` matrix."""
        self.check_shape(rows, cols)
        return 2 * rows * cols

    def bit_words_in_use(self, rows: int, cols: int) -> int:
        """Registers of one fault-bit block used by a ``rows x cols`` matrix."""
        self.check_shape(rows, cols)
        return -(-rows * cols // 16)

    def field_at(self, address: int) -> Field | None:
        """The field holding register ``address``, or None."""
        for field in self.fields.values():
            if field.address <= address < field.end:
                return field
        return None

    @property
    def total_registers(self) -> int:
        """One past the highest register of the map."""
        return max(field.end for field in self.fields.values())

    # -- documentation -------------------------------------------------------------
    def render_markdown(self) -> str:
        """The PLC programmer's description of this map (``docs/register-map.md``)."""
        from mppf.drivers.regmap_doc import render_markdown

        return render_markdown(self)


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
    return value


def _load_fields(data: dict, src: str) -> dict:
    fields: dict[str, Field] = {}
    for i, entry in enumerate(data.get("register", [])):
        where = f"{src}: [[register]] #{i + 1}"
        field = Field(
            name=_need(entry, "name", str, where),
            address=_need(entry, "address", int, where),
            count=_need(entry, "count", int, where),
            type=_need(entry, "type", str, where),
            access=_need(entry, "access", str, where),
            group=_need(entry, "group", str, where),
            description=_need(entry, "description", str, where),
        )
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


def register_map_from_dict(data: dict, source: str = "register map") -> RegisterMap:
    """Build and validate a :class:`RegisterMap` from the TOML layout.

    Raises
    ------
    ConfigError
        Missing or mistyped keys, overlapping registers, blocks too small for the
        declared matrix size, or a required register/command/bit missing.
    """
    head = data.get("map")
    if not isinstance(head, dict):
        raise ConfigError(f"{source}: missing table [map]")
    where = f"{source}: [map]"
    fields = _load_fields(data, source)
    fault_codes: dict[int, FaultCode] = {}
    for i, entry in enumerate(data.get("fault_codes", [])):
        w = f"{source}: [[fault_codes]] #{i + 1}"
        fc = FaultCode(
            _need(entry, "code", int, w), _need(entry, "name", str, w), _need(entry, "kind", str, w), _need(entry, "text", str, w)
        )
        if fc.code in fault_codes:
            raise ConfigError(f"{w}: code {fc.code} is defined twice")
        fault_codes[fc.code] = fc
    rmap = RegisterMap(
        name=_need(head, "name", str, where),
        version=_need(head, "version", int, where),
        magic=_need(head, "magic", int, where),
        max_rows=_need(head, "max_rows", int, where),
        max_cols=_need(head, "max_cols", int, where),
        count_mm=float(_need(head, "count_mm", float, where)),
        max_write_registers=_need(head, "max_write_registers", int, where),
        max_read_registers=_need(head, "max_read_registers", int, where),
        fields=fields,
        commands={str(k): int(v) for k, v in data.get("commands", {}).items()},
        status_bits={str(k): int(v) for k, v in data.get("status_bits", {}).items()},
        fault_codes=fault_codes,
        exceptions={str(k): int(v) for k, v in data.get("exceptions", {}).items()},
        source=source,
    )
    required = [
        "magic", "map_version", "rows", "cols", "command", "command_arg", "setpoint_crc",
        "job_sequence", "master_heartbeat", "status_word", "fault_code", "refusal_code",
        "acknowledged_sequence", "plc_heartbeat",
    ]  # fmt: skip
    for name in required:
        rmap[name]  # raises ConfigError naming the missing register
    n = rmap.max_rows * rmap.max_cols
    for side in ("upper", "lower"):
        for block, need in ((f"{side}_setpoints", 2 * n), (f"{side}_actuals", 2 * n), (f"{side}_fault_bits", -(-n // 16))):
            if rmap[block].count < need:
                raise ConfigError(
                    f"{source}: block {block!r} has {rmap[block].count} registers, "
                    f"{rmap.max_rows} x {rmap.max_cols} punches need {need}"
                )
    for name in ("GO", "STOP", "RESET"):
        rmap.command(name)
    for name in ("ready", "busy", "in_position", "fault", "estop", "remote", "data_valid"):
        if name not in rmap.status_bits:
            raise ConfigError(f"{source}: [status_bits] lacks {name!r}")
    for key in ("read_only", "refused"):
        if key not in rmap.exceptions:
            raise ConfigError(f"{source}: [exceptions] lacks {key!r}")
    if rmap.max_write_registers % 2 or rmap.max_read_registers % 2:
        raise ConfigError(f"{where}: max_write_registers and max_read_registers must be even")
    return rmap


def load_register_map(path=None) -> RegisterMap:
    """Load a register map (default: the packaged ``register_map.toml``).

    Raises
    ------
    ConfigError
        The file is missing, not TOML, or not a valid map.
    """
    path = default_map_path() if path is None else Path(path)
    try:
        with path.open("rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(f"register map {path} does not exist") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"register map {path}: not valid TOML: {exc}") from None
    return register_map_from_dict(data, source=str(path))


if __name__ == "__main__":  # pragma: no cover - documentation generator
    print(load_register_map().render_markdown(), end="")
