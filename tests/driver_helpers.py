"""Helpers shared by the driver, PLC and press-CLI tests: a small press, jobs, a hook reporter, raw masters."""

from __future__ import annotations

import numpy as np

from mppf.drivers import codec
from mppf.drivers.audit import AuditLog
from mppf.model.job import Job
from mppf.model.job_parts import StepStrokes
from mppf.model.press import example_press_path, load_press, press_from_dict, press_to_toml

THICKNESS_MM = 20.0


def small_press(rows: int = 4, cols: int = 6, **forming):
    """The example press cut down to ``rows x cols`` punches (fast to upload and simulate)."""
    doc = load_press(example_press_path()).to_dict()
    doc["matrix"]["rows"], doc["matrix"]["cols"] = rows, cols
    doc["forming"].update(forming)
    return press_from_dict(doc)


def step_setpoints(press, upper_mm: float = 30.0, lower_mm: float = 10.0, seed: int = 0):
    """(upper, lower) setpoints with a little variation per punch, within the limits.

    Every pair's tips stay at least 25 mm apart and neighbours differ by at most 25 mm, so the
    PLC's own tip-gap and neighbour-step checks pass from the parks.
    """
    rng = np.random.default_rng(seed)
    upper = upper_mm + np.round(rng.uniform(0, 20, press.shape), 2)
    lower = lower_mm + np.round(rng.uniform(0, 20, press.shape), 2)
    return np.maximum(upper, lower + 25.0), lower


def small_job(press, n_steps: int = 2, *, beyond_limit: bool = False) -> Job:
    """A valid job of ``n_steps`` steps for a 20 mm plate; punch (0, 0) inactive (parked).

    The tips close on the plate (gap = thickness) and travel up to 20 mm with up to 10 mm
    between neighbours, step k at k/n of the way: within the dimpling limit and monotonic.
    ``beyond_limit``: one upper stroke of the last step beyond the press's limit.
    """
    active = np.ones(press.shape, dtype=bool)
    active[0, 0] = False
    travel = 10.0 + np.round(np.random.default_rng(7).uniform(0, 10, press.shape), 2)
    steps = []
    for k in range(1, n_steps + 1):
        lower = travel * k / n_steps
        upper = THICKNESS_MM + lower
        if beyond_limit and k == n_steps:
            upper = upper.copy()
            upper[1, 2] = press.upper.max_mm + 50.0
        steps.append(StepStrokes(np.where(active, upper, np.nan), np.where(active, lower, np.nan), active))
    return Job(press=press, thickness_mm=THICKNESS_MM, steps=steps)


class HookReporter:
    """A Reporter that records what it is told and runs test actions at chosen moments.

    ``on_start(task)``, ``on_info(message)`` and ``on_update(completed)`` are called
    with the reporter's arguments; they play the part of things happening in the shop
    (a foreign master, an e-stop, the operator's Ctrl-C) at a precise point of a step.
    """

    def __init__(self, on_start=None, on_info=None, on_update=None):
        self.tasks: list[str] = []
        self.messages: list[str] = []
        self.updates = 0
        self._on_start, self._on_info, self._on_update = on_start, on_info, on_update

    def start(self, task, total=None):
        self.tasks.append(task)
        if self._on_start:
            self._on_start(task)

    def advance(self, amount=1.0):
        pass

    def update(self, completed):
        self.updates += 1
        if self._on_update:
            self._on_update(completed)

    def finish(self):
        pass

    def info(self, message):
        self.messages.append(message)
        if self._on_info:
            self._on_info(message)


