"""STOP first: ``mppf stop`` over Modbus TCP on a bare socket, before anything else is loaded.

STOP is the one request whose delay matters for safety. :func:`stop_over_tcp` opens a
socket, reads the magic and map version (registers 0-2, which also give the word order),
writes ``stop_request`` = 1 and ``stop_master`` in one function-16 request, and only then
loads the rest: the audit log (the STOP is one of the requests sent whether or not its row
can be written, :data:`mppf.drivers.audit.ALWAYS_SENT`; here it is recorded just after it
left, with the time it left), the confirmation that the PLC took it (``stop_request`` back
to 0) and the state. It imports neither pymodbus nor numpy; a device that is not an mppf
press PLC of this map version gets no STOP from here (:class:`NotHere`): the caller then
takes the full path, which says what answered.
"""

from __future__ import annotations

import os
import re
import socket
import struct
import time

FC_READ, FC_WRITE = 3, 16


class NotHere(Exception):
    """The fast path does not apply (not TCP, not an mppf PLC of this map, no answer): use the full one."""


def _request(sock: socket.socket, unit: int, pdu: bytes, transaction: int) -> bytes:
    sock.sendall(struct.pack(">HHHB", transaction, 0, len(pdu) + 1, unit) + pdu)
    header = _receive(sock, 7)
    tid, _, length, _ = struct.unpack(">HHHB", header)
    body = _receive(sock, length - 1)
    if tid != transaction or not body or body[0] & 0x80:
        raise NotHere(f"the PLC answered function {body[:1].hex() or '?'} (exception {body[1:2].hex() or '?'})")
    return body


def _receive(sock: socket.socket, n: int) -> bytes:
    data = b""
    while len(data) < n:
        part = sock.recv(n - len(data))
        if not part:
            raise NotHere("the connection was closed")
        data += part
    return data


def _read(sock, unit: int, address: int, count: int, transaction: int) -> list[int]:
    body = _request(sock, unit, struct.pack(">BHH", FC_READ, address, count), transaction)
    return list(struct.unpack(f">{count}H", body[2: 2 + 2 * count]))


def _u32_words(value: int, order: str) -> list[int]:
    high, low = value >> 16, value & 0xFFFF
    return [high, low] if order == "ABCD" else [low, high]


_PLAIN_URL = re.compile(r"tcp://([A-Za-z0-9.-]+):([0-9]{1,5})(?:\?unit=([0-9]{1,3}))?")
PLAIN_TIMEOUT_S = 1.0  # the default reply timeout of drivers/url.py


def parse_tcp(url: str) -> tuple[str, int, int, float]:
    """(host, port, unit, reply timeout s) of a ``tcp://host:port?unit=N`` URL (NotHere otherwise).

    The plain form (host, port and at most the unit) is read here; anything else by
    :func:`mppf.drivers.url.parse_plc_url`, which judges it (and loads urllib).
    """
    plain = _PLAIN_URL.fullmatch(url)
    if plain and 1 <= int(plain.group(2)) <= 65535 and 1 <= int(plain.group(3) or 1) <= 247:
        return plain.group(1), int(plain.group(2)), int(plain.group(3) or 1), PLAIN_TIMEOUT_S
    from mppf.drivers.url import parse_plc_url

    parsed = parse_plc_url(url)  # InputError for a bad URL, as on the full path
    if parsed.scheme != "tcp":
        raise NotHere("not a TCP URL")
    return parsed.host, parsed.port, parsed.unit, float(parsed.timeout_s)


