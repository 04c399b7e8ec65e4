"""The program of the simulated press PLC: a register image and a scan cycle, no communication.

:class:`PlcProgram` is what runs inside the press PLC. Its register image is laid out by
``drivers/register_map.toml``; a master's writes land in the image at once (as a PLC's
Modbus server stores them: :meth:`PlcProgram.store`), and the program looks at them only
in its next scan (:meth:`PlcProgram.advance`), in this order:

1. inputs: the e-stop circuit and the remote-enable key switch;
2. guard: setpoint registers changed since the last scan are taken (IDLE, LOADED,
   VALIDATED) or undone and counted (every other state); written read-only or reserved
   registers are restored and counted;
3. the STOP request, from anyone (:mod:`mppf.sim.plc.commands`);
4. the owner's heartbeat: lease, watchdog, key switch during motion;
5. the command mailbox: at most one new command, acknowledged with its result;
6. motion: hydraulics (:mod:`mppf.sim.hydraulics`), fault timers, end of motion;
7. outputs: status, codes, tokens, actual positions, fault bits.

The states, commands and refusals are those of the register map's tables. There are no
threads and no pymodbus; time moves only when the host calls :meth:`advance`:
:mod:`mppf.sim.plc.server` every scan period of wall time behind a Modbus server,
:class:`mppf.sim.plc.link.InProcessPress` as fast as the CPU allows. The noise on the
reported positions is seeded. The injectable faults of the program (stuck punch, e-stop,
overpressure, halted program, key switch) are :mod:`mppf.sim.plc.program_faults`.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable

import numpy as np

from mppf.core.errors import InputError
from mppf.drivers.codec import (check_word_order, counts_to_mm, decode_int32, encode_int32, mm_to_counts, pack_bits,
                                u32_to_words, words_to_u32)
from mppf.drivers.regmap import RegisterMap, load_register_map
from mppf.model.press import PressConfig
from mppf.sim.hydraulics import Hydraulics
from mppf.sim.plc.commands import MATRICES, Commands
from mppf.sim.plc.motion import MAX_STEP_S, MAX_STEPS_PER_SCAN, Motion  # noqa: F401 - re-exported
from mppf.sim.plc.program_faults import ProgramFaults
from mppf.sim.plc.quirks import Quirks
from mppf.sim.plc.settings import PlcSettings

MAX_SCAN_S = 0.2
"""Longest scan period the simulated PLC accepts (the register map's scan_time_max_ms)."""
BEATS_KEPT = 20000
"""Owner heartbeats whose arrival times are kept (:attr:`PlcProgram.beats`)."""


class PlcProgram(Commands, Motion, ProgramFaults, Quirks):
    """The simulated press PLC's program (no communication, no threads).

    Parameters
    ----------
    press : PressConfig
        Matrix size, stroke limits (the PLC's own limits), speed, acceleration and
        position tolerance.
    regmap : RegisterMap, optional
        Register map (default: the packaged one).
    clock : callable, optional
        Time source (s) of the lease and watchdog; default :attr:`now_s`, the sum of the
        :meth:`advance` steps. The Modbus host passes ``time.monotonic``.
    **settings
        The fields of :class:`~mppf.sim.plc.settings.PlcSettings` (``word_order``,
        ``time_scale``, ``watchdog_s``, ``seed``, ``noise_mm``, ``scan_s``, ``remote``,
        ``limits``, ``quirks``).

    Attributes
    ----------
    regs : list of int
        The register image (the Modbus server shares this list with pymodbus).
    now_s : float
        Time advanced so far (s).
    state : str
        The state's name (``"IDLE"``, ``"EXECUTING"``...).
    beats : deque of float
        ``clock`` times at which a scan saw a new heartbeat of the owner.
    """

    def __init__(self, press: PressConfig, *, regmap: RegisterMap | None = None,
                 clock: Callable[[], float] | None = None, **settings):
        opts = PlcSettings(**settings)
        word_order, time_scale, watchdog_s, scan_s = opts.word_order, opts.time_scale, opts.watchdog_s, opts.scan_s
        self.press = press
        self.map = regmap or load_register_map()
        self.map.check_shape(press.rows, press.cols)
        self.word_order = check_word_order(word_order)
        if not (math.isfinite(time_scale) and time_scale > 0):
            raise InputError(f"time_scale must be a positive number, got {time_scale}",
                             hint="e.g. 1 (real time) or 50 (fast tests)")
        if watchdog_s is not None and not (math.isfinite(watchdog_s) and 0 <= watchdog_s <= 65.0):
            raise InputError(f"watchdog_s must be a number of seconds >= 0 and at most 65 (0 or None: off), "
                             f"got {watchdog_s}")
        if not (math.isfinite(scan_s) and 0 < scan_s <= MAX_SCAN_S):
            raise InputError(f"the scan period must be above 0 and at most {MAX_SCAN_S * 1000:g} ms, "
                             f"got {scan_s * 1000:g} ms", hint="e.g. 10 ms (the default) or 100 ms")
        self.time_scale = float(time_scale)
        self.watchdog_s = watchdog_s or None
        self.scan_s = float(scan_s)
        self.noise_mm = float(opts.noise_mm)
        self.remote_key = bool(opts.remote)
        self._configure(opts.limits or {})
        self.now_s = 0.0
        self._clock = clock if clock is not None else (lambda: self.now_s)
        self._rng = np.random.default_rng(opts.seed)
        self._words = self.map.words_in_use(press.rows, press.cols)
        park = np.stack([np.full(press.shape, press.upper.park_mm), np.full(press.shape, press.lower.park_mm)])
        self.hydraulics = Hydraulics(park, press.speed_mm_s, press.accel_mm_s2)
        self.regs: list[int] = [0] * self.map.total_registers
        self._ro_spans = self._read_only_spans()
        self.beats: deque[float] = deque(maxlen=BEATS_KEPT)
        self._init_faults()
        self._init_quirks(opts.quirks)
        self._power_on()

    # ------------------------------------------------------------------ state ---
    def _power_on(self) -> None:
        """The program's power-on state (also a restart); the punches stay where they are."""
        self.hydraulics.halt()
        self._actual_cache: dict = {}  # matrix -> (actual positions' bytes, their register words)
        self.goal_mm = self.hydraulics.position.copy()
        self.state = "IDLE"
        self.fault_code = 0
        self.punch_faults = np.zeros((2, self.press.rows, self.press.cols), dtype=bool)
        self.motion_time_s = 0.0
        self._still_s = float("inf")  # simulated s since a punch last moved
        self.heartbeat = 0
        self._reset_commands()
        if self.estop_pressed:
            self._latch("ESTOP")
        self.regs[: self.map.total_registers] = self._image()  # pymodbus keeps one guard register past the end
        self._copy = {side: self._setpoint_words(side) for side in MATRICES}
        self.publish()

    def restart(self) -> None:
        """Restart: the program runs again from its power-on state (punches stay put)."""
        self.frozen = False
        self._power_on()

    def adopt_image(self, registers: list[int]) -> None:
        """Make ``registers`` (a Modbus server's register list) the image, carrying the current one over."""
        registers[: len(self.regs)] = self.regs[: self.map.total_registers]
        self.regs = registers

    def _image(self) -> list[int]:
        """The complete power-on register image: identity, setpoints = positions, the rest 0."""
        m, p = self.map, self.press
        regs = [0] * m.total_registers

        def put(name, words):
            regs[m[name].address : m[name].address + len(words)] = words

        put("magic", u32_to_words(m.magic, self.word_order))
        put("map_version", [m.version])
        put("rows", [p.rows])
        put("cols", [p.cols])
        put("scan_time_max_ms", [max(1, math.ceil(self.scan_s * 1000 - 1e-9))])
        put("watchdog_ms", [round((self.watchdog_s or 0.0) * 1000)])
        put("position_tolerance", [round(p.position_tolerance_mm / m.count_mm)])
        put("positioning_timeout_ms", [min(65535, round(self.positioning_timeout_s * 1000))])
        put("rest_speed", [round(self.rest_speed_mm_s / m.count_mm)])
        put("rest_time_ms", [round(self.rest_time_s * 1000)])
        put("dimpling_limit", encode_int32(mm_to_counts([self.dimpling_limit_mm], m.count_mm), self.word_order))
        put("tip_gap_min", encode_int32(mm_to_counts([self.tip_gap_min_mm], m.count_mm), self.word_order))
        for side in MATRICES:
            limits = getattr(p, side)
            put(f"{side}_min", encode_int32(mm_to_counts([limits.min_mm], m.count_mm), self.word_order))
            put(f"{side}_max", encode_int32(mm_to_counts([limits.max_mm], m.count_mm), self.word_order))
        for k, side in enumerate(MATRICES):
            put(f"{side}_setpoints", encode_int32(mm_to_counts(self.goal_mm[k].ravel(), m.count_mm), self.word_order))
        return regs

    def _read_only_spans(self) -> list[tuple[int, int]]:
        """(start, end) of every register the master may not write: read-only fields and the gaps."""
        spans, at = [], 0
        for field in self.map.fields.values():
            if field.writable:
                if field.address > at:
                    spans.append((at, field.address))
                at = field.end
        if at < self.map.total_registers:
            spans.append((at, self.map.total_registers))
        return spans

    # ------------------------------------------------------------- the image ---
    def _word(self, name: str) -> int:
        return self.regs[self.map[name].address]

    def _u32(self, name: str) -> int:
        a = self.map[name].address
        return words_to_u32(self.regs[a : a + 2], self.word_order)

    def _set(self, name: str, words: list[int]) -> None:
        a = self.map[name].address
        self.regs[a : a + len(words)] = words

    def _set_u32(self, name: str, value: int) -> None:
        self._set(name, u32_to_words(value, self.word_order))

    def _setpoint_words(self, side: str) -> list[int]:
        a = self.map[f"{side}_setpoints"].address
        return self.regs[a : a + self._words]

    def _copy_mm(self) -> np.ndarray:
        """(2, rows, cols) the PLC's copy of the setpoints, in mm."""
        return np.stack([counts_to_mm(decode_int32(self._copy[side], self.word_order), self.map.count_mm).reshape(
            self.press.shape) for side in MATRICES])

    # ---------------------------------------------------------- master access ---
    def read(self, address: int, count: int) -> list[int]:
        """Registers ``address`` .. ``address + count - 1`` as a master reads them."""
        return self.regs[address : address + count]

    def store(self, address: int, values: list[int]) -> int | None:
        """Store a master's write as the PLC's Modbus server does: at once, unchecked.

        Returns
        -------
        int or None
            The exception code (ILLEGAL DATA ADDRESS) of a write outside the map, else None.
            The program acts on the write in its next scan.
        """
        if address < 0 or address + len(values) > self.map.total_registers:
            return self.map.illegal_address
        self.regs[address : address + len(values)] = [int(v) & 0xFFFF for v in values]
        return None

    def write_foreign_setpoint(self, matrix: str, row: int, col: int, value_mm: float) -> None:
        """Change one setpoint register (row, col 0-based) as a foreign master would: stored at once."""
        if matrix not in MATRICES:
            raise InputError(f"matrix must be 'upper' or 'lower', got {matrix!r}")
        index = self.map.punch_index(row, col, self.press.cols)
        self.store(self.map[f"{matrix}_setpoints"].address + 2 * index,
                   encode_int32(mm_to_counts([value_mm], self.map.count_mm), self.word_order))

    # --------------------------------------------------------------- the scan ---
    def advance(self, dt_s: float) -> None:
        """Let ``dt_s`` seconds pass, ending with one PLC scan (none while the program is halted)."""
        self.now_s += dt_s
        if self.frozen:
            return
        self._quirk_scan_start()     #    (a literal PLC's valves open a scan after GO)
        self._read_inputs()          # 1. e-stop circuit, key switch
        self._guard_registers()      # 2. setpoint changes, writes to read-only registers
        self._handle_stop_request()  # 3. STOP, from anyone
        self._check_lease()          # 4. the owner's heartbeat, lease, watchdog, key switch in motion
        self._took_go = False
        self._handle_mailbox()       # 5. one new command, acknowledged
        self._run_motion(dt_s)       # 6. hydraulics, fault timers, end of motion
        self.heartbeat = (self.heartbeat + 1) & 0xFFFF
        self.publish()               # 7. status, tokens, actual positions
        self._quirk_after_scan(self._took_go)  # foreign masters' writes land after the scan

    def _guard_registers(self) -> None:
        """Take setpoint changes while they are allowed, undo them (and foreign writes) otherwise."""
        refused = changed = False
        accept = self.map.states.by_name[self.state].setpoints == "accept"
        for side in MATRICES:
            now = self._setpoint_words(side)
            if now != self._copy[side]:
                if accept:
                    self._copy[side], changed = now, True
                else:
                    self._set(f"{side}_setpoints", self._copy[side])
                    refused = True
        if refused:
            self.refused_setpoint_writes = (self.refused_setpoint_writes + 1) & 0xFFFF
        if changed:
            self._drop_job("LOADED")
        for start, end in self._ro_spans:
            if self.regs[start:end] != self._shadow[start:end]:
                self.regs[start:end] = self._shadow[start:end]
                refused = True
        if refused:
            self.refused_writes = (self.refused_writes + 1) & 0xFFFF

    def _latch(self, name: str, *, halt: bool = True) -> None:
        """Latch fault ``name`` (the first fault keeps its code), drop the job, stop the punches."""
        if self.fault_code == 0:
            self.fault_code = self.map.fault(name)
        self.state = "FAULT"
        self.validated = (0, 0)
        if halt:
            self.hydraulics.halt()
        else:
            self.hydraulics.stop()

    # ----------------------------------------------------------------- status ---
    def status_bits(self) -> dict[str, bool]:
        """Status-word flags by name."""
        rest = self.at_rest
        return {
            "ready": self.state in ("IDLE", "LOADED", "VALIDATED", "COMPLETE", "STOPPED")
            and not self.fault_code and not self.estop_pressed,
            "busy": self.state in ("EXECUTING", "STOPPING") or not rest,
            "in_position": rest and self.in_band,
            "fault": self.fault_code != 0,
            "estop": self.estop_pressed,
            "remote_enabled": self.remote_key,
            "owned": self.owner != 0,
            "lease_ok": self.owner != 0 and self._lease_fresh(),
            "setpoints_locked": self.map.states.by_name[self.state].setpoints == "refuse",
        }

    def publish(self) -> None:
        """Write actual positions, fault bits, status, codes and tokens into the register image."""
        m = self.map
        actual = self.hydraulics.position
        if self.noise_mm > 0:
            actual = actual + self._rng.normal(0.0, self.noise_mm, actual.shape)
        for k, side in enumerate(MATRICES):
            self._set(f"{side}_actuals", self._actual_words(k, actual[k]))
            self._set(f"{side}_fault_bits", pack_bits(self.punch_faults[k].ravel()))
        counter, master, command, result = self.ack
        self._set("status_word", [self._late_status_word(m.status_word(**self.status_bits()))])
        for name, value in (("state", self._published_state()), ("fault_code", self.fault_code),
                            ("owner_ack_counter", self.owner_ack[0]), ("owner_ack_command", self.owner_ack[1]),
                            ("owner_result_code", self.owner_ack[2]),
                            ("refused_setpoint_writes", self.refused_setpoint_writes),
                            ("ack_counter", counter), ("ack_command", command), ("result_code", result),
                            ("validated_sequence", self.validated[0]), ("motion_sequence", self.motion[0]),
                            ("plc_heartbeat", self.heartbeat), ("refused_writes", self.refused_writes),
                            ("last_sequence", self.last_sequence), ("stop_count", self.stop_count),
                            ("stop_cause", m.stop_causes.code(self.stop_cause))):
            self._set(name, [value])
        for name, value in (("ack_master", master), ("owner_master", self.owner), ("validated_crc", self.validated[1]),
                            ("motion_crc", self.motion[1]), ("last_stop_master", self.last_stop_master),
                            ("claim_reply", self.claim_reply)):
            self._set_u32(name, value)
        self._shadow = self.regs[: m.total_registers]

    def _actual_words(self, k: int, actual_mm: np.ndarray) -> list[int]:
        """The register words of matrix ``k``'s actual positions (rows, cols) mm: encoded again only when they
        changed since the last scan (at rest they do not, and most scans find the punches at rest)."""
        key = actual_mm.tobytes()
        cached = self._actual_cache.get(k)
        if cached is None or cached[0] != key:
            cached = (key, encode_int32(mm_to_counts(actual_mm.ravel(), self.map.count_mm), self.word_order))
            self._actual_cache[k] = cached
        return cached[1]

    # ---------------------------------------------------------------- reading ---
    def actual_positions_mm(self) -> tuple[np.ndarray, np.ndarray]:
        """Actual tip heights (upper, lower), each (rows, cols) mm, without noise."""
        pos = self.hydraulics.position
        return pos[0].copy(), pos[1].copy()

    def setpoints_mm(self) -> tuple[np.ndarray, np.ndarray]:
        """Setpoints in the registers (upper, lower), each (rows, cols) mm."""
        sp = np.stack([counts_to_mm(decode_int32(self._setpoint_words(side), self.word_order),
                                    self.map.count_mm).reshape(self.press.shape) for side in MATRICES])
        return sp[0], sp[1]

    @property
    def busy(self) -> bool:
        """Motion in progress (state EXECUTING or STOPPING, or a punch not at rest)."""
        return self.state in ("EXECUTING", "STOPPING") or not self.at_rest
