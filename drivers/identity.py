"""What a press PLC says about itself on connect, and the checks made before anything is written.

:func:`identify` reads the magic (which gives the word order), the register map version,
the matrix size and the PLC's own stroke limits in one read, and refuses a device that is
not an mppf press PLC, speaks another map version, uses another word order than asked
for, or drives another matrix than the press description.
"""

from __future__ import annotations

from dataclasses import dataclass

from mppf.core.errors import ConfigError, InputError, LinkError, PlcError
from mppf.drivers import codec
from mppf.drivers.regmap import RegisterMap

SIDES = ("upper", "lower")


@dataclass(frozen=True)
class PlcIdentity:
    """What the PLC says about itself on connect.

    Attributes
    ----------
    word_order : {"ABCD", "CDAB"}
        Detected from the magic.
    map_version, rows, cols : int
    limits_mm : dict of str to (float, float)
        The PLC's own stroke limits, ``{"upper": (min, max), "lower": (min, max)}``.
    scan_time_s : float
        The PLC's longest scan time.
    watchdog_s : float or None
        Its watchdog and lease time (None: no watchdog).
    position_tolerance_mm : float
    positioning_timeout_s, rest_time_s : float
        The PLC's positioning timeout and the time a punch must stay slow to be at rest.
    rest_speed_mm_s : float
        Below this speed a punch is slow enough to be at rest.
    dimpling_limit_mm, tip_gap_min_mm : float
        The PLC's own neighbour-step and tip-gap limits (its VALIDATE checks them).
    """

    word_order: str
    map_version: int
    rows: int
    cols: int
    limits_mm: dict
    scan_time_s: float = 0.01
    watchdog_s: float | None = 1.0
    position_tolerance_mm: float = 0.2
    positioning_timeout_s: float = 2.0
    rest_time_s: float = 0.05
    rest_speed_mm_s: float = 0.5
    dimpling_limit_mm: float = 0.0
    tip_gap_min_mm: float = 0.0


def _word_order(magic: list[int], rmap: RegisterMap, url, word_order: str) -> str:
    """The PLC's word order from its magic (LinkError: not an mppf PLC, or not the order asked for)."""
    try:
        detected = codec.detect_word_order(magic, rmap.magic)
    except InputError:
        raise LinkError(
            f"the device at {url} is not an mppf press PLC: registers "
            f"{rmap['magic'].address}-{rmap['magic'].end - 1} hold "
            f"0x{magic[0]:04X} 0x{magic[1]:04X}, expected the magic 0x{rmap.magic:08X} "
            "in ABCD or CDAB word order",
            hint="check the URL (host, port, unit id): another Modbus device answered",
        ) from None
    if word_order != "auto" and word_order != detected:
        raise LinkError(
            f"the PLC at {url} uses word order {detected}, but {word_order} was requested",
            hint="use --word-order auto or fix the PLC's word-order setting",
        )
    return detected


def _identity(get, rmap: RegisterMap, order: str, version: int) -> PlcIdentity:
    """The :class:`PlcIdentity` of the identity registers (``get(name)`` gives a field's words)."""
    mm = rmap.count_mm

    def i32_mm(name: str) -> float:
        return round(codec.words_to_i32(get(name), order) * mm, 6)

    (rows,), (cols,) = get("rows"), get("cols")
    limits = {side: (i32_mm(f"{side}_min"), i32_mm(f"{side}_max")) for side in SIDES}
    (scan_ms,), (watchdog_ms,), (tolerance,) = get("scan_time_max_ms"), get("watchdog_ms"), get("position_tolerance")
    (timeout_ms,), (rest_speed,), (rest_ms,) = get("positioning_timeout_ms"), get("rest_speed"), get("rest_time_ms")
    return PlcIdentity(order, version, rows, cols, limits, scan_time_s=max(scan_ms, 1) / 1000.0,
                       watchdog_s=watchdog_ms / 1000.0 or None, position_tolerance_mm=tolerance * mm,
                       positioning_timeout_s=timeout_ms / 1000.0, rest_time_s=rest_ms / 1000.0,
                       rest_speed_mm_s=rest_speed * mm, dimpling_limit_mm=i32_mm("dimpling_limit"),
                       tip_gap_min_mm=i32_mm("tip_gap_min"))


def identify(io, rmap: RegisterMap, url, unit: int, word_order: str, press=None) -> PlcIdentity:
    """Read and check magic, map version, size and limits.

    Parameters
    ----------
    io
        The register transport (``read_holding``).
    rmap : RegisterMap
    url : str or PlcUrl
        Where the PLC is (for the messages).
    unit : int
        Its unit id (for the messages).
    word_order : {"auto", "ABCD", "CDAB"}
    press : PressConfig or None
        Checked against the PLC's matrix size when given.

    Raises
    ------
    LinkError
        Not an mppf press PLC (or not at this unit id), another map version or word order.
    ConfigError
        The press description has another matrix size.
    """
    first = rmap["magic"].address
    last = max(f.end for f in rmap.group("identity"))
    try:
        words = io.read_holding(first, last - first, max_chunk=rmap.max_read_registers)
    except PlcError as exc:
        raise LinkError(
            f"the device at {url} is not an mppf press PLC with unit id {unit}: reading its "
            f"identity (registers {first}-{last - 1}) was refused: {exc.message}",
            hint="check the unit id (unit=N in the URL), the host and the port: another Modbus device answered",
        ) from None

    def get(name: str) -> list[int]:
        f = rmap[name]
        return words[f.address - first : f.end - first]

    detected = _word_order(get("magic"), rmap, url, word_order)
    (version,) = get("map_version")
    if version != rmap.version:
        raise LinkError(
            f"the PLC at {url} implements register map version {version}, "
            f"this mppf speaks version {rmap.version} only; nothing was written",
            hint=f"update the PLC program to register map version {rmap.version} (docs/register-map.md), "
                 "or use the mppf release made for its version",
        )
    ident = _identity(get, rmap, detected, version)
    rows, cols = ident.rows, ident.cols
    if press is not None and (rows, cols) != press.shape:
        raise ConfigError(
            f"the PLC at {url} drives {rows} x {cols} punches, the press description "
            f"'{press.name}' has {press.rows} x {press.cols}",
            hint="use the press description (or job) made for this press",
        )
    return ident
