"""The live press PLC for the panel: a reader in a background thread, and STOP.

:class:`PlcMonitor` polls the PLC with :class:`~mppf.drivers.modbus.ModbusPress` (the Modbus driver,
which decodes the registers; reading only: no heartbeat is written, so a dead master's watchdog still stops the press) four
times a second while the press moves and once a second at rest, and keeps the latest
snapshot for the page (:mod:`mppf.panel.live`); when the PLC stops answering the snapshot
says "LINK LOST" and the monitor reconnects every second, asking ``locate`` again (the
loop may have started another dry run's PLC meanwhile). :func:`send_stop` sends STOP on a
connection of its own, recorded in the audit log like ``mppf stop``.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from datetime import datetime, timezone

from mppf.core.errors import MppfError
from mppf.drivers.modbus import ModbusPress
from mppf.model.press import PressConfig
from mppf.panel.live import SIDES, LiveTracker, grid_json, press_state
from mppf.panel.sources import PlcTarget

PERIOD_S = 0.25
"""Reading period while the press moves (and of the page's refresh)."""

IDLE_EVERY = 4
"""At rest, the punch positions are read every this many periods."""

RECONNECT_S = 1.0
"""Time between two attempts to reach a PLC that stopped answering."""

REPLY_TIMEOUT_S = 0.5
"""Reply timeout of one request of the panel's reader."""


def send_stop(url: str, audit, reason: str, timeout_s: float = 1.0) -> None:
    """Send STOP to the PLC at ``url`` on a fresh connection and wait until the PLC has taken it.

    One attempt, recorded in ``audit`` (:class:`mppf.drivers.modbus_session.ModbusSession`,
    the session of ``mppf stop``: it claims nothing and writes no heartbeat).

    Raises
    ------
    LinkError
        The PLC cannot be reached: STOP was not delivered.
    PlcError
        The PLC refused it.
    PressFault
        The PLC did not take the STOP in time.
    """
    from mppf.drivers.modbus_session import ModbusSession

    with ModbusSession(url, None, heartbeat_s=None, timeout_s=timeout_s, audit=audit) as plc:
        plc.stop(reason)


def status_fields(report: dict) -> dict:
    """What the page shows of a status report (:meth:`ModbusPress.status_report`, register map version 3).

    Returns
    -------
    dict
        ``state`` (one word, :func:`mppf.panel.live.press_state`), ``plc_state``, ``status``
        (the status bits), ``fault`` and ``refusal`` (``code``: 0 or a name, ``text``; the
        refusal is the last command's result when the PLC did not carry it out),
        ``sequence`` (validated, motion), ``owner`` (the owning master's id, 0: none),
        ``stops`` (count and last cause), ``moving``.
    """
    flags, last = report["status"], report["last_command"]
    refused = last["result"] != "ACCEPTED"
    return {
        "state": press_state(flags, True, report["state"]), "plc_state": report["state"], "status": flags,
        "fault": {"code": report["fault_code"], "text": report["fault_text"]},
        "refusal": {"code": last["result"] if refused else 0,
                    "text": f"{last['command']}: {last['result_text']}" if refused else "none"},
        "sequence": {"validated": report["validated"]["sequence"], "motion": report["motion"]["sequence"]},
        "owner": report["owner_master"], "stops": report["stops"], "moving": bool(flags["busy"]),
    }


def _now_utc() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds")


class PlcMonitor:
    """The latest reading of the press PLC, refreshed in a background thread.

    Parameters
    ----------
    locate : callable returning PlcTarget or None
        Where the PLC is (asked again before every connection attempt).
    press : PressConfig or None
        The press description (the matrices are read only with it).
    find_press : callable returning PressConfig or None, optional
        Asked before each connection while ``press`` is None (the history may get its first
        plate after the panel started).
    base : int
        First row / column number of the punch names.
    period_s : float
        Reading period while the press moves.
    """

    def __init__(self, locate: Callable[[], PlcTarget | None], press: PressConfig | None, *,
                 find_press: Callable[[], PressConfig | None] | None = None, base: int = 1,
                 period_s: float = PERIOD_S):
        self.locate = locate
        self.press = press
        self.find_press = find_press
        self.period_s = float(period_s)
        self._base = base
        self._tracker = LiveTracker(press.position_tolerance_mm if press else 0.2, base)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._link: ModbusPress | None = None
        self._target: PlcTarget | None = None
        self._targets = self._actuals = None
        self._job = None
        self._was_busy = False
        self._tick = 0
        self._lost_since: float | None = None
        self._snapshot = self._lost("not connected yet")

    # -- life -------------------------------------------------------------------------------

    def start(self) -> PlcMonitor:
        """Start the reader thread."""
        self._thread = threading.Thread(target=self._run, name="mppf-panel-plc", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop the reader thread and disconnect (the press is not touched)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        self._disconnect()

    def snapshot(self) -> dict:
        """The latest reading (JSON-ready; see :meth:`read_once`)."""
        with self._lock:
            return self._snapshot

    @property
    def target(self) -> PlcTarget | None:
        """The PLC watched now (None: none known)."""
        return self._target

    def _run(self) -> None:
        next_connect = 0.0
        while not self._stop.is_set():
            now = time.monotonic()
            if now >= next_connect and (self._link is None or self.press is None):
                next_connect = now + RECONNECT_S
                if self._link is not None and self._find_press():
                    self._disconnect()  # connected for the status only: again, with the press description
                if self._link is None:
                    self._connect()
            snap = self.read_once() if self._link is not None else None
            if snap is not None:
                with self._lock:
                    self._snapshot = snap
            self._stop.wait(self.period_s)

    # -- one reading ------------------------------------------------------------------------

    def _find_press(self) -> bool:
        """Ask ``find_press`` for the press description while there is none; True when it came."""
        if self.press is not None or self.find_press is None:
            return False
        try:
            self.press = self.find_press()
        except MppfError:  # a history being written: asked again later
            self.press = None
        if self.press is not None:
            self._tracker = LiveTracker(self.press.position_tolerance_mm, self._base)
        return self.press is not None

    def _connect(self) -> None:
        self._find_press()
        try:
            # a PLC that stopped answering stays the one watched until another is known
            self._target = self.locate() or self._target
        except MppfError as exc:
            self._publish_lost(f"cannot find the PLC: {exc.message}")
            return
        if self._target is None:
            self._publish_lost("no PLC known: start the panel with --plc URL, or start 'mppf loop' / 'mppf press'")
            return
        try:
            self._link = ModbusPress(self._target.url, self.press, heartbeat_s=None, timeout_s=REPLY_TIMEOUT_S)
        except MppfError as exc:
            self._publish_lost(exc.message)
            return
        self._targets = self._actuals = self._job = None

    def read_once(self) -> dict | None:
        """Read the PLC once; the snapshot, or None (and the link closed) when the PLC did not answer.

        The snapshot: ``time_utc``, ``state`` (:func:`mppf.panel.live.press_state`), ``link``
        (``ok``, ``url``, ``source``, ``error``, ``lost_s``), ``status`` (the status bits),
        ``plc_state``, ``fault`` / ``refusal`` (``code``, ``text``), ``sequence`` (validated, motion), ``owner``,
        ``stops`` (count, cause),
        ``heartbeat_stale``, ``matrices`` (per side ``target``, ``actual``, ``flags``; None
        without a press description), ``flagged``, ``n_flagged``, ``progress_pct``, ``moving``.
        """
        try:
            report = self._link.status_report()
            live = self._read_matrices(report) if self.press is not None else {}
        except MppfError as exc:
            self._disconnect()
            self._publish_lost(exc.message)
            return None
        self._lost_since = None
        link = {"ok": True, "url": self._target.url, "source": self._target.source, "error": "", "lost_s": 0}
        stale = self._tracker.heartbeat_stale(time.monotonic(), report["plc_heartbeat"])
        return {"time_utc": _now_utc(), "link": link, **status_fields(report), "heartbeat_stale": stale,
                "matrices": None, "flagged": [], "n_flagged": 0, "progress_pct": None,
                "press": self.press.name if self.press else "", "park_mm": self._park_mm(), **live}

    def _read_matrices(self, report: dict) -> dict:
        """Setpoints (when the job sequence changed), positions, fault bits; the tracker's marks."""
        busy = bool(report["status"]["busy"])
        job = (report["state"], report["validated"]["sequence"], report["motion"]["sequence"])
        changed, self._job = job != self._job, job
        self._tick += 1
        if self._targets is None or changed:  # new setpoints come with a change of state
            self._targets = self._link.read_setpoints_mm()
        if self._actuals is None or busy or changed or self._was_busy or self._tick % IDLE_EVERY == 0:
            self._actuals = self._link.read_actuals_mm()  # at rest once a second, and once more as a motion ends
        self._was_busy = busy
        faulted = self._link.read_fault_bits() if report["status"]["fault"] else {}
        marks = self._tracker.update(time.monotonic(), busy, self._targets, self._actuals, faulted)
        matrices = {side: {"target": grid_json(self._targets[side]), "actual": grid_json(self._actuals[side]),
                           "flags": marks["flags"][side]} for side in SIDES}
        return {"matrices": matrices, "flagged": marks["flagged"], "n_flagged": marks["n_flagged"],
                "progress_pct": marks["progress_pct"]}

    def _park_mm(self) -> dict | None:
        """Parking heights per side (the page draws parked punches grey)."""
        return None if self.press is None else {"upper": self.press.upper.park_mm, "lower": self.press.lower.park_mm}

    def _disconnect(self) -> None:
        link, self._link = self._link, None
        if link is not None:
            try:
                link.close()
            except Exception:  # noqa: BLE001 - closing a dead link must not stop the reader
                pass

    def _lost(self, error: str) -> dict:
        """The snapshot when the PLC does not answer: the last matrices kept, marked as old."""
        now = time.monotonic()
        if self._lost_since is None:
            self._lost_since = now
        old = getattr(self, "_snapshot", None) or {}
        target = self._target
        return {
            "time_utc": _now_utc(), "state": press_state(None, False) if target else "NO PLC",
            "link": {"ok": False, "url": target.url if target else "", "source": target.source if target else "",
                     "error": error, "lost_s": round(now - self._lost_since, 1)},
            "status": None, "plc_state": "", "fault": None, "refusal": None, "sequence": None, "owner": None,
            "stops": None, "heartbeat_stale": False,
            "matrices": old.get("matrices"), "flagged": [], "n_flagged": 0, "progress_pct": None, "moving": False,
            "press": self.press.name if self.press else "", "park_mm": self._park_mm(),
            "last_read_utc": old.get("last_read_utc")
            or (old.get("time_utc") if old.get("link", {}).get("ok") else None),
        }

    def _publish_lost(self, error: str) -> None:
        snap = self._lost(error)
        with self._lock:
            self._snapshot = snap
