"""Reconnecting as documented: after a lost link the driver tries for the map's 2 s, also when connections
are accepted and then reset at once (a PLC restarting its stack, a gateway), then sends STOP.

A real TCP proxy between the driver and the simulated PLC plays the broken link.
"""

from __future__ import annotations

import socket
import struct
import threading
import time

import pytest
from driver_helpers import HookReporter, small_press, step_setpoints

from mppf.core.errors import LinkError
from mppf.drivers.audit import AuditLog
from mppf.drivers.modbus import ModbusPress
from mppf.sim.plc.host import start_simulated_plc


class ResettingProxy:
    """Forwards TCP to ``target``; while :attr:`broken`, resets every open and new connection at once."""

    def __init__(self, target: tuple[str, int]):
        self.target = target
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.broken_until = 0.0
        self.resets = 0
        self._pairs: list[tuple[socket.socket, socket.socket]] = []
        self._lock = threading.Lock()
        threading.Thread(target=self._accept, daemon=True).start()

    @staticmethod
    def _reset(sock: socket.socket) -> None:
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            sock.close()
        except OSError:
            pass

    def break_for(self, seconds: float) -> None:
        self.broken_until = time.monotonic() + seconds
        with self._lock:
            pairs, self._pairs = self._pairs, []
        for a, b in pairs:
            self._reset(a)
            self._reset(b)

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            if time.monotonic() < self.broken_until:
                self.resets += 1
                self._reset(client)
                continue
            server = socket.create_connection(self.target)
            with self._lock:
                self._pairs.append((client, server))
            for a, b in ((client, server), (server, client)):
                threading.Thread(target=self._pipe, args=(a, b), daemon=True).start()

    @staticmethod
    def _pipe(src: socket.socket, dst: socket.socket) -> None:
        try:
            while data := src.recv(4096):
                dst.sendall(data)
        except OSError:
            pass
        for sock in (src, dst):
            try:
                sock.close()
            except OSError:
                pass

    def close(self) -> None:
        self.listener.close()
        self.break_for(0)


def test_a_link_reset_for_1_5_s_is_reconnected_and_the_press_stopped(tmp_path):
    press = small_press()
    upper, lower = step_setpoints(press)
    sim = start_simulated_plc(press, time_scale=2.0, watchdog_s=5.0)  # a long watchdog: only the STOP stops it
    proxy = ResettingProxy(("127.0.0.1", sim.port))
    try:
        def cut(task):
            if task.startswith("motion"):
                proxy.break_for(1.5)

        with AuditLog(tmp_path / "a.sqlite") as audit, \
                ModbusPress(f"tcp://127.0.0.1:{proxy.port}?unit=1&timeout=0.3", press, audit=audit) as plc:
            started = time.monotonic()
            with pytest.raises(LinkError) as info:
                plc.run_step(upper, lower, reporter=HookReporter(on_start=cut))
            took = time.monotonic() - started
            stops = [(e.outcome, e.detail) for e in audit.entries() if e.action == "stop"]
        assert "STOP was sent after reconnecting" in str(info.value), str(info.value)
        assert proxy.resets >= 1  # tries met connections accepted and reset at once
        assert stops and stops[0][0] == "ok"
        assert sim.state() == "STOPPED" and took < 10
    finally:
        proxy.close()
        sim.stop()
