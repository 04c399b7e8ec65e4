"""The register map of the press PLC, loaded from ``drivers/register_map.toml``.

The driver and the simulated PLC both use this module; no register number appears
anywhere else. It also holds the encoding rules shared by both sides: positions as
signed int32 counts of 0.01 mm, the word order of 32-bit values (``"ABCD"``: high word
first, ``"CDAB"``: low word first), the CRC-32 of the setpoint blocks, and the chunking
of long writes. ``docs/register-map.md`` is :func:`RegisterMap.render_markdown` of the
packaged map (``python -m mppf.drivers.regmap > docs/register-map.md``).

This module does not import pymodbus.
"""

from __future__ import annotations

import tomllib
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mppf.core.errors import ConfigError, InputError, LimitError

WORD_ORDERS = ("ABCD", "CDAB")
INT32_MIN = -(2**31)
INT32_MAX = 2**31 - 1
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
        return _render_markdown(self)


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


# ---------------------------------------------------------------------------------
# Encoding
# ---------------------------------------------------------------------------------
def check_word_order(word_order: str) -> str:
    """Return ``word_order`` if it is ``"ABCD"`` or ``"CDAB"``, else raise InputError."""
    if word_order not in WORD_ORDERS:
        raise InputError(
            f"word order must be one of {WORD_ORDERS}, got {word_order!r}",
            hint="ABCD = high word first (big-endian), CDAB = low word first",
        )
    return word_order


def mm_to_counts(values_mm, count_mm: float = 0.01) -> np.ndarray:
    """Millimetres to position counts (0.01 mm), rounded to the nearest count.

    Parameters
    ----------
    values_mm : array_like of float, any shape
    count_mm : float
        Millimetres per count.

    Returns
    -------
    counts : int64 array, same shape

    Raises
    ------
    LimitError
        A value is not finite or does not fit a signed int32 after scaling.
    """
    values = np.asarray(values_mm, dtype=float)
    if not np.all(np.isfinite(values)):
        bad = values[~np.isfinite(values)].ravel()[0]
        raise LimitError(f"position {bad} mm is not a finite number", hint="fill inactive punches with parking heights")
    counts = np.rint(values / count_mm)
    if values.size and (counts.min() < INT32_MIN or counts.max() > INT32_MAX):
        worst = values.ravel()[np.argmax(np.abs(counts.ravel()))]
        raise LimitError(
            f"position {worst} mm does not fit a signed 32-bit register in {count_mm} mm counts",
            hint=f"positions must lie within +-{INT32_MAX * count_mm:.0f} mm",
        )
    return counts.astype(np.int64)


def counts_to_mm(counts, count_mm: float = 0.01) -> np.ndarray:
    """Position counts to millimetres (float array of the same shape)."""
    return np.asarray(counts, dtype=np.int64) * count_mm


def encode_int32(values, word_order: str = "ABCD") -> list[int]:
    """Signed int32 values to 16-bit register words.

    Parameters
    ----------
    values : array_like of int, (n,)
    word_order : {"ABCD", "CDAB"}
        ABCD: high word first; CDAB: low word first (bytes within a word stay big-endian).

    Returns
    -------
    words : list of int, 2n values in 0..65535

    Raises
    ------
    LimitError
        A value outside the int32 range.
    """
    check_word_order(word_order)
    vals = np.asarray(values, dtype=np.int64).ravel()
    if vals.size and (vals.min() < INT32_MIN or vals.max() > INT32_MAX):
        raise LimitError(f"value {vals[np.argmax(np.abs(vals))]} does not fit a signed int32")
    unsigned = vals & 0xFFFFFFFF
    return _split_words(unsigned, word_order)


def encode_uint32(values, word_order: str = "ABCD") -> list[int]:
    """Unsigned 32-bit values (0..2**32-1) to register words (see :func:`encode_int32`)."""
    check_word_order(word_order)
    vals = np.asarray(values, dtype=np.int64).ravel()
    if vals.size and (vals.min() < 0 or vals.max() > 0xFFFFFFFF):
        raise LimitError(f"value {vals[np.argmax(np.abs(vals))]} does not fit an unsigned 32-bit register pair")
    return _split_words(vals, word_order)


