"""PLC addresses as URLs: ``tcp://host:port?unit=1`` and ``rtu:///dev/ttyUSB0?baud=115200&parity=E``.

Query keys
----------
tcp
    ``unit`` (Modbus device id, 1-247, default 1), ``timeout`` (s, default 1.0),
    ``retries`` (read / setpoint-write retries, default 2; commands are never retried).
rtu
    the same, plus ``baud`` (default 19200), ``parity`` (``N``, ``E`` or ``O``,
    default ``E`` as in the Modbus serial-line standard), ``stopbits`` (1 or 2, default 1),
    ``bytesize`` (7 or 8, default 8).
"""

from __future__ import annotations

from dataclasses import dataclass
from urllib.parse import parse_qs, urlsplit

from mppf.core.errors import InputError

DEFAULT_TCP_PORT = 502
_HINT = "write tcp://HOST:PORT?unit=1 or rtu:///dev/ttyUSB0?baud=115200&parity=E&unit=1"
_TCP_KEYS = {"unit", "timeout", "retries"}
_RTU_KEYS = _TCP_KEYS | {"baud", "parity", "stopbits", "bytesize"}
_BAUDS = (1200, 2400, 4800, 9600, 14400, 19200, 38400, 57600, 115200, 230400, 460800, 921600)


@dataclass(frozen=True)
class PlcUrl:
    """A parsed PLC address.

    Attributes
    ----------
    scheme : {"tcp", "rtu"}
    host : str
        TCP host ("" for rtu).
    port : int
        TCP port (0 for rtu).
    device : str
        Serial device path ("" for tcp).
    baud, bytesize, stopbits : int
        Serial settings (unused for tcp).
    parity : {"N", "E", "O"}
    unit : int
        Modbus device (unit, slave) id.
    timeout_s : float
        Reply timeout of one request.
    retries : int
        Extra attempts for reads and setpoint writes (never for command writes).
    text : str
        The URL as given.
    """

    scheme: str
    host: str = ""
    port: int = 0
    device: str = ""
    baud: int = 19200
    parity: str = "E"
    stopbits: int = 1
    bytesize: int = 8
    unit: int = 1
    timeout_s: float = 1.0
    retries: int = 2
    text: str = ""

    def __str__(self) -> str:
        if self.scheme == "tcp":
            return f"tcp://{self.host}:{self.port}?unit={self.unit}"
        return (
            f"rtu://{self.device}?baud={self.baud}&parity={self.parity}"
            f"&stopbits={self.stopbits}&unit={self.unit}"
        )

    @property
    def char_time_s(self) -> float:
        """Wire time of one byte on the serial line (start + data + parity + stop bits)."""
        bits = 1 + self.bytesize + (0 if self.parity == "N" else 1) + self.stopbits
        return bits / self.baud


def _number(url: str, key: str, text: str, kind, lo, hi):
    try:
        value = kind(text)
    except ValueError:
        raise InputError(
            f"PLC URL {url!r}: {key}={text!r} is not a number", hint=_HINT
        ) from None
    if not lo <= value <= hi:
        raise InputError(f"PLC URL {url!r}: {key}={text} is outside {lo}..{hi}", hint=_HINT)
    return value


