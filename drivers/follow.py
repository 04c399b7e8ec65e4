"""Step 8 of a press step: follow the motion to its end and check where every punch stands.

:class:`Follow` is the part of :class:`mppf.drivers.plc_press.PlcPress` that polls the
PLC after GO: a fault or e-stop, a restarted PLC (sequence lost, heartbeat fallen), a
halted PLC program (heartbeat stale) or a timeout sends STOP and raises
:class:`~mppf.core.errors.PressFault`; at the end the actual positions are read and every
punch is checked against its target. Time is the press's clock (``self._clock``), so the
same code follows a real press in wall time and the in-process press in simulated time.
"""

from __future__ import annotations

import math

import numpy as np

from mppf.core.errors import LinkError, PlcError, PressFault
from mppf.core.presslink import PressStatus, StepResult
from mppf.core.progress import Reporter
from mppf.drivers import codec
from mppf.drivers.handshake import SIDES, listed

PLC_STALE_S = 1.0  # plc_heartbeat unchanged this long during motion: the PLC program has stopped
PROGRESS_S = 0.25  # actual positions read for the progress display this often during motion


def motion_time_s(distance_mm: float, speed_mm_s: float, accel_mm_s2: float) -> float:
    """Time of a trapezoidal (or triangular) move of ``distance_mm`` from rest to rest."""
    d = abs(float(distance_mm))
    ramp_mm = speed_mm_s**2 / accel_mm_s2  # accelerate + decelerate to/from full speed
    if d >= ramp_mm:
        return d / speed_mm_s + speed_mm_s / accel_mm_s2
    return 2.0 * math.sqrt(d / accel_mm_s2)