def _split_words(unsigned: np.ndarray, word_order: str) -> list[int]:
    high = (unsigned >> 16) & 0xFFFF
    low = unsigned & 0xFFFF
    pairs = (high, low) if word_order == "ABCD" else (low, high)
    return np.column_stack(pairs).ravel().astype(int).tolist()


def _join_words(words, word_order: str) -> np.ndarray:
    check_word_order(word_order)
    arr = np.asarray(words, dtype=np.int64).ravel()
    if arr.size % 2:
        raise InputError(f"32-bit values need an even number of registers, got {arr.size}")
    if arr.size and (arr.min() < 0 or arr.max() > 0xFFFF):
        raise InputError("register words must lie in 0..65535")
    first, second = arr[0::2], arr[1::2]
    high, low = (first, second) if word_order == "ABCD" else (second, first)
    return (high << 16) | low


def decode_int32(words, word_order: str = "ABCD") -> np.ndarray:
    """Register words (2n) to signed int32 values, int64 array (n,)."""
    unsigned = _join_words(words, word_order)
    return np.where(unsigned >= 2**31, unsigned - 2**32, unsigned)


def decode_uint32(words, word_order: str = "ABCD") -> np.ndarray:
    """Register words (2n) to unsigned 32-bit values, int64 array (n,)."""
    return _join_words(words, word_order)


def detect_word_order(words, magic: int) -> str:
    """Word order in which the two ``magic`` registers decode to ``magic``.

    Raises
    ------
    InputError
        Neither order gives the magic (not an mppf PLC, or a wrong register map).
    """
    for order in WORD_ORDERS:
        if len(words) == 2 and int(decode_uint32(words, order)[0]) == magic:
            return order
    raise InputError(
        f"registers {list(words)} are not the magic 0x{magic:08X} in either word order",
        hint="is this an mppf press PLC with the same register map?",
    )


def setpoint_crc32(upper_words, lower_words) -> int:
    """CRC-32 of the setpoint registers in use, as written.

    The CRC is the IEEE 802.3 CRC-32 (as ``zlib.crc32``, initial value 0xFFFFFFFF,
    reflected, final XOR 0xFFFFFFFF) over the bytes of the upper setpoint registers in
    use (``2 * rows * cols`` registers from ``upper_setpoints``, in address order)
    followed by those of the lower block, each register as two bytes, high byte first
    (as on the wire). It therefore depends on the word order.

    Parameters
    ----------
    upper_words, lower_words : sequence of int, (2 * rows * cols,)
        Register words in address order.

    Returns
    -------
    crc : int, 0..2**32-1
    """
    data = np.concatenate(
        [np.asarray(upper_words, dtype=np.int64).ravel(), np.asarray(lower_words, dtype=np.int64).ravel()]
    )
    if data.size and (data.min() < 0 or data.max() > 0xFFFF):
        raise InputError("register words must lie in 0..65535")
    return zlib.crc32(data.astype(">u2").tobytes()) & 0xFFFFFFFF


def chunks(start: int, words, max_regs: int = 122) -> list[tuple[int, list[int]]]:
    """Split a write of ``words`` at register ``start`` into requests of at most ``max_regs``.

    Every chunk but the last has an even length, so with ``start`` even no int32
    (register pair) is split across two requests.

    Returns
    -------
    list of (address, words)
    """
    if max_regs < 2:
        raise InputError(f"max_regs must be at least 2, got {max_regs}")
    step = max_regs - (max_regs % 2)
    words = list(words)
    return [(start + i, words[i : i + step]) for i in range(0, len(words), step)]


