"""The settings of the simulated press PLC's program, and of the hosts that serve it.

:class:`PlcSettings` is what :class:`~mppf.sim.plc.program.PlcProgram` takes beyond the
press description, the register map and the clock; :class:`~mppf.sim.plc.link.InProcessPress`
and :func:`~mppf.sim.plc.host.start_simulated_plc` pass their keyword arguments on to it.
:class:`SimTransport` is how :func:`~mppf.sim.plc.host.start_simulated_plc` serves the
program (Modbus TCP, or RTU on a pseudo-terminal pair or a serial device).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields


@dataclass(frozen=True)
class PlcSettings:
    """The simulated PLC program's own settings (checked by the program).

    Attributes
    ----------
    word_order : {"ABCD", "CDAB"}
        Word order of 32-bit registers.
    time_scale : float
        Simulated seconds of motion per second of ``advance`` (50 = 50x faster).
    watchdog_s : float or None
        Watchdog and lease time (s of the program's clock): the owner's heartbeat must
        change within it (None or 0: no watchdog, the lease never lapses).
    seed : int
        Seed of the measurement noise.
    noise_mm : float
        Standard deviation of the noise on reported actual positions (0: exact).
    scan_s : float
        The scan period the host keeps (0 < scan_s <= 0.2 s); written to ``scan_time_max_ms``.
    remote : bool
        Position of the remote-enable key switch at power-on (True: remote, GO allowed).
    limits : mapping, optional
        The PLC's own configuration beyond the press description: ``positioning_timeout_s``
        (simulated s, default 2), ``rest_speed_mm_s`` (0.5), ``rest_time_s`` (0.05),
        ``tip_gap_min_mm`` (5); the dimpling limit is the press's ``max_neighbour_diff_mm``.
    quirks : sequence of str
        Misbehaviours of a PLC written from a misread map (:mod:`mppf.sim.plc.quirks`).
    """

    word_order: str = "ABCD"
    time_scale: float = 1.0
    watchdog_s: float | None = 1.0
    seed: int = 0
    noise_mm: float = 0.0
    scan_s: float = 0.01
    remote: bool = True
    limits: Mapping | None = None
    quirks: Sequence[str] = ()


@dataclass(frozen=True)
class SimTransport:
    """Where and how a hosted simulated PLC is served.

    Attributes
    ----------
    host, port : str, int
        TCP address (port 0: a free port). Used unless ``rtu`` or ``rtu_port``.
    rtu : bool
        Serve RTU on a new pseudo-terminal pair; the handle's ``url`` names the client's end.
    rtu_port : str, optional
        Serve RTU on this serial device instead.
    baud, parity : int, str
        Serial settings (RTU); parity ``"N"``, ``"E"`` or ``"O"``.
    paced : bool
        Pace the pseudo-terminal relay at ``baud`` (11 bits/byte).
    """

    host: str = "127.0.0.1"
    port: int = 0
    rtu: bool = False
    rtu_port: str | None = None
    baud: int = 115200
    parity: str = "E"
    paced: bool = False

    @property
    def serial(self) -> bool:
        """Whether RTU is served (on a pseudo-terminal pair or a serial device)."""
        return bool(self.rtu or self.rtu_port)


def split_options(options: Mapping) -> tuple[SimTransport, dict]:
    """Split keyword arguments into the transport's settings and the rest (the program's).

    Parameters
    ----------
    options : mapping
        Fields of :class:`SimTransport` and of :class:`PlcSettings`.

    Returns
    -------
    transport : SimTransport
    program_options : dict
        The other keyword arguments, unchanged.
    """
    names = {f.name for f in fields(SimTransport)}
    transport = SimTransport(**{k: v for k, v in options.items() if k in names})
    return transport, {k: v for k, v in options.items() if k not in names}
