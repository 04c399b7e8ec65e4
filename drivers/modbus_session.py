"""A PLC session over Modbus TCP or RTU, with the owner's heartbeat thread.

:class:`ModbusLink` connects a :class:`~mppf.drivers.session.PlcSession` (or the press
driver built on it) to a PLC URL through :class:`mppf.drivers.modbus_adapter.ModbusAdapter`
on the wall clock, and keeps the heartbeat: once the master has claimed the PLC, a
thread writes the master id and a new counter every :attr:`heartbeat_period_s` (a tenth of
the PLC's watchdog, at most 0.25 s) as urgent requests, which slip in between the frames of
a long upload. It measures the gaps between its beats, so that the driver refuses GO when
it could not keep a quarter of the watchdog. :class:`ModbusSession` is the light session of
``mppf status``, ``mppf stop`` and ``mppf reset`` (no numpy); ``ModbusPress``
(:mod:`mppf.drivers.modbus`) the press driver.
"""

from __future__ import annotations

import threading
import time

from mppf.core.errors import LinkError, PlcError
from mppf.drivers.session import PlcSession
from mppf.drivers.url import PlcUrl, parse_plc_url


class ModbusLink:
    """Modbus transport and heartbeat thread (a mixin before a ``PlcSession`` in the bases).

    Parameters
    ----------
    url : str or PlcUrl
        ``tcp://host:port?unit=1`` or ``rtu:///dev/ttyUSB0?baud=115200&parity=E&unit=1``.
    press : PressConfig or None
        The press description (needed to press; None for status, STOP and RESET).
    timeout_s : float, optional
        Reply timeout of one request (default: the URL's, 1 s).
    heartbeat_s : float or None
        Longest heartbeat period (the period is the smaller of this and a tenth of the
        PLC's watchdog); None: no heartbeat (the driver then refuses GO on a PLC with a
        watchdog).
    **options
        Keyword arguments of the session (``word_order``, ``audit``, ``job_sha256``, ...).

    Attributes
    ----------
    heartbeat_errors : int
        Heartbeat writes that failed (the main thread meets the trouble on its next request).
    """

    def __init__(self, url: str | PlcUrl, press=None, *, timeout_s: float | None = None,
                 heartbeat_s: float | None = 0.25, **options):
        from mppf.drivers.modbus_adapter import ModbusAdapter  # pymodbus: only once a PLC is reached

        url = parse_plc_url(url) if isinstance(url, str) else url
        self.heartbeat_s = float(heartbeat_s) if heartbeat_s else None
        self.heartbeat_errors = 0
        self.last_heartbeat_error: Exception | None = None
        self._hb_stop = threading.Event()
        self._hb_thread: threading.Thread | None = None
        self._hb_last = 0.0
        self._hb_gap = 0.0
        adapter = ModbusAdapter(url, timeout_s=timeout_s)
        super().__init__(adapter, url, press, unit=url.unit, reply_timeout_s=adapter.timeout_s, **options)

    @property
    def heartbeat_period_s(self) -> float:
        period = super().heartbeat_period_s
        return period if self.heartbeat_s is None else min(period, self.heartbeat_s)

    def _start_heartbeat(self) -> None:
        if self.heartbeat_s is None or (self._hb_thread is not None and self._hb_thread.is_alive()):
            return
        self._hb_stop = threading.Event()
        self._hb_last = time.monotonic()
        self._hb_thread = threading.Thread(target=self._heartbeat_loop, name="mppf-heartbeat", daemon=True)
        self._hb_thread.start()

    def _stop_heartbeat(self) -> None:
        if self._hb_thread is not None:
            self._hb_stop.set()
            self._hb_thread.join()
            self._hb_thread = None

    def start_heartbeat(self) -> None:
        """Start the heartbeat thread (after a claim; :meth:`claim` does it)."""
        self._start_heartbeat()

    def stop_heartbeat(self) -> None:
        """Stop the heartbeat thread (the PLC's watchdog will stop any motion)."""
        self._stop_heartbeat()

    def heartbeat_gap_s(self) -> float:
        if self._hb_thread is None or not self._hb_thread.is_alive():
            return float("inf")
        return max(self._hb_gap, time.monotonic() - self._hb_last)

    def _mark_heartbeat(self) -> None:
        self._hb_gap = 0.0

    def _heartbeat_loop(self) -> None:
        period = self.heartbeat_period_s
        while True:
            started = time.monotonic()
            try:
                self._beat()
                now = time.monotonic()
                self._hb_gap = max(self._hb_gap, now - self._hb_last)
                self._hb_last = now
            except (LinkError, PlcError) as exc:  # counted; the main thread meets the trouble on its next request
                self.heartbeat_errors += 1
                self.last_heartbeat_error = exc
            if self._hb_stop.wait(max(0.0, period - (time.monotonic() - started))):
                return


class ModbusSession(ModbusLink, PlcSession):
    """A PLC session over Modbus: status, STOP, RESET (no press needed, no numpy).

    ``ModbusSession(url, press=None, *, word_order="auto", timeout_s=None, heartbeat_s=0.25,
    audit=None, job_sha256=None)``; see :class:`ModbusLink` and
    :class:`~mppf.drivers.session.PlcSession`.
    """
