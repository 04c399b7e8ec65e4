"""A linked pair of pseudo-terminals, optionally paced at a baud rate (no socat needed).

:class:`PtyPair` opens two pseudo-terminals and relays bytes between their master
ends in two threads: whatever is written to ``port_a`` can be read from ``port_b`` and
back, like a null-modem cable. A pseudo-terminal delivers bytes at once whatever baud
rate is set on it; with ``baud`` given, the relay holds each burst until it would have
finished on a real line at that rate (11 bits per byte: start, 8 data, parity, stop),
so RTU timings are realistic.

Example::

    with PtyPair(baud=115200) as link:
        server_port, client_port = link.port_a, link.port_b
"""

from __future__ import annotations

import os
import select
import termios
import threading
import time
import tty

BITS_PER_BYTE = 11


def wire_time_s(n_bytes: int, baud: int) -> float:
    """Time to send ``n_bytes`` at ``baud`` with 11 bits per byte."""
    return n_bytes * BITS_PER_BYTE / baud


def _accepts_parity(fd: int) -> bool:
    """True if terminal ``fd`` accepts even parity (the setting is restored)."""
    attrs = termios.tcgetattr(fd)
    trial = list(attrs)
    trial[2] |= termios.PARENB
    try:
        termios.tcsetattr(fd, termios.TCSANOW, trial)
    except termios.error:
        return False
    termios.tcsetattr(fd, termios.TCSANOW, attrs)
    return True


class PtyPair:
    """Two linked pseudo-terminals.

    Parameters
    ----------
    baud : int, optional
        Pace the relay at this baud rate (11 bits per byte); None relays at once.

    Attributes
    ----------
    port_a, port_b : str
        Device paths (``/dev/pts/N``) of the two ends.
    bytes_relayed : int
        Total bytes relayed in both directions.
    supports_parity : bool
        False if the kernel refuses parity settings on pseudo-terminals (seen on Linux
        6.18: ``tcsetattr`` with PARENB fails with EINVAL, so pyserial cannot open the
        port with parity E or O); open both ends with parity N then.
    """

    def __init__(self, baud: int | None = None):
        if baud is not None and baud <= 0:
            raise ValueError(f"baud must be positive, got {baud}")
        self.baud = baud
        self.bytes_relayed = 0
        self._stop = threading.Event()
        self._fds: list[int] = []
        ends = []
        for _ in range(2):
            master, slave = os.openpty()
            tty.setraw(slave)  # no echo, no line editing, 8 bit clean
            self._fds += [master, slave]  # the slave stays open: no EIO while the port is closed
            ends.append((master, os.ttyname(slave)))
        (self._master_a, self.port_a), (self._master_b, self.port_b) = ends
        self.supports_parity = _accepts_parity(self._fds[1])
        self._wake_r, self._wake_w = os.pipe()
        self._fds += [self._wake_r, self._wake_w]
        self._threads = [
            threading.Thread(target=self._relay, args=(self._master_a, self._master_b), daemon=True, name="pty-a-b"),
            threading.Thread(target=self._relay, args=(self._master_b, self._master_a), daemon=True, name="pty-b-a"),
        ]
        for thread in self._threads:
            thread.start()

    def _relay(self, src: int, dst: int) -> None:
        line_free_at = 0.0  # when the simulated line finishes the previous burst
        while not self._stop.is_set():
            ready, _, _ = select.select([src, self._wake_r], [], [])
            if self._stop.is_set():
                return
            if src not in ready:
                continue
            try:
                data = os.read(src, 4096)
            except OSError:
                time.sleep(0.01)  # the other side closed the port; wait for a reopen
                continue
            if self.baud is not None:
                line_free_at = max(time.perf_counter(), line_free_at) + wire_time_s(len(data), self.baud)
                delay = line_free_at - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
            try:
                os.write(dst, data)
            except OSError:
                continue
            self.bytes_relayed += len(data)

    def close(self) -> None:
        """Stop the relay and close both pseudo-terminals."""
        if self._stop.is_set():
            return
        self._stop.set()
        os.write(self._wake_w, b"x")
        for thread in self._threads:
            thread.join(timeout=2.0)
        for fd in self._fds:
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> PtyPair:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