class Follow:
    """Motion following, fault reports and the final position check (a mixin of ``PlcPress``)."""

    def read_actuals_mm(self) -> dict[str, np.ndarray]:
        """Actual tip heights, ``{"upper": (rows, cols), "lower": (rows, cols)}`` in mm."""
        out = {}
        for side in SIDES:
            addr, n = self._block("actuals", side)
            words = self._io.read_holding(addr, n, max_chunk=self.map.max_read_registers)
            counts = codec.decode_int32(words, self.identity.word_order).reshape(self.press.shape)
            out[side] = codec.counts_to_mm(counts, self.map.count_mm)
        return out

    def _fault_bits(self) -> dict[str, np.ndarray]:
        n = self.press.rows * self.press.cols
        out = {}
        for side in SIDES:
            f = self._field(f"{side}_fault_bits")
            words = self._io.read_holding(f.address, self.map.bit_words_in_use(self.press.rows, self.press.cols),
                                          max_chunk=self.map.max_read_registers)
            out[side] = codec.unpack_bits(words, n).reshape(self.press.shape)
        return out

    def _follow(self, seq, targets_mm, start_mm, reporter: Reporter, timeout_s, t0: float) -> StepResult:
        """Poll until motion ends; then check the actual positions."""
        travel = {side: np.abs(targets_mm[side] - start_mm[side]) for side in SIDES}
        total_mm = float(sum(t.sum() for t in travel.values()))
        if timeout_s is None:
            longest = max(float(t.max()) for t in travel.values())
            timeout_s = 2.0 * motion_time_s(longest, self.press.speed_mm_s, self.press.accel_mm_s2) + 10.0
        reporter.start(f"motion job {seq} (mm of travel)", total=max(total_mm, 1e-9))
        last_progress = self._clock.now()
        last_hb = None
        last_hb_change = self._clock.now()
        while True:
            raw = self._status_words()
            st = self._status_from(raw)
            now = self._clock.now()
            if st.fault or st.estop:
                reporter.finish()
                self._stop_after_trouble(f"fault: {st.fault_text}")
                raise self._fault_error(seq, st, targets_mm)
            lost = raw["acknowledged_sequence"] != seq or raw["motion_sequence"] != seq
            restarted = last_hb is not None and 0 < (last_hb - raw["plc_heartbeat"]) < 0x8000
            if lost or restarted:
                reporter.finish()
                self._stop_after_trouble("PLC restarted")
                beat = f", PLC heartbeat fell from {last_hb} to {raw['plc_heartbeat']}" if restarted else ""
                raise PressFault(
                    f"the PLC restarted (or another master took over) during job {seq}: acknowledged "
                    f"sequence {raw['acknowledged_sequence']}, motion sequence {raw['motion_sequence']}{beat}; "
                    "STOP was sent, the step did not complete",
                    hint="check the press, then run the step again",
                )
            if raw["plc_heartbeat"] != last_hb:
                last_hb, last_hb_change = raw["plc_heartbeat"], now
            elif now - last_hb_change > PLC_STALE_S:
                reporter.finish()
                self._stop_after_trouble("PLC heartbeat stale")
                raise PressFault(
                    f"job {seq}: the PLC heartbeat stayed at {last_hb} for {now - last_hb_change:.1f} s during "
                    "motion: the PLC program is not running (PLC in STOP mode, or halted); STOP was sent, but "
                    "the PLC may not act on it",
                    hint="stop the press at the machine and check the PLC before anything else",
                )
            if not st.busy:
                break
            if now - t0 > timeout_s:
                reporter.finish()
                self._stop_after_trouble(f"timeout after {timeout_s:.1f} s")
                raise PressFault(
                    f"job {seq}: motion did not end within {timeout_s:.1f} s; STOP was sent",
                    hint="check the hydraulics and punches; give --timeout for slow moves",
                )
            if now - last_progress >= PROGRESS_S:
                actual = self.read_actuals_mm()
                remaining = sum(float(np.abs(targets_mm[s] - actual[s]).sum()) for s in SIDES)
                reporter.update(max(0.0, total_mm - remaining))
                last_progress = now
            self._clock.sleep(self.poll_s)
        duration = self._clock.now() - t0
        actual = self.read_actuals_mm()
        reporter.update(total_mm - sum(float(np.abs(targets_mm[s] - actual[s]).sum()) for s in SIDES))
        reporter.finish()
        return self._check_arrival(seq, targets_mm, actual, duration)

    def _check_arrival(self, seq: int, targets_mm, actual, duration: float) -> StepResult:
        """Every punch within the position tolerance of its target, else PressFault naming them."""
        errors = {s: actual[s] - targets_mm[s] for s in SIDES}
        max_error = max(float(np.abs(e).max()) for e in errors.values())
        off = self._out_of_tolerance(targets_mm, actual)
        if off:
            self._record("complete", "out of tolerance", sequence=seq, detail=f"{len(off)} punches")
            raise PressFault(
                f"job {seq}: {len(off)} punch(es) not in position within {self.press.position_tolerance_mm} mm "
                f"after the motion ended: " + listed(off),
                hint="a punch may be stuck or blocked: inspect it before the next step",
            )
        self._record("complete", "ok", sequence=seq, detail=f"max error {max_error:.3f} mm, {duration:.2f} s")
        return StepResult(
            sequence=seq,
            target_upper_mm=targets_mm["upper"],
            target_lower_mm=targets_mm["lower"],
            actual_upper_mm=actual["upper"],
            actual_lower_mm=actual["lower"],
            max_error_mm=max_error,
            duration_s=duration,
        )

    def _out_of_tolerance(self, targets_mm, actual_mm) -> list[str]:
        tol = self.press.position_tolerance_mm + 0.5 * self.map.count_mm
        off = []
        for side in SIDES:
            for r, c in np.argwhere(np.abs(actual_mm[side] - targets_mm[side]) > tol):
                off.append(f"{side} (row {r}, col {c}) target {targets_mm[side][r, c]:.2f} mm, "
                           f"actual {actual_mm[side][r, c]:.2f} mm")
        return off

    def _fault_error(self, seq: int, st: PressStatus, targets_mm) -> PressFault:
        """The PressFault for a fault or e-stop seen during motion (names faulted punches)."""
        what = "the e-stop was pressed" if st.estop and not st.fault else f"the PLC faulted: {st.fault_text}"
        details = ""
        try:
            bits = self._fault_bits()
            actual = self.read_actuals_mm()
            named = [f"{side} (row {r}, col {c}) target {targets_mm[side][r, c]:.2f} mm, "
                     f"actual {actual[side][r, c]:.2f} mm"
                     for side in SIDES for r, c in np.argwhere(bits[side])]
            if named:
                details = f"; faulted punches: {listed(named)}"
        except (LinkError, PlcError):  # the report loses its details, never the fault
            details = "; the per-punch fault bits could not be read"
        self._record("complete", "fault", sequence=seq, detail=f"{st.fault_text}{details}")
        return PressFault(
            f"job {seq}: {what} during motion; STOP was sent{details}",
            hint="remove the cause, then 'mppf reset' and run the step again",
        )
