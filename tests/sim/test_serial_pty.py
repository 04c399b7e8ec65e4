"""A linked pair of pseudo-terminals (mppf.sim.serial_pty): paced at a baud rate, it takes the wire time."""

from __future__ import annotations

import os
import time

import pytest

from mppf.sim.serial_pty import PtyPair


@pytest.mark.rtu
def test_paced_pty_relay_takes_the_wire_time():
    with PtyPair(baud=9600) as link:
        a = os.open(link.port_a, os.O_RDWR | os.O_NOCTTY)
        b = os.open(link.port_b, os.O_RDWR | os.O_NOCTTY)
        try:
            payload = bytes(range(96))
            started = time.monotonic()
            os.write(a, payload)
            received = b""
            while len(received) < len(payload):
                received += os.read(b, 256)
            elapsed = time.monotonic() - started
        finally:
            os.close(a)
            os.close(b)
    assert received == payload
    wire_s = 96 * 11 / 9600  # 0.11 s
    assert wire_s <= elapsed < wire_s + 0.1
