"""The Modbus press driver: :class:`mppf.drivers.plc_press.PlcPress` over Modbus TCP or RTU.

:class:`ModbusPress` is the press driver (:class:`~mppf.drivers.plc_press.PlcPress`) on the
Modbus transport and the owner's heartbeat thread of
:class:`mppf.drivers.modbus_session.ModbusLink`: once it has claimed the PLC it writes the
heartbeat every tenth of the PLC's watchdog while connected (the PLC's watchdog stops the
motion when it goes stale). The press step itself, its checks and its safety are
``PlcPress``'s; see ``docs/driver.md``.
"""

from __future__ import annotations

from mppf.drivers.follow import motion_time_s
from mppf.drivers.identity import PlcIdentity
from mppf.drivers.modbus_session import ModbusLink
from mppf.drivers.plc_press import PlcPress

__all__ = ["ModbusPress", "PlcIdentity", "motion_time_s"]


class ModbusPress(ModbusLink, PlcPress):
    """A press PLC on Modbus TCP or RTU (a :class:`mppf.core.presslink.PressLink`).

    Connects on construction: reads the PLC's identity (word order, map version, matrix
    size, scan time, limits, watchdog). The heartbeat starts when the driver claims the PLC
    (the first step, or :meth:`reset`) and stops when it releases it (:meth:`close`).

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
        Longest heartbeat period (the PLC's watchdog / 10 when shorter); None: no heartbeat
        (status reading and uploads only: GO is refused on a PLC with a watchdog).
    audit : AuditLog, optional
        Where commands and writes are recorded, written ahead (default: nowhere).
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

    def __enter__(self) -> ModbusPress:
        return self
