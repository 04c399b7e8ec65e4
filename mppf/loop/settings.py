"""The loop's settings: when it stops, how it plans the first cycle, how it waits (stored with each plate).

The loop corrects one way (:func:`mppf.correct.step.correct_step`), so no setting chooses a correction;
the keys that did in older histories (:data:`RETIRED_KEYS`) are read and ignored.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

from mppf.core.defaults import RMS_TOLERANCE_MM, TOLERANCE_MM
from mppf.core.validate import check_number
from mppf.forming.material import DEFAULT_YIELD_UNCERTAINTY_PCT, check_yield_uncertainty

MAX_CYCLES_LIMIT = 50
"""Most press cycles a plate may be given."""

MAX_RESCANS = 10
"""Most rescans a cycle may ask for."""

RETIRED_KEYS = ("gain", "model_gain", "calibrate", "learn")
"""Keys of older plates' settings that chose corrections the loop no longer has; ignored when read."""

_log = logging.getLogger("mppf")


@dataclass(frozen=True)
class LoopSettings:
    """When the loop stops, how it plans the first cycle and how it waits for scans.

    Attributes
    ----------
    tolerance_mm : float
        Largest absolute deviation accepted (mm; default :data:`mppf.core.defaults.TOLERANCE_MM`).
    rms_tolerance_mm : float
        Largest RMS deviation accepted (mm; default :data:`mppf.core.defaults.RMS_TOLERANCE_MM`).
        In tolerance = both limits met.
    max_cycles : int
        Press cycles at most (the first, planned one included), 1 to :data:`MAX_CYCLES_LIMIT`.
    divergence_factor : float
        The loop stops as diverged when the RMS deviation is more than this factor (> 1)
        times the best one before it in two cycles running, or grows two cycles in a row
        (see :func:`mppf.loop.decide.decide`).
    springback : bool
        Plan the first cycle with springback pre-compensation (over-bend).
    yield_uncertainty_pct : float
        Declared scatter of the plate's yield stress, +- % in [0, 50) (``--yield-uncertainty``;
        default :data:`mppf.forming.material.DEFAULT_YIELD_UNCERTAINTY_PCT`): the first cycle's
        springback is compensated for the weakest plate of the range, so the first press
        under-bends and the corrections add bend (docs/planning.md, "The first press under-bends").
    offset_mm : float or None
        Normal offset from the design surface to the scanned skin (mm); None = half the
        thickness (the design is the moulded mid-surface, the scanner sees the top skin).
    margin_mm : float or None
        Trim margin the flat plate is cut with (mm, see :func:`mppf.planning.plan.plan_job`);
        None = the press's ``[forming] margin_mm``. The scans carry it; the tolerance is
        judged on the net plate.
    on_pressed : str or None
        Command run when a cycle is pressed, after its scan request is written (``--on-pressed``;
        the request's path is its last argument and ``$MPPF_SCAN_REQUEST``; no shell:
        :func:`mppf.loop.scan_request.run_on_pressed`).
    on_pressed_timeout_s : float
        Longest run of that command (s); it is killed after, the loop goes on.
    mark_settle_s : float
        How long a scan without its reference mark waits for one saved just after it (s),
        when the plate does not need the mark (:mod:`mppf.loop.marks`).
    mark_timeout_s : float
        How long a scan of a plate that needs its mark (nearly symmetric) waits for it (s)
        before the loop stops (exit 4, the cycle stays "pressed").
    rescans : int
        Rescans a compared cycle may ask for, 0 to :data:`MAX_RESCANS`, when its verdict needs
        review only because areas of the net plate were not measured
        (:mod:`mppf.loop.rescanning`; ``--rescans``); 0: the loop stops with needs_review there.
    rescan_timeout_s : float
        Longest wait for a rescan file (s; ``--rescan-timeout``; at most the scanner's own
        timeout). A station that does not answer rescan requests costs this once per run: after
        one unanswered request the run asks for no more rescans and decides on the scans taken.
    """

    tolerance_mm: float = TOLERANCE_MM
    rms_tolerance_mm: float = RMS_TOLERANCE_MM
    max_cycles: int = 5
    divergence_factor: float = 1.5
    springback: bool = True
    yield_uncertainty_pct: float = DEFAULT_YIELD_UNCERTAINTY_PCT
    offset_mm: float | None = None
    margin_mm: float | None = None
    on_pressed: str | None = None
    on_pressed_timeout_s: float = 60.0
    mark_settle_s: float = 5.0
    mark_timeout_s: float = 600.0
    rescans: int = 2
    rescan_timeout_s: float = 300.0

    def __post_init__(self):
        checks = {  # name: (lower bound, exclusive)
            "tolerance_mm": 0.0, "rms_tolerance_mm": 0.0, "divergence_factor": 1.0,
            "on_pressed_timeout_s": 0.0, "mark_timeout_s": 0.0,
            "rescan_timeout_s": 0.0,
        }
        for name, low in checks.items():
            object.__setattr__(self, name, check_number(f"loop setting {name}", getattr(self, name), low=low,
                                                        low_open=True))
        object.__setattr__(self, "yield_uncertainty_pct", check_yield_uncertainty(
            self.yield_uncertainty_pct, "loop setting yield_uncertainty_pct"))
        object.__setattr__(self, "mark_settle_s", check_number("loop setting mark_settle_s", self.mark_settle_s,
                                                               low=0.0, unit="s"))
        if self.on_pressed is not None and not str(self.on_pressed).strip():
            object.__setattr__(self, "on_pressed", None)
        object.__setattr__(self, "max_cycles", check_number("loop setting max_cycles", self.max_cycles, low=1,
                                                            high=MAX_CYCLES_LIMIT, integer=True))
        object.__setattr__(self, "rescans", check_number("loop setting rescans", self.rescans, low=0,
                                                         high=MAX_RESCANS, integer=True))

    def to_dict(self) -> dict:
        """JSON-ready dict (stored with the plate)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, doc: dict) -> LoopSettings:
        """Inverse of :meth:`to_dict`; unknown keys are ignored (noted on the ``mppf`` log, except the
        :data:`RETIRED_KEYS` of older histories, which are ignored silently)."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(str(k) for k in doc if k not in names and k not in RETIRED_KEYS)
        if unknown:
            _log.info("loop settings: ignoring unknown key(s) %s (written by another version of mppf)",
                      ", ".join(unknown))
        return cls(**{k: v for k, v in doc.items() if k in names})
