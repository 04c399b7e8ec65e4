"""The register map's data model: fields, code tables and the map with its look-ups.

:mod:`mppf.drivers.regmap` loads and checks it from ``register_map.toml`` (and re-exports
these classes). This module imports neither pymodbus nor numpy.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

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
class Code:
    """A named code of a table of the map (fault, result, stop cause, command, state).

    Attributes
    ----------
    code : int
    name : str
    text : str
        What it means (a result's or fault's text, what a command does, what a state is entered by).
    from_states : str or None
        A command's states it is accepted in, in words (``from``).
    arguments : str or None
        A command's arguments, in words.
    checks : tuple of str
        A command's checks: the results it may refuse with, in the order of the result table.
    setpoints : str or None
        A state's treatment of setpoint writes: ``accept`` or ``refuse``.
    commands : tuple of str
        A state's accepted commands.
    punches : str or None
        A fault's punches, in words.
    """

    code: int
    name: str
    text: str
    from_states: str | None = None
    arguments: str | None = None
    checks: tuple[str, ...] = ()
    setpoints: str | None = None
    commands: tuple[str, ...] = ()
    punches: str | None = None


class CodeTable:
    """The codes of one table, by code and by name."""

    def __init__(self, what: str, entries: list[Code], source: str):
        self.what, self.source = what, source
        self.entries = entries
        self.by_code = {e.code: e for e in entries}
        self.by_name = {e.name: e for e in entries}
        if len(self.by_code) != len(entries) or len(self.by_name) != len(entries):
            raise ConfigError(f"{source}: a {what} code or name is defined twice")

    def code(self, name: str) -> int:
        """The code of ``name``."""
        try:
            return self.by_name[name].code
        except KeyError:
            raise ConfigError(f"register map {self.source}: no {self.what} named {name!r}",
                              hint=f"known: {', '.join(self.by_name)}") from None

    def name(self, code: int) -> str | None:
        """The name of ``code`` (None for an unknown code)."""
        entry = self.by_code.get(int(code))
        return None if entry is None else entry.name

    def text(self, code: int) -> str:
        """``NAME: text`` of a code (code 0 just its text; unknown codes named as such)."""
        entry = self.by_code.get(int(code))
        if entry is None:
            return f"unknown {self.what} code {int(code)}"
        return entry.text if entry.code == 0 else f"{entry.name}: {entry.text}"

    def __iter__(self):
        return iter(self.entries)

    def __contains__(self, name: str) -> bool:
        return name in self.by_name


@dataclass(frozen=True)
class RegisterMap:
    """The register map.

    Attributes
    ----------
    name : str
    version : int
        Map version, also in register ``map_version``.
    magic : int
        Value of the 32-bit word at ``magic`` (0x4D505046, "MPPF").
    max_rows, max_cols : int
        Largest matrix the setpoint blocks hold.
    count_mm : float
        Millimetres per count of a position register (0.01).
    max_write_registers, max_read_registers : int
        Chunk sizes for FC16 writes and FC3 reads (even: no int32 is split).
    illegal_address : int
        The Modbus exception code of a request outside the map (the only exception sent).
    fields : dict of str to Field
        Registers by name, in address order.
    commands, states, results, faults, stop_causes : CodeTable
    status_bits : dict of str to int
        Bit numbers in ``status_word``.
    status_texts : dict of str to str
    timing : dict of str to int
        The timing requirements of ``[timing]`` (ms, counts).
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
    illegal_address: int
    fields: dict
    commands: CodeTable
    states: CodeTable
    results: CodeTable
    faults: CodeTable
    stop_causes: CodeTable
    status_bits: dict
    status_texts: dict
    timing: dict
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
        """Code of command ``name`` (``"CLAIM"``, ``"GO"``, ...)."""
        return self.commands.code(name)

    def fault(self, name: str) -> int:
        """Code of fault ``name`` (e.g. ``"ESTOP"``)."""
        return self.faults.code(name)

    def fault_text(self, code: int) -> str:
        """Readable text of a fault code."""
        return self.faults.text(code)

    def result_text(self, code: int) -> str:
        """Readable text of a result code."""
        return self.results.text(code)

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
        """Index of a punch in the blocks: ``row * cols + col`` (0-based, row-major, packed)."""
        return row * cols + col

    def words_in_use(self, rows: int, cols: int) -> int:
        """Registers of one setpoint/actual block used by a ``rows x cols`` matrix."""
        self.check_shape(rows, cols)
        return 2 * rows * cols

    def bit_words_in_use(self, rows: int, cols: int) -> int:
        """Registers of one fault-bit block used by a ``rows x cols`` matrix."""
        self.check_shape(rows, cols)
        return -(-rows * cols // 16)

    def span(self, first: str, last: str) -> tuple[int, int]:
        """``(address, count)`` of the registers from field ``first`` to field ``last``."""
        return self[first].address, self[last].end - self[first].address

    def group(self, name: str) -> list[Field]:
        """The fields of one group, in address order."""
        return [f for f in self.fields.values() if f.group == name]

    @cached_property
    def total_registers(self) -> int:
        """One past the highest register of the map (computed once: the simulated PLC asks on every scan)."""
        return max(field.end for field in self.fields.values())

    # -- documentation -------------------------------------------------------------
    def render_markdown(self) -> str:
        """The PLC programmer's description of this map (``docs/register-map.md``)."""
        from mppf.drivers.regmap_doc import render_markdown

        return render_markdown(self)
