"""The one client-side module that imports pymodbus: function 3 and function 16 over TCP or RTU.

:class:`ModbusAdapter` wraps a synchronous pymodbus client (``ModbusTcpClient``, or
``ModbusSerialClient`` in RTU framing with exact-length replies and the 3.5-character
silence before every request: :class:`_ExactRtuClient`) and speaks the project's language:

- a Modbus exception reply becomes :class:`mppf.core.errors.PlcError` (with the function,
  address and exception code);
- a timeout, a refused or dropped connection or a garbled reply (bad CRC, transaction id,
  unit or length: pymodbus checks them) becomes :class:`mppf.core.errors.LinkError`;
- reads are chunked at 125 registers (FC3), writes at 122 (FC16), so that a block that
  starts on an int32 boundary never has a value split between two frames;
- retries (after a lost reply only) are done here, never by pymodbus (its client is made
  with ``retries=0``): reads and setpoint writes get ``url.retries`` extra attempts, command
  writes (:meth:`write_command`) exactly one attempt, because a repeated command can act
  twice. After a lost reply the TCP connection is re-opened and the RTU input flushed, so
  a late reply is never paired with the next request.

Each request holds the link for one frame, so a heartbeat thread can share the adapter with
the main thread; urgent requests (heartbeat, STOP: ``urgent=True``) go before any ordinary
request that waits for the link, so a beat waits at most for the one frame on the wire.

pymodbus is imported with this module, and this module only once a PLC is reached
(:mod:`mppf.drivers.modbus_session`), so commands that do not talk to a PLC never load it.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence

from mppf.drivers.codec import EXCEPTION_NAMES, chunks
from mppf.drivers.url import PlcUrl
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException

from mppf.core.errors import LinkError, PlcError

READ_STEP_S = 0.05  # RTU: longest single blocking read while waiting for a reply
MAX_READ_REGS = 125
MAX_WRITE_REGS = 122
RETRY_DELAY_S = 0.1  # pause before the n-th retry: n * RETRY_DELAY_S
RTU_SILENCE_CHARS = 3.5  # the silence that separates RTU frames

# pymodbus logs every failed connection and dumps the last frames at ERROR level; with no
# handler configured Python would print them on stderr beside our own message. The errors
# reach the user as LinkError / PlcError instead; an application that wants the pymodbus
# log configures a handler for it.
logging.getLogger("pymodbus").addHandler(logging.NullHandler())


class _Link:
    """The link, held by one request at a time; urgent requests go before waiting ordinary ones."""

    def __init__(self):
        self._cond = threading.Condition()
        self._busy = False
        self._urgent = 0

    def hold(self, urgent: bool = False) -> _Held:
        return _Held(self, urgent)

    def acquire(self, urgent: bool) -> None:
        with self._cond:
            self._urgent += urgent
            while self._busy or (not urgent and self._urgent):
                self._cond.wait()
            self._urgent -= urgent
            self._busy = True

    def release(self) -> None:
        with self._cond:
            self._busy = False
            self._cond.notify_all()


class _Held:
    def __init__(self, link: _Link, urgent: bool):
        self.link, self.urgent = link, urgent

    def __enter__(self):
        self.link.acquire(self.urgent)

    def __exit__(self, *exc):
        self.link.release()


class _ExactRtuClient(ModbusSerialClient):
    """``ModbusSerialClient`` that reads each RTU reply with its exact length.

    pymodbus builds the request frame, checks the CRC and the unit id and decodes the reply;
    only the way bytes are taken from the port changes: after a request, :meth:`recv`
    (called by pymodbus with ``size=None``) reads the reply header (unit, function code,
    byte count), asks pymodbus's PDU decoder for the frame size it implies (FC3 reply:
    5 + byte count, FC16 reply: 8, exception reply: 5) and reads exactly the rest, each
    read blocking in pyserial until the bytes are there. So a reply is handed over as soon
    as its last byte arrives, instead of after pymodbus's 1 ms polling steps (1-3 ms more
    on each of the 72 frames of a 2 x 32 x 32 upload). Before each request the line is
    kept silent for 3.5 characters after the last reply (the RTU frame separator).

    The reply must start within ``timeout`` seconds of the request and be complete by
    then; otherwise :meth:`recv` returns what it has (nothing: pymodbus raises
    ``ModbusIOException``; a truncated or garbled frame fails pymodbus's CRC check).
    """

    HEADER_BYTES = 3  # unit id, function code, byte count (or exception code)

    def __init__(self, *args, silence_s: float = 0.0, **kwargs):
        super().__init__(*args, **kwargs)
        self._deadline = 0.0
        self._silence_s = silence_s
        self._quiet_at = 0.0  # the line has been silent long enough from then on

    def connect(self) -> bool:
        ok = super().connect()  # pymodbus calls this before every request too
        step = min(READ_STEP_S, self.comm_params.timeout_connect)
        if ok and self.socket is not None and self.socket.timeout != step:
            self.socket.timeout = step  # short blocking reads: the reply deadline kept within READ_STEP_S
        return ok

    def send(self, request: bytes, addr: tuple | None = None) -> int:
        wait = self._quiet_at - time.monotonic()
        if wait > 0:
            time.sleep(wait)  # at least 3.5 characters of silence before a request
        self._deadline = time.monotonic() + self.comm_params.timeout_connect
        return super().send(request, addr)

    def _read_until_deadline(self, size: int) -> bytes:
        """Read ``size`` bytes, or fewer if the reply deadline passes first."""
        data = bytearray()
        while len(data) < size:
            data += self.socket.read(size - len(data))
            if len(data) < size and time.monotonic() >= self._deadline:
                break
        return bytes(data)

    def _read_frame(self) -> bytes:
        if self.socket.in_waiting == 0 and time.monotonic() >= self._deadline:
            return b""
        head = self._read_until_deadline(self.HEADER_BYTES)
        if len(head) < self.HEADER_BYTES:
            return head
        frame_size = 0
        pdu_class = self.framer.decoder.lookupPduClass(head)
        if pdu_class is not None:
            try:
                frame_size = pdu_class.calculateRtuFrameSize(head)
            except ModbusException:  # a reply whose size the header does not tell
                frame_size = 0
        if frame_size <= self.HEADER_BYTES:  # unknown: hand over what has arrived
            return head + self.socket.read(self.socket.in_waiting)
        return head + self._read_until_deadline(frame_size - self.HEADER_BYTES)

    def recv(self, size: int | None) -> bytes:
        if not self.socket:
            raise ConnectionException(str(self))
        try:
            data = self._read_frame() if size is None else self._read_until_deadline(size)
        except OSError:  # includes serial.SerialException: the device went away
            self.close()
            raise ConnectionException(str(self)) from None
        self._quiet_at = time.monotonic() + self._silence_s
        return data


class ModbusAdapter:
    """A Modbus master on one PLC URL (TCP or RTU).

    Parameters
    ----------
    url : PlcUrl
        Where the PLC is (see :func:`mppf.drivers.url.parse_plc_url`).
    timeout_s : float, optional
        Reply timeout; default ``url.timeout_s``.
    retries : int, optional
        Extra attempts for reads and setpoint writes; default ``url.retries``.

    Attributes
    ----------
    requests : int
        Modbus requests sent so far (all attempts).
    """

    def __init__(self, url: PlcUrl, *, timeout_s: float | None = None, retries: int | None = None):
        self.url = url
        self.timeout_s = url.timeout_s if timeout_s is None else float(timeout_s)
        self.retries = url.retries if retries is None else int(retries)
        self.requests = 0
        self._link = _Link()
        if url.scheme == "tcp":
            self._client = ModbusTcpClient(url.host, port=url.port, timeout=self.timeout_s, retries=0)
        else:
            self._client = _ExactRtuClient(url.device, baudrate=url.baud, parity=url.parity, stopbits=url.stopbits,
                                           bytesize=url.bytesize, timeout=self.timeout_s, retries=0,
                                           silence_s=RTU_SILENCE_CHARS * url.char_time_s)

    # -- connection ------------------------------------------------------------------
    def connect(self) -> None:
        """Open the connection (idempotent).

        Raises
        ------
        LinkError
            The PLC cannot be reached (refused, no route, no such serial device).
        """
        with self._link.hold():
            ok = self._client.connect()
        if not ok:
            raise LinkError(f"cannot connect to the PLC at {self.url}",
                            hint="check the address, the cable and that the PLC is powered and in remote mode")

    def close(self) -> None:
        """Close the connection (idempotent)."""
        with self._link.hold():
            self._client.close()

    # -- requests --------------------------------------------------------------------
    def _call(self, what: str, function: int, address: int, arg, urgent: bool = False) -> list[int] | None:
        """One request (FC3: ``arg`` registers; FC16: ``arg`` the words) holding the link; errors translated."""
        with self._link.hold(urgent):
            self.requests += 1
            try:
                if function == 3:
                    reply = self._client.read_holding_registers(address, count=arg, device_id=self.url.unit)
                else:
                    reply = self._client.write_registers(address, list(arg), device_id=self.url.unit)
            except ModbusIOException:
                self._after_lost_reply()
                raise LinkError(f"no reply from the PLC at {self.url} to {what} within {self.timeout_s:g} s",
                                hint="check the link; a longer timeout=... in the URL helps on slow serial lines") \
                    from None
            except ConnectionException as exc:
                self._client.close()
                raise LinkError(f"connection to the PLC at {self.url} lost during {what} ({exc})",
                                hint="check the cable / network and that the PLC is running") from None
            except ModbusException as exc:
                self._after_lost_reply()
                raise LinkError(f"invalid reply from the PLC at {self.url} to {what}: {exc}") from None
            except OSError as exc:  # includes serial.SerialException
                self._client.close()
                raise LinkError(f"connection to the PLC at {self.url} lost during {what} ({exc})",
                                hint="check the cable / network and that the PLC is running") from None
        if reply is None:
            raise LinkError(f"no reply from the PLC at {self.url} to {what}")
        if reply.isError():
            code = int(getattr(reply, "exception_code", 0))
            error = PlcError(f"the PLC at {self.url} refused {what}: Modbus exception {code} "
                             f"({EXCEPTION_NAMES.get(code, 'unknown')})",
                             hint="read 'mppf status' for the PLC's state and result codes")
            error.exception_code = code
            raise error
        if function == 3:
            words = list(reply.registers)
            if len(words) != arg:
                raise LinkError(f"invalid reply from the PLC at {self.url} to {what}: {len(words)} registers")
            return words
        return None

    def _after_lost_reply(self) -> None:
        """After a lost or garbled reply, make sure a late reply is never paired with the next request.

        TCP: the connection is closed (the next request opens a new one); RTU: the input
        is flushed after a short pause.
        """
        if self.url.scheme == "tcp":
            self._client.close()
            return
        time.sleep(min(0.05, self.timeout_s))
        port = getattr(self._client, "socket", None)
        try:
            port.reset_input_buffer()
        except (OSError, AttributeError):
            pass

    def _with_retries(self, retries: int, fn: Callable, *args):
        """Call ``fn``; after a link failure wait ``RETRY_DELAY_S * attempt`` and try again."""
        attempt = 0
        while True:
            try:
                return fn(*args)
            except PlcError:
                raise  # the PLC answered: asking again gives the same answer
            except LinkError:
                if attempt >= retries:
                    raise
                attempt += 1
                time.sleep(RETRY_DELAY_S * attempt)

    def read_holding(self, address: int, count: int, *, retries: int | None = None, max_chunk: int = MAX_READ_REGS,
                     on_chunk: Callable[[int], None] | None = None) -> list[int]:
        """Read ``count`` holding registers (FC3) from ``address``, in frames of at most ``max_chunk``.

        ``on_chunk`` (optional) is called with the number of registers read after each frame.

        Returns
        -------
        list of int
            Unsigned 16-bit register values.

        Raises
        ------
        PlcError, LinkError
        """
        retries = self.retries if retries is None else retries
        if not 1 <= max_chunk <= MAX_READ_REGS:
            raise ValueError(f"max_chunk must be 1..{MAX_READ_REGS}, got {max_chunk}")
        words: list[int] = []
        for start in range(address, address + count, max_chunk):
            n = min(max_chunk, address + count - start)
            words += self._with_retries(retries, self._call, f"reading {n} registers at {start}", 3, start, n)
            if on_chunk is not None:
                on_chunk(n)
        return words

    def write_registers(self, address: int, words: Sequence[int], *, retries: int | None = None,
                        max_chunk: int = MAX_WRITE_REGS, on_chunk: Callable[[int], None] | None = None) -> None:
        """Write registers (FC16) from ``address``, in frames of at most ``max_chunk`` (<= 122, even).

        Parameters
        ----------
        words : sequence of int
            Unsigned 16-bit values.
        retries : int, optional
            Extra attempts after a lost reply (default ``self.retries``; use :meth:`write_command`
            for commands, which is never retried).
        on_chunk : callable, optional
            Called with the number of registers written after each frame (progress).

        Raises
        ------
        PlcError, LinkError
        """
        retries = self.retries if retries is None else retries
        if not 1 <= max_chunk <= MAX_WRITE_REGS or max_chunk % 2:
            raise ValueError(f"max_chunk must be an even number 2..{MAX_WRITE_REGS}, got {max_chunk}")
        words = [int(w) for w in words]
        bad = [w for w in words if not 0 <= w <= 0xFFFF]
        if bad:
            raise ValueError(f"register values must be 0..65535, got {bad[:5]}")
        for start, chunk in chunks(address, words, max_chunk):
            self._with_retries(retries, self._call, f"writing {len(chunk)} registers at {start}", 16, start, chunk)
            if on_chunk is not None:
                on_chunk(len(chunk))

    def write_command(self, address: int, words: Sequence[int], *, urgent: bool = False) -> None:
        """Write a command (one FC16 frame, exactly one attempt: never retried).

        ``urgent`` (heartbeat, STOP): sent before any ordinary request waiting for the link.

        Raises
        ------
        PlcError
            The PLC refused the request.
        LinkError
            No reply: the command may or may not have been carried out.
        """
        words = [int(w) for w in words]
        if not 1 <= len(words) <= MAX_WRITE_REGS or any(not 0 <= w <= 0xFFFF for w in words):
            raise ValueError(f"a command is 1..{MAX_WRITE_REGS} registers of 0..65535, got {words[:5]}")
        self._call(f"command write at {address}", 16, address, words, urgent=urgent)

    def __enter__(self) -> ModbusAdapter:
        self.connect()
        return self

    def __exit__(self, *exc) -> None:
        self.close()