class RawMaster:
    """A bare master speaking register map v3 on any register store (the test's own, not the driver).

    ``write(address, words)`` and ``read(address, count)`` are the transport (the program's
    ``store``/``read`` in-process, a pymodbus client over a socket); ``scan()`` lets the PLC
    act (one program scan in-process, a wait on a socket). CLAIM sends a claim key and keeps
    the nonce the PLC returns; owner commands and beats carry the auth computed with it.
    """

    def __init__(self, rmap, write, read, scan, master_id: int, word_order: str = "ABCD"):
        self.map, self._write, self._read, self.scan = rmap, write, read, scan
        self.master_id, self.word_order = master_id, word_order
        self.counter = 0
        self.beats = 0
        self.nonce = 0
        self.claim_key = 0x5EED0000 + (master_id & 0xFFFF)

    def u32(self, value: int) -> list[int]:
        return codec.u32_to_words(value, self.word_order)

    def field(self, name: str) -> int:
        f = self.map[name]
        words = self._read(f.address, f.count)
        return words[0] if f.count == 1 else codec.words_to_u32(words, self.word_order)

    def state(self) -> str:
        return self.map.states.name(self.field("state"))

    def flags(self) -> dict:
        return self.map.status_flags(self.field("status_word"))

    def result(self) -> str:
        return self.map.results.name(self.field("result_code"))

    def send(self, name: str, sequence: int = 0, crc: int = 0, *, master: int | None = None,
             nonce: int | None = None) -> None:
        """Write the mailbox in one request (no wait); the auth uses ``nonce`` (default: this master's)."""
        self.counter = self.counter % 0xFFFF + 1
        master = self.master_id if master is None else master
        if name == "CLAIM" and not crc:
            crc = self.claim_key
        head = [self.map.command(name), self.counter] + self.u32(master) + self.u32(crc)
        auth = codec.auth_crc32(self.nonce if nonce is None else nonce, head + [sequence])
        self._write(self.map["command"].address, head + self.u32(auth) + [sequence])

    def command(self, name: str, sequence: int = 0, crc: int = 0, *, master: int | None = None,
                nonce: int | None = None) -> str:
        """Send a command, let the PLC scan, return the result's name (checks the acknowledgement)."""
        self.send(name, sequence, crc, master=master, nonce=nonce)
        self.scan()
        assert self.field("ack_counter") == self.counter, "the PLC did not acknowledge the command"
        result = self.result()
        if name == "CLAIM" and result == "ACCEPTED" and master in (None, self.master_id):
            self.nonce = self.field("claim_reply") ^ (crc or self.claim_key)
        return result

    def beat(self, *, master: int | None = None, nonce: int | None = None) -> None:
        self.beats = self.beats % 0xFFFF + 1
        head = [self.beats] + self.u32(self.master_id if master is None else master)
        auth = codec.auth_crc32(self.nonce if nonce is None else nonce, head)
        self._write(self.map["heartbeat_counter"].address, head + self.u32(auth))

    def stop(self) -> None:
        self._write(self.map["stop_request"].address, [1] + self.u32(self.master_id))

    def upload(self, upper_mm, lower_mm) -> int:
        """Write both setpoint blocks; return their CRC."""
        words = {side: codec.encode_int32(codec.mm_to_counts(np.ravel(v)), self.word_order)
                 for side, v in (("upper", upper_mm), ("lower", lower_mm))}
        for side in ("upper", "lower"):
            for address, part in codec.chunks(self.map[f"{side}_setpoints"].address, words[side]):
                self._write(address, part)
        return codec.setpoint_crc32(words["upper"], words["lower"])

    def actuals_mm(self, side: str, shape) -> np.ndarray:
        n = shape[0] * shape[1]
        words = self._read(self.map[f"{side}_actuals"].address, 2 * n)
        return codec.counts_to_mm(codec.decode_int32(words, self.word_order)).reshape(shape)


def fill_up_audit(path, monkeypatch):
    """The log at ``path`` with its last page nearly full, and every log opened from now on unable to grow."""
    from mppf.core.db import open_sqlite
    from mppf.drivers import audit as audit_module
    from mppf.drivers.audit import AuditLog

    with AuditLog(path) as log:
        log.record("tcp://plc:502", "connect", "ok", detail="x" * 3500)

    def full(*args, **kwargs):
        db = open_sqlite(*args, **kwargs)
        db.execute(f"PRAGMA max_page_count = {db.execute('PRAGMA page_count').fetchone()[0]}")
        return db

    monkeypatch.setattr(audit_module, "open_sqlite", full)


def actions(log: AuditLog) -> list[tuple[str, str]]:
    """(action, outcome) of every entry of the audit log, oldest first."""
    return [(e.action, e.outcome) for e in log.entries()]


def open_audit(tmp_path):
    """An audit log in ``tmp_path`` (the ``audit`` fixtures of the driver tests: yield it, then close it)."""
    log = AuditLog(tmp_path / "audit.sqlite")
    yield log
    log.close()


def running_sim(press):
    """A simulated PLC for ``press`` on a loopback port at 50x (watchdog 2 s): yield it, then stop it."""
    from mppf.sim.plc.host import start_simulated_plc

    handle = start_simulated_plc(press, time_scale=50.0, watchdog_s=2.0)
    yield handle
    handle.stop()


def install_press(tmp_path, monkeypatch, press):
    """``MPPF_HOME`` in ``tmp_path / "home"`` with ``press`` installed as this machine's press; returns the folder."""
    home = tmp_path / "home"
    monkeypatch.setenv("MPPF_HOME", str(home))
    home.mkdir()
    (home / "press.toml").write_text(press_to_toml(press))
    return home