def parse_plc_url(url: str) -> PlcUrl:
    """Parse a PLC URL.

    Parameters
    ----------
    url : str
        ``tcp://host[:port][?unit=N&timeout=S&retries=R]`` or
        ``rtu:///dev/PORT[?baud=B&parity=N|E|O&stopbits=1|2&bytesize=7|8&unit=N&timeout=S&retries=R]``.

    Returns
    -------
    PlcUrl

    Raises
    ------
    InputError
        Unknown scheme, missing host or device, unknown or repeated query keys, values out of range.
    """
    if not isinstance(url, str) or not url.strip():
        raise InputError(f"PLC URL must be a non-empty string, got {url!r}", hint=_HINT)
    url = url.strip()
    if any(ch.isspace() or ord(ch) < 32 or ord(ch) == 127 for ch in url):  # urlsplit drops tabs, keeps spaces
        raise InputError(f"PLC URL {url!r} holds a space or control character", hint=_HINT)
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError as exc:
        raise InputError(f"PLC URL {url!r} cannot be parsed: {exc}", hint=_HINT) from None
    scheme = parts.scheme.lower()
    if scheme not in ("tcp", "rtu"):
        raise InputError(f"PLC URL {url!r}: unknown scheme {parts.scheme!r} (expected tcp or rtu)", hint=_HINT)
    if parts.fragment:
        raise InputError(f"PLC URL {url!r}: unexpected '#{parts.fragment}'", hint=_HINT)
    q = _query(url, parts.query, scheme)
    common = {
        "unit": _number(url, "unit", q.get("unit", "1"), int, 1, 247),
        "timeout_s": _number(url, "timeout", q.get("timeout", "1.0"), float, 0.01, 60.0),
        "retries": _number(url, "retries", q.get("retries", "2"), int, 0, 10),
        "text": url,
    }
    if scheme == "tcp":
        if not parts.hostname:
            raise InputError(f"PLC URL {url!r}: no host", hint=_HINT)
        if parts.path not in ("", "/"):
            raise InputError(f"PLC URL {url!r}: unexpected path {parts.path!r} after the host", hint=_HINT)
        if port == 0:
            raise InputError(f"PLC URL {url!r}: port 0 is not a valid TCP port", hint=_HINT)
        return PlcUrl("tcp", host=parts.hostname, port=port or DEFAULT_TCP_PORT, **common)
    return _rtu(url, parts, q, common)


def _query(url: str, text: str, scheme: str) -> dict[str, str]:
    """The URL's query as ``{key: value}``: only the scheme's keys, each at most once (else InputError)."""
    try:
        query = parse_qs(text, keep_blank_values=True, strict_parsing=bool(text))
    except ValueError:
        raise InputError(f"PLC URL {url!r}: malformed query {text!r}", hint=_HINT) from None
    allowed = _TCP_KEYS if scheme == "tcp" else _RTU_KEYS
    unknown = sorted(set(query) - allowed)
    if unknown:
        raise InputError(
            f"PLC URL {url!r}: unknown option(s) {unknown} for {scheme}", hint=f"{scheme} takes {sorted(allowed)}"
        )
    repeated = sorted(k for k, v in query.items() if len(v) > 1)
    if repeated:
        raise InputError(f"PLC URL {url!r}: option(s) {repeated} given more than once", hint=_HINT)
    return {k: v[0] for k, v in query.items()}


def _rtu(url: str, parts, q: dict[str, str], common: dict) -> PlcUrl:
    """The serial link of an ``rtu:///dev/PORT?...`` URL: device, baud, parity, stop bits, byte size checked."""
    if parts.netloc:
        raise InputError(
            f"PLC URL {url!r}: rtu takes a device path, not a host ({parts.netloc!r})",
            hint="use three slashes: rtu:///dev/ttyUSB0",
        )
    if not parts.path or parts.path == "/":
        raise InputError(f"PLC URL {url!r}: no serial device", hint=_HINT)
    baud = _number(url, "baud", q.get("baud", "19200"), int, 300, 4_000_000)
    if baud not in _BAUDS:
        raise InputError(f"PLC URL {url!r}: baud={baud} is not a standard rate", hint=f"use one of {_BAUDS}")
    parity = q.get("parity", "E").upper()
    if parity not in ("N", "E", "O"):
        raise InputError(f"PLC URL {url!r}: parity={q['parity']!r} (expected N, E or O)", hint=_HINT)
    stopbits = _number(url, "stopbits", q.get("stopbits", "1"), int, 1, 2)
    bytesize = _number(url, "bytesize", q.get("bytesize", "8"), int, 7, 8)
    return PlcUrl(
        "rtu", device=parts.path, baud=baud, parity=parity, stopbits=stopbits, bytesize=bytesize, **common
    )
