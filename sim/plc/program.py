"""The program of the simulated press PLC: register image, commands, checks, watchdog, motion.

:class:`PlcProgram` is what runs inside the press PLC, without any communication: the
register image laid out by ``drivers/register_map.toml``, the handling of a master's
writes (:meth:`~mppf.sim.plc.commands.Commands.write`: protected registers, validation,
GO / STOP / RESET; :mod:`mppf.sim.plc.commands`) and the PLC scan
(:meth:`PlcProgram.advance`: hydraulic motion by :mod:`mppf.sim.hydraulics`, fault timers,
watchdog, status). It has no threads and no pymodbus, and its time moves only when the
host calls :meth:`~PlcProgram.advance` with a time step: :mod:`mppf.sim.plc.server` does
so from the wall clock behind a Modbus server, :class:`mppf.sim.plc.link.InProcessPress`
as fast as the CPU allows. The noise on the reported positions is seeded. The injectable
faults of the program itself (stuck punch, e-stop, overpressure, halted program) are in
:mod:`mppf.sim.plc.program_faults`; those of the link (slow replies, dropped connections,
restarts) belong to the server.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from mppf.core.errors import InputError
from mppf.drivers.codec import (
    check_word_order,
    counts_to_mm,
    decode_int32,
    encode_int32,
    encode_uint32,
    mm_to_counts,
    pack_bits,
)
from mppf.drivers.regmap import RegisterMap, load_register_map
from mppf.planning.press import PressConfig
from mppf.sim.hydraulics import Hydraulics
from mppf.sim.plc.commands import MATRICES, Commands
from mppf.sim.plc.program_faults import ProgramFaults

MAX_STEPS_PER_SCAN = 50  # coarser steps rather than a scan that falls further and further behind


class PlcProgram(Commands, ProgramFaults):
    """The simulated press PLC's program (no communication, no threads).

    Parameters
    ----------
    press : PressConfig
        Matrix size, stroke limits (the PLC's own limits), speed, acceleration and
        position tolerance.
    word_order : {"ABCD", "CDAB"}
        Word order of 32-bit registers.
    time_scale : float
        Simulated seconds of motion per second of :meth:`advance` (50 = 50x faster).
    watchdog_s : float or None
        Seconds (of ``clock``) without a master-heartbeat change after which motion is
        stopped with fault WATCHDOG (None or 0: no watchdog).
    seed : int
        Seed of the measurement noise.
    noise_mm : float
        Standard deviation of the noise on reported actual positions (0: exact).
    tick_s : float
        The scan period the host keeps; the motion is integrated in steps of at most
        ``tick_s`` simulated seconds.
    regmap : RegisterMap, optional
        Register map (default: the packaged one).
    announce_simulated : bool
        Set status bit ``simulated`` (the driver then skips the operator's confirmation);
        False makes it pose as a real press (to test the confirmation path).
    clock : callable, optional
        Time source (s) of the watchdog and of the ``remote`` bit; default :attr:`now_s`,
        the sum of the :meth:`advance` steps. The Modbus host passes ``time.monotonic``.

    Attributes
    ----------
    regs : list of int
        The register image (the Modbus server shares this list with pymodbus).
    now_s : float
        Time advanced so far (s).
    """

    def __init__(
        self,
        press: PressConfig,
        *,
        word_order: str = "ABCD",
        time_scale: float = 1.0,
        watchdog_s: float | None = 1.0,
        seed: int = 0,
        noise_mm: float = 0.0,
        tick_s: float = 0.02,
        regmap: RegisterMap | None = None,
        announce_simulated: bool = True,
        clock: Callable[[], float] | None = None,
    ):
        self.press = press
        self.announce_simulated = bool(announce_simulated)
        self.map = regmap or load_register_map()
        self.map.check_shape(press.rows, press.cols)
        self.word_order = check_word_order(word_order)
        if not (time_scale > 0 and math.isfinite(time_scale)):
            raise InputError(f"time_scale must be a positive number, got {time_scale}",
                             hint="e.g. 1 (real time) or 50 (fast tests)")
        if watchdog_s is not None and not (watchdog_s >= 0 and math.isfinite(watchdog_s)):
            raise InputError(f"watchdog_s must be a number of seconds >= 0 (0 or None: off), got {watchdog_s}")
        if not tick_s > 0:
            raise InputError(f"tick_s must be positive, got {tick_s}")
        self.time_scale = float(time_scale)
        self.watchdog_s = watchdog_s or None
        self.tick_s = float(tick_s)
        self.noise_mm = float(noise_mm)
        self.now_s = 0.0
        self._clock = clock if clock is not None else (lambda: self.now_s)
        self._rng = np.random.default_rng(seed)
        self._words = self.map.words_in_use(press.rows, press.cols)
        park = np.stack(
            [np.full(press.shape, press.upper.park_mm), np.full(press.shape, press.lower.park_mm)]
        )
        self.hydraulics = Hydraulics(park, press.speed_mm_s, press.accel_mm_s2)
        self.regs: list[int] = [0] * self.map.total_registers
        self._init_faults()
        self._power_on()

    # ------------------------------------------------------------------ state ---
    def _power_on(self) -> None:
        """Reset the program state (power-on or restart); punches stay where they are."""
        self.hydraulics.halt()
        self.goal_mm = self.hydraulics.position.copy()
        self.busy = False
        self.fault_code = 0
        self.refusal_code = 0
        self.ack_sequence = 0
        self.motion_sequence = 0
        self.data_valid = False
        self.punch_faults = np.zeros((2, self.press.rows, self.press.cols), dtype=bool)
        self.motion_time_s = 0.0
        self._arrived_at_s: float | None = None
        self.heartbeat = 0
        self._last_master_hb: float | None = None
        self._motion_started_at = 0.0
        if self.estop_pressed:
            self.fault_code = self.map.fault("ESTOP")
        image = self._image()
        self.regs[: len(image)] = image  # pymodbus keeps one guard register past the end
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
        """The complete power-on register image."""
        m, p = self.map, self.press
        regs = [0] * m.total_registers

        def put(name, words):
            regs[m[name].address : m[name].address + len(words)] = words

        put("magic", encode_uint32([m.magic], self.word_order))
        put("map_version", [m.version])
        put("rows", [p.rows])
        put("cols", [p.cols])
        for side in MATRICES:
            limits = getattr(p, side)
            put(f"{side}_min", encode_int32(mm_to_counts([limits.min_mm], m.count_mm), self.word_order))
            put(f"{side}_max", encode_int32(mm_to_counts([limits.max_mm], m.count_mm), self.word_order))
        for k, side in enumerate(MATRICES):
            put(f"{side}_setpoints", encode_int32(mm_to_counts(self.goal_mm[k].ravel(), m.count_mm), self.word_order))
        return regs

    def _get(self, name: str) -> list[int]:
        f = self.map[name]
        return self.regs[f.address : f.end]

    def _set(self, name: str, words: list[int]) -> None:
        a = self.map[name].address
        self.regs[a : a + len(words)] = words

    def _setpoint_words(self, side: str) -> list[int]:
        a = self.map[f"{side}_setpoints"].address
        return self.regs[a : a + self._words]

    def _setpoints_mm(self) -> np.ndarray:
        """(2, rows, cols) setpoints currently in the registers."""
        return np.stack([
            counts_to_mm(decode_int32(self._setpoint_words(side), self.word_order), self.map.count_mm).reshape(
                self.press.shape)
            for side in MATRICES
        ])

    def _status_flags(self) -> dict[str, bool]:
        fault = self.fault_code != 0
        in_position = (
            not self.busy
            and bool(np.all(np.abs(self.hydraulics.position - self.goal_mm) <= self.press.position_tolerance_mm))
        )
        remote = self._last_master_hb is not None and (
            self.watchdog_s is None or self._clock() - self._last_master_hb <= self.watchdog_s
        )
        return {
            "ready": not (self.busy or fault or self.estop_pressed),
            "busy": self.busy,
            "in_position": in_position,
            "fault": fault,
            "estop": self.estop_pressed,
            "remote": remote,
            "data_valid": self.data_valid,
            "simulated": self.announce_simulated,
        }

    def publish(self) -> None:
        """Write actual positions, fault bits and status into the register image."""
        actual = self.hydraulics.position
        if self.noise_mm > 0:
            actual = actual + self._rng.normal(0.0, self.noise_mm, actual.shape)
        for k, side in enumerate(MATRICES):
            self._set(f"{side}_actuals", encode_int32(mm_to_counts(actual[k].ravel(), self.map.count_mm), self.word_order))
        self._publish_status()

    def _publish_status(self) -> None:
        """Write fault bits, status word, codes, sequences and heartbeat (cheap: after each write)."""
        for k, side in enumerate(MATRICES):
            self._set(f"{side}_fault_bits", pack_bits(self.punch_faults[k].ravel()))
        self._set("status_word", [self.map.status_word(**self._status_flags())])
        self._set("fault_code", [self.fault_code])
        self._set("refusal_code", [self.refusal_code])
        self._set("acknowledged_sequence", [self.ack_sequence])
        self._set("motion_sequence", [self.motion_sequence])
        self._set("plc_heartbeat", [self.heartbeat])

    def _latch(self, name: str, *, halt: bool = True) -> None:
        """Latch fault ``name`` and stop the punches (at once, or decelerating)."""
        if self.fault_code == 0:
            self.fault_code = self.map.fault(name)
        if halt:
            self.hydraulics.halt()
        else:
            self.hydraulics.stop()

    # ---------------------------------------------------------- master access ---
    def read(self, address: int, count: int) -> list[int]:
        """Registers ``address`` .. ``address + count - 1`` as a master reads them."""
        return self.regs[address : address + count]

    # --------------------------------------------------------------- the scan ---
    def advance(self, dt_s: float) -> None:
        """Let ``dt_s`` seconds pass: one PLC scan over them (none while the program is halted)."""
        self.now_s += dt_s
        if self.frozen:
            return
        sim_dt = dt_s * self.time_scale
        steps = min(max(1, int(np.ceil(sim_dt / self.tick_s))), MAX_STEPS_PER_SCAN)
        for _ in range(steps):
            self._step(sim_dt / steps)
            if self.frozen:  # the program halted in this step: this scan publishes its last image
                break
        self._check_watchdog()
        self.heartbeat = (self.heartbeat + 1) & 0xFFFF
        self.publish()

    def _step(self, dt_s: float) -> None:
        """Advance the motion and its timers by ``dt_s`` simulated seconds."""
        self.hydraulics.step(dt_s)
        if not self.busy:
            return
        self.motion_time_s += dt_s
        self._run_motion_faults()
        if self.frozen:
            return
        self._check_stuck()
        if not self.hydraulics.moving and not self._stuck_pending():
            self.busy = False

    def _check_watchdog(self) -> None:
        if self.watchdog_s is None or not self.busy or self.fault_code:
            return
        last = max(self._last_master_hb or 0.0, self._motion_started_at)
        if self._clock() - last > self.watchdog_s:
            self._latch("WATCHDOG", halt=False)

    # ---------------------------------------------------------------- reading ---
    def actual_positions_mm(self) -> tuple[np.ndarray, np.ndarray]:
        """Actual tip heights (upper, lower), each (rows, cols) mm, without noise."""
        pos = self.hydraulics.position
        return pos[0].copy(), pos[1].copy()

    def setpoints_mm(self) -> tuple[np.ndarray, np.ndarray]:
        """Setpoints in the registers (upper, lower), each (rows, cols) mm."""
        sp = self._setpoints_mm()
        return sp[0], sp[1]

    def status_bits(self) -> dict[str, bool]:
        """Status-word flags by name."""
        return self._status_flags()