class FastMap:
    """What the fast STOP needs of ``register_map.toml``, read with three regular expressions (no tomllib).

    A test checks it against :func:`mppf.drivers.regmap.load_register_map`.

    Attributes
    ----------
    version, magic : int
    address : dict of str to (int, int)
        (address, count) of ``magic``, ``map_version``, ``stop_request``, ``state``.
    states : dict of int to str
    """

    def __init__(self, text: str):
        head = text.split("[[", 1)[0]
        self.version = int(re.search(r"(?m)^version\s*=\s*(\d+)", head).group(1))
        self.magic = int(re.search(r"(?m)^magic\s*=\s*(0x[0-9A-Fa-f]+|\d+)", head).group(1), 0)
        self.address = {m.group(1): (int(m.group(2)), int(m.group(3))) for m in re.finditer(
            r'\[\[register\]\]\s*name\s*=\s*"(\w+)"\s*address\s*=\s*(\d+)\s*count\s*=\s*(\d+)', text)}
        self.states = {int(m.group(1)): m.group(2) for m in re.finditer(
            r'\[\[state\]\]\s*code\s*=\s*(\d+)\s*name\s*=\s*"(\w+)"', text)}


def fast_map() -> FastMap:
    """The packaged map's :class:`FastMap`."""
    with open(os.path.join(os.path.dirname(__file__), "register_map.toml"), encoding="utf-8") as fh:
        return FastMap(fh.read())


def stop_over_tcp(url: str, reason: str = "mppf stop") -> dict:
    """Send STOP to the PLC at ``url`` at once; return what :func:`finish_stop` needs.

    Raises
    ------
    NotHere
        Not a TCP URL, no mppf press PLC of this register map there, or no answer: nothing was sent.
    InputError
        A malformed URL.
    """
    host, port, unit, timeout_s = parse_tcp(url)
    rmap = fast_map()
    try:
        sock = socket.create_connection((host, port), timeout=timeout_s)
    except OSError as exc:
        raise NotHere(str(exc)) from None
    try:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        (magic, _), (version, _) = rmap.address["magic"], rmap.address["map_version"]
        words = _read(sock, unit, magic, version + 1 - magic, 1)
        order = {_u32_words(rmap.magic, o)[0]: o for o in ("ABCD", "CDAB")}.get(words[0])
        if order is None or words[1] != _u32_words(rmap.magic, order)[1] or words[2] != rmap.version:
            raise NotHere("not an mppf press PLC of this register map version")
        master = int.from_bytes(os.urandom(4), "big") or 1
        values = [1] + _u32_words(master, order)
        sent_at = time.time()
        _request(sock, unit, struct.pack(f">BHHB{len(values)}H", FC_WRITE, rmap.address["stop_request"][0],
                                         len(values), 2 * len(values), *values), 2)
    except (OSError, NotHere) as exc:
        sock.close()
        raise NotHere(str(exc)) from None
    return {"sock": sock, "unit": unit, "map": rmap, "master": master, "order": order, "sent_at": sent_at,
            "url": url, "reason": reason, "timeout_s": timeout_s}


def finish_stop(sent: dict, audit) -> str:
    """After the STOP left: record it, wait until the PLC took it, return the state it is in (or why not known)."""
    rmap, sock, unit = sent["map"], sent["sock"], sent["unit"]
    audit.record(sent["url"], "connect", "ok", detail=f"master 0x{sent['master']:08X}, word order {sent['order']}, "
                                                      f"map version {rmap.version} (mppf stop: STOP first)")
    row = audit.intent(sent["url"], "stop", detail=f"{sent['reason']}; master 0x{sent['master']:08X}; sent at "
                                                   f"{sent['sent_at']:.3f} (STOP first, recorded after)")
    deadline = time.monotonic() + 2 * sent["timeout_s"] + 0.5
    try:
        transaction = 3
        while True:
            transaction += 1
            first, state_at = rmap.address["stop_request"][0], rmap.address["state"][0]
            words = _read(sock, unit, first, state_at + 1 - first, transaction)
            if words[0] == 0:
                state = rmap.states.get(words[state_at - first], "unknown")
                audit.outcome(row, "ok")
                return state
            if time.monotonic() > deadline:
                audit.outcome(row, "not taken")
                return "STOP NOT TAKEN: stop the press at the machine"
            time.sleep(0.01)
    except (OSError, NotHere) as exc:
        audit.outcome(row, "ok", detail=f"not confirmed: {exc}")
        return f"not confirmed ({exc})"
    finally:
        sock.close()
