"""The Modbus press driver: :class:`mppf.drivers.plc_press.PlcPress` over Modbus TCP or RTU.

:class:`ModbusPress` connects the driver to a PLC URL through
:class:`mppf.drivers.modbus_adapter.ModbusAdapter` (the one client-side module that
imports pymodbus) on the wall clock, and keeps a heartbeat thread that changes
``master_heartbeat`` every ``heartbeat_s`` while connected (the PLC's watchdog stops the
motion when it goes stale). The press step itself, its checks and its safety are
:class:`~mppf.drivers.plc_press.PlcPress`'s; see ``docs/driver.md``.
"""

from __future__ import annotations

import threading

from mppf.core.errors import InputError, LinkError, PlcError
from mppf.drivers import codec, regmap as rm
from mppf.drivers.follow import motion_time_s
from mppf.drivers.identity import PlcIdentity
from mppf.drivers.modbus_adapter import ModbusAdapter
from mppf.drivers.plc_press import PlcPress
from mppf.drivers.url import PlcUrl, parse_plc_url
from mppf.planning.press import PressConfig

__all__ = ["ModbusPress", "PlcIdentity", "motion_time_s"]


class ModbusPress(PlcPress):
    """A press PLC on Modbus TCP or RTU (a :class:`mppf.core.presslink.PressLink`).

    Connects on construction: reads the magic (word order), map version, matrix size and
    the PLC's stroke limits, and starts the heartbeat.

    Parameters
    ----------
    url : str or PlcUrl
        ``tcp://host:port?unit=1`` or ``rtu:///dev/ttyUSB0?baud=115200&parity=E&unit=1``.
    press : PressConfig or None
        The press description (limits, speed, tolerance). None is enough for
        :meth:`status`, :meth:`stop` and :meth:`reset` but not for :meth:`run_step`.
    word_order : {"auto", "ABCD", "CDAB"}
        Expected word order of 32-bit values; "auto" takes the PLC's.
    timeout_s : float, optional
        Reply timeout of one request (default: the URL's, 1 s).
    heartbeat_s : float or None
        Period of the master heartbeat; None or 0 for none (status reading only).
    audit : AuditLog, optional
        Where commands and writes are recorded (default: nowhere).
    job_sha256 : str, optional
        Hash of the job being pressed, recorded in the audit log.
    register_map : RegisterMap, optional
        Default: the packaged map.
    poll_s : float
        Status polling period during motion.

    Raises
    ------
    InputError
        Bad URL or word order.
    LinkError
        The PLC cannot be reached, or is not an mppf press PLC with this register map.
    ConfigError
        The press description does not match the PLC's matrix size.
    """

    def __init__(
        self,
        url: str | PlcUrl,
        press: PressConfig | None = None,
        *,
        word_order: str = "auto",
        timeout_s: float | None = None,
        heartbeat_s: float | None = 0.25,
        audit=None,
        job_sha256: str | None = None,
        register_map: rm.RegisterMap | None = None,
        poll_s: float = 0.05,
    ):
        url = parse_plc_url(url) if isinstance(url, str) else url
        if word_order != "auto":
            codec.check_word_order(word_order)
        self.heartbeat_s = float(heartbeat_s) if heartbeat_s else 0.0
        self.heartbeat_errors = 0
        self.last_heartbeat_error: Exception | None = None
        self._hb_value = 0
        self._hb_stop = threading.Event()
        self._hb_thread: threading.Thread | None = None
        super().__init__(ModbusAdapter(url, timeout_s=timeout_s), url, press, word_order=word_order, unit=url.unit,
                         audit=audit, job_sha256=job_sha256, register_map=register_map, poll_s=poll_s)

    def _connected(self) -> None:
        if self.heartbeat_s > 0:
            self.start_heartbeat()

    def start_heartbeat(self, period_s: float | None = None) -> None:
        """Start (or restart) the heartbeat thread."""
        self.stop_heartbeat()
        if period_s:
            self.heartbeat_s = float(period_s)
        if self.heartbeat_s <= 0:
            raise InputError(f"heartbeat period must be positive, got {self.heartbeat_s}")
        self._hb_value = self._read_field("master_heartbeat")[0]
        self._hb_stop = threading.Event()
        self._hb_thread = threading.Thread(target=self._heartbeat_loop, name="mppf-heartbeat", daemon=True)
        self._hb_thread.start()

    def stop_heartbeat(self) -> None:
        """Stop the heartbeat thread (the PLC's watchdog will stop any motion)."""
        if self._hb_thread is not None:
            self._hb_stop.set()
            self._hb_thread.join()
            self._hb_thread = None

    def _heartbeat_loop(self) -> None:
        addr = self._field("master_heartbeat").address
        while True:
            self._hb_value = (self._hb_value + 1) & 0xFFFF
            try:
                self._io.write_command(addr, [self._hb_value])
            except (LinkError, PlcError) as exc:  # counted; the main thread meets the trouble on its next request
                self.heartbeat_errors += 1
                self.last_heartbeat_error = exc
            if self._hb_stop.wait(self.heartbeat_s):
                return

    def close(self) -> None:
        """Stop the heartbeat and disconnect (the press is not stopped)."""
        self.stop_heartbeat()
        super().close()

    def __enter__(self) -> ModbusPress:
        return self
