"""Steps 1-7 of a press step: limits, readiness, upload, read-back, CRC and sequence, GO.

:class:`Handshake` is the part of :class:`mppf.drivers.plc_press.PlcPress` that gets one
step into the PLC and started: nothing is written when a setpoint is beyond a limit or the
PLC is not ready; every register written is read back and compared; the PLC validates
the CRC and the job sequence; GO is sent once, never retried. Every stage is recorded in
the audit log.
"""

from __future__ import annotations

import numpy as np

from mppf.core.errors import ConfigError, InputError, LimitError, LinkError, PlcError, PressRefused
from mppf.core.presslink import PressStatus
from mppf.core.progress import Reporter
from mppf.drivers import codec

SIDES = ("upper", "lower")
MAX_LISTED = 8  # punches named in one error message


def listed(items: list[str]) -> str:
    """At most :data:`MAX_LISTED` items joined by "; ", with how many more."""
    more = f"; and {len(items) - MAX_LISTED} more" if len(items) > MAX_LISTED else ""
    return "; ".join(items[:MAX_LISTED]) + more


class Handshake:
    """Limits, upload, verification, validation and GO (a mixin of ``PlcPress``)."""

    def check_setpoints(self, upper_mm, lower_mm) -> dict[str, np.ndarray]:
        """Check shapes and limits; return the setpoints in counts.

        Parameters
        ----------
        upper_mm, lower_mm : (rows, cols) float

        Returns
        -------
        dict of str to (rows, cols) int64
            Counts of 0.01 mm per side.

        Raises
        ------
        InputError
            Wrong shape or NaN.
        LimitError
            Setpoints beyond the press description's or the PLC's limits (lists the punches).
        """
        if self.press is None:
            raise InputError("a press description is needed to run a step", hint="pass press=PressConfig")
        grids = {"upper": np.asarray(upper_mm, dtype=float), "lower": np.asarray(lower_mm, dtype=float)}
        problems = []
        for side, grid in grids.items():
            if grid.shape != self.press.shape:
                raise InputError(f"{side} setpoints have shape {grid.shape}, the press has {self.press.shape}")
            if np.isnan(grid).any():
                r, c = np.argwhere(np.isnan(grid))[0]
                raise InputError(f"{side} setpoint of punch (row {r}, col {c}) is NaN",
                                 hint="fill inactive punches with parking heights (StepStrokes.setpoints_mm)")
            axis = getattr(self.press, side)
            plc_lo, plc_hi = self.identity.limits_mm[side]
            lo, hi = max(axis.min_mm, plc_lo), min(axis.max_mm, plc_hi)
            for r, c in np.argwhere((grid < lo) | (grid > hi)):
                problems.append(f"{side} punch {r * self.press.cols + c} (row {r}, col {c}) = "
                                f"{grid[r, c]:.2f} mm, limits {lo:.2f}..{hi:.2f} mm")
        if problems:
            self._record("limits", "refused", detail=f"{len(problems)} setpoints beyond limits")
            raise LimitError(
                f"{len(problems)} setpoint(s) beyond the stroke limits, nothing was written to the PLC: "
                f"{listed(problems)}",
                hint="re-plan the job for this press (limits from the press description and the PLC)",
            )
        return {side: codec.mm_to_counts(grid, self.map.count_mm) for side, grid in grids.items()}

    def _block(self, kind: str, side: str) -> tuple[int, int]:
        """(address, registers in use) of a setpoint/actual block."""
        return self._field(f"{side}_{kind}").address, self.map.words_in_use(self.press.rows, self.press.cols)

    def _next_sequence(self) -> int:
        raw = self._status_words()
        base = max(raw["acknowledged_sequence"], raw["motion_sequence"], self._last_sequence)
        return base % 0xFFFF + 1  # 1..65535, never 0

    def _require_ready(self, st: PressStatus, what: str) -> None:
        if st.estop:
            raise PressRefused(f"{what} refused: the e-stop of the press is pressed",
                               hint="release the e-stop, then 'mppf reset'")
        if st.fault:
            raise PressRefused(f"{what} refused: the PLC has a latched fault ({st.fault_text})",
                               hint="remove the cause, then 'mppf reset'")
        if st.busy:
            raise PressRefused(f"{what} refused: the press is moving", hint="wait for the motion to end or STOP it")
        if not st.ready:
            raise PressRefused(f"{what} refused: the PLC is not ready", hint="check the PLC (mode, hydraulics)")

    def _prepare(self, upper_mm, lower_mm, reporter: Reporter) -> tuple[int, dict[str, np.ndarray]]:
        """Limits, readiness, upload, read-back, CRC and sequence; return (sequence, targets mm)."""
        counts = self.check_setpoints(upper_mm, lower_mm)
        targets_mm = {side: codec.counts_to_mm(counts[side], self.map.count_mm) for side in SIDES}
        blocks = {side: codec.encode_int32(counts[side].ravel(), self.identity.word_order) for side in SIDES}
        self._require_ready(self.status(), "upload")
        seq = self._next_sequence()
        self._last_sequence = seq
        self._upload(blocks, seq, reporter)
        self._validate(blocks, seq, reporter)
        return seq, targets_mm

    def _upload(self, blocks: dict[str, list[int]], seq: int, reporter: Reporter) -> None:
        """Write both setpoint blocks, then read them back and compare every register."""
        n = sum(len(b) for b in blocks.values())
        reporter.start(f"upload job {seq} ({n} registers)", total=2 * n)
        for side in SIDES:
            addr, _ = self._block("setpoints", side)
            try:
                self._io.write_registers(addr, blocks[side], max_chunk=self.map.max_write_registers,
                                         on_chunk=reporter.advance)
            except (LinkError, PlcError) as exc:  # either way the upload failed: recorded, raised
                self._record("upload", "failed", sequence=seq, detail=f"{side}: {exc}")
                raise
        self._record("upload", "ok", sequence=seq, detail=f"{n} registers, word order {self.identity.word_order}")
        mismatches = []
        for side in SIDES:
            addr, count = self._block("setpoints", side)
            back = self._io.read_holding(addr, count, max_chunk=self.map.max_read_registers, on_chunk=reporter.advance)
            mismatches += [(side, addr + i, w, r) for i, (w, r) in enumerate(zip(blocks[side], back)) if w != r]
        reporter.finish()
        if mismatches:
            side, a, w, r = mismatches[0]
            self._record("verify", "failed", sequence=seq, detail=f"{len(mismatches)} registers differ")
            raise PressRefused(
                f"verification of job {seq} failed: {len(mismatches)} setpoint register(s) read back differ "
                f"from what was written (first: {side} block, register {a}: wrote {w}, read {r}); GO was not sent",
                hint="another master may be writing to the PLC; check, then run the step again",
            )
        reporter.info(f"job {seq}: {n} setpoint registers written and verified")

    def _validate(self, blocks: dict[str, list[int]], seq: int, reporter: Reporter) -> None:
        """Write CRC and sequence (one request); check the PLC acknowledged and is ready for GO."""
        crc_f, seq_f = self._field("setpoint_crc"), self._field("job_sequence")
        if seq_f.address != crc_f.end:
            raise ConfigError("register map: job_sequence must follow setpoint_crc (one request)")
        crc = codec.setpoint_crc32(blocks["upper"], blocks["lower"])
        words = codec.encode_uint32([crc], self.identity.word_order) + [seq]
        try:
            self._io.write_command(crc_f.address, words)
        except PlcError as exc:
            text = self._refusal_text()
            self._record("validate", "refused", sequence=seq, detail=f"crc 0x{crc:08X}: {text}")
            raise PressRefused(f"the PLC refused job {seq} (CRC 0x{crc:08X}): {text}; GO was not sent",
                               hint="run the step again; if it repeats, check the PLC limits and other masters") from exc
        except LinkError as exc:
            self._record("validate", "failed", sequence=seq, detail=str(exc))
            raise
        self._record("validate", "ok", sequence=seq, detail=f"crc 0x{crc:08X}")
        st = self.status()
        if st.acknowledged_sequence != seq or not st.data_valid:
            self._record("go", "not sent", sequence=seq, detail="sequence not acknowledged")
            raise PressRefused(
                f"the PLC did not acknowledge job {seq} (acknowledged sequence {st.acknowledged_sequence}, "
                f"data valid {st.data_valid}); GO was not sent",
                hint="another master may be writing to the PLC; run the step again",
            )
        try:
            self._require_ready(st, "GO")
        except PressRefused as exc:
            self._record("go", "not sent", sequence=seq, detail=exc.message)
            raise
        reporter.info(f"job {seq} validated by the PLC (CRC 0x{crc:08X})")

    def _go(self, seq: int) -> None:
        """GO with the job sequence: one attempt, never retried."""
        try:
            self._command("GO", seq)
        except PlcError as exc:
            text = self._refusal_text()
            self._record("go", "refused", sequence=seq, detail=text)
            raise PressRefused(f"the PLC refused GO for job {seq}: {text}; nothing moved",
                               hint="run the step again (it uploads and verifies afresh)") from exc
        except LinkError as exc:
            self._record("go", "failed", sequence=seq, detail=str(exc))
            raise
        self._record("go", "ok", sequence=seq)