def pack_bits(flags) -> list[int]:
    """Booleans (n,) to registers, 16 per register, least significant bit first."""
    bits = np.asarray(flags, dtype=bool).ravel()
    padded = np.zeros(-(-bits.size // 16) * 16, dtype=np.int64)
    padded[: bits.size] = bits
    weights = 1 << np.arange(16, dtype=np.int64)
    return (padded.reshape(-1, 16) @ weights).astype(int).tolist()


def unpack_bits(words, n: int) -> np.ndarray:
    """Registers to ``n`` booleans (inverse of :func:`pack_bits`)."""
    arr = np.asarray(words, dtype=np.int64).ravel()
    bits = ((arr[:, None] >> np.arange(16)) & 1).astype(bool).ravel()
    if bits.size < n:
        raise InputError(f"{arr.size} registers hold {bits.size} bits, {n} needed")
    return bits[:n]


# ---------------------------------------------------------------------------------
# Documentation
# ---------------------------------------------------------------------------------
_INTRO = """\
# Register map of the press PLC

This page is generated from `drivers/register_map.toml` by
`python -m mppf.drivers.regmap > docs/register-map.md`; edit the TOML, not this page.
The mppf driver and the simulated PLC (`mppf sim`) both read that file.

## Conventions
- Everything is a **holding register** (read: function 3; write: function 16, function 6
  for single registers). Addresses are 0-based protocol addresses (mbpoll: `-0`).
- Positions are **signed int32 in 0.01 mm** (`12345` = 123.45 mm), tip heights in press z.
- 32-bit values use two registers in a **word order** configured on the PLC: `ABCD`
  (high word first) or `CDAB` (low word first); the bytes inside a register are always
  high byte first. Registers {magic_span} hold the **magic** 0x{magic:08X} ("MPPF"): the master reads
  them on connect and decodes them in both orders; the one that gives the magic is the
  PLC's order (ABCD: `0x4D50 0x5046`, CDAB: `0x5046 0x4D50`). Anything else: not an mppf PLC.
- Setpoint, actual and fault-bit blocks are in **punch index** order,
  `index = row * cols + col` (row-major, packed), with `rows`/`cols` the press size in
  registers {rows} and {cols}. Punch `index` uses registers `block + 2*index` and `+1`; its fault bit
  is bit `index % 16` (bit 0 = least significant) of register `block + index // 16`.
  Registers past the matrix in use are ignored.
- Registers marked **ro** may only be read by the master: a write that touches one is
  refused with exception {read_only} (ILLEGAL DATA ADDRESS) and nothing of that write is applied;
  so is a write to the unused registers between the fields (they read as 0).

## Handshake of a press step
1. **Upload**: the master writes the upper and lower setpoint blocks (chunks of at most
   {max_write} registers, so no int32 is split). Any write to a setpoint register clears
   the `data_valid` bit.
2. **Verify**: the master reads every written register back and compares.
3. **Validate**: the master writes `setpoint_crc` and `job_sequence` in one request
   (registers {job_first}-{job_last}, CRC first). On the write that contains `job_sequence` the PLC
   computes the CRC of its setpoint registers (below) and checks every setpoint against
   its own stroke limits (`upper_min`...`lower_max`). If both pass it stores the
   sequence in `acknowledged_sequence` and sets `data_valid`; otherwise it refuses the
   write with exception {refused} (ILLEGAL DATA VALUE) and puts the reason
   (`CRC_MISMATCH`, `LIMIT`; `SEQUENCE_MISMATCH` for sequence 0) in `refusal_code`.
4. **GO**: the master writes `command` = GO and `command_arg` = the job sequence in one
   request. The PLC accepts only if there is no e-stop, no latched fault, no motion in
   progress, the CRC still matches the setpoint registers (a foreign write since
   validation is caught here), every setpoint is within limits, `command_arg` equals
   `acknowledged_sequence` and `data_valid` is set. Otherwise it refuses with exception
   {refused} and the reason in `refusal_code`; nothing moves. A GO repeating the sequence of
   the motion in progress is accepted and does nothing (a retried GO cannot start a
   second motion).
5. **Follow**: the master polls `status_word` until `busy` clears, then reads the actual
   blocks and checks them against the setpoints. `in_position` is set when motion has
   ended and every punch is within the PLC's position tolerance.

**STOP** is always accepted and decelerates every punch to a standstill. **RESET**
clears a latched fault and the per-punch fault bits; it is refused (`ESTOP_ACTIVE`)
while the e-stop is still pressed. After a refused write, `refusal_code` holds the
reason until the next accepted command.

## Watchdog
The master changes `master_heartbeat` (any new value) at least every half watchdog
time. The PLC sets `remote` while the heartbeat changes within its watchdog time. If
the heartbeat goes stale **during motion** (no change for the watchdog time, counted from
the later of the last change and the GO), the PLC brakes every punch and latches fault
`WATCHDOG`.

## Setpoint CRC
`setpoint_crc` is the IEEE 802.3 CRC-32 (as zlib `crc32`: reflected polynomial
0xEDB88320, initial value 0xFFFFFFFF, final XOR 0xFFFFFFFF) over the bytes of the
`2 * rows * cols` upper setpoint registers in use, in address order, followed by the
`2 * rows * cols` lower setpoint registers in use; each register contributes two bytes,
high byte first, exactly as written (so the CRC depends on the word order). The CRC
itself is a uint32 in the PLC's word order.
"""


def _render_markdown(rmap: RegisterMap) -> str:
    lines = [
        _INTRO.format(
            read_only=rmap.exceptions["read_only"],
            refused=rmap.exceptions["refused"],
            max_write=rmap.max_write_registers,
            magic_span=f"{rmap['magic'].address}-{rmap['magic'].end - 1}",
            magic=rmap.magic,
            rows=rmap["rows"].address,
            cols=rmap["cols"].address,
            job_first=min(rmap["setpoint_crc"].address, rmap["job_sequence"].address),
            job_last=max(rmap["setpoint_crc"].end, rmap["job_sequence"].end) - 1,
        ),
        "## Registers",
        f"Map version {rmap.version}, magic 0x{rmap.magic:08X}, up to {rmap.max_rows} x "
        f"{rmap.max_cols} punches per matrix, one count = {rmap.count_mm} mm.",
        "",
        "| address | count | name | type | access | description |",
        "|---:|---:|---|---|---|---|",
    ]
    for f in rmap.fields.values():
        span = f"{f.address}" if f.count == 1 else f"{f.address}-{f.end - 1}"
        lines.append(f"| {span} | {f.count} | `{f.name}` | {f.type} | {f.access} | {f.description} |")
    lines += ["", "## Commands", "", "| code | command |", "|---:|---|"]
    lines += [f"| {code} | {name} |" for name, code in rmap.commands.items()]
    lines += ["", "## Status bits (`status_word`)", "", "| bit | name |", "|---:|---|"]
    lines += [f"| {bit} | `{name}` |" for name, bit in sorted(rmap.status_bits.items(), key=lambda kv: kv[1])]
    lines += [
        "",
        "## Fault codes",
        "",
        "`fault_code` holds latched faults (kind *fault*: motion stopped, RESET needed);",
        "`refusal_code` holds the reason of the last refused write (kind *refusal*).",
        "",
        "| code | name | kind | meaning |",
        "|---:|---|---|---|",
    ]
    lines += [f"| {fc.code} | {fc.name} | {fc.kind} | {fc.text} |" for fc in rmap.fault_codes.values()]
    lines += [
        "",
        "## Modbus exception replies",
        "",
        "| code | when |",
        "|---:|---|",
        f"| {rmap.exceptions['read_only']} | a write touches a read-only or unused register |",
        f"| {rmap.exceptions['refused']} | a command or the job block is refused (reason in `refusal_code`) |",
        "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover - documentation generator
    print(load_register_map().render_markdown(), end="")
