"""The report of one production plate: the pictures and ``report.html`` in the plate's work folder.

``mppf loop`` writes it after its loop (on by default, ``--no-report`` to skip) and ``mppf
history --report PLATE`` writes it afterwards, from the history and the recorded scans. It is
the demo's report (:func:`mppf.report.convergence.loop_report`) with what a production record
needs: when it was made, the operator, the press, the plate id and every cycle's job SHA-256;
pages print on A4 without orphaned headings (the print CSS of :mod:`mppf.report.html`), and
the punch maps carry their values.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from mppf.loop.records import CycleRecord, PlateRecord


@dataclass(frozen=True)
class Signature:
    """Who made a plate's record, on which press, when.

    Attributes
    ----------
    operator, press_name : str, optional
        Who ran the plate and on which press (printed as given; default: "not given", the
        plate's press).
    made_utc : datetime, optional
        When the report is made (default: now).
    """

    operator: str | None = None
    press_name: str | None = None
    made_utc: datetime | None = None


def write_plate_report(out_dir, plate: PlateRecord, cycles: Sequence[CycleRecord], comparisons: Mapping[int, object],
                       job, *, tolerance_mm: float, rms_tolerance_mm: float,
                       signed: Signature = Signature()) -> list[Path]:
    """Write the pictures and ``report.html`` of a plate into ``out_dir``; return the files written.

    Parameters
    ----------
    out_dir : path
        The plate's work folder (made if missing).
    plate : PlateRecord
    cycles : sequence of CycleRecord
        Every cycle of the plate, in order.
    comparisons : mapping cycle -> Comparison
        The comparisons of the measured cycles (cycles without one get no deviation pictures).
    job : Job
        The first cycle's job (its strokes picture).
    tolerance_mm, rms_tolerance_mm : float
        The loop's limits.
    signed : Signature
        The operator, the press and when the report is made.

    Returns
    -------
    list of Path
        The strokes picture, each measured cycle's deviation map and punch map, the
        convergence chart and ``report.html``.
    """
    from mppf.report.convergence import draw_pictures, loop_report
    from mppf.report.strokes import plot_strokes

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    made = signed.made_utc or datetime.now(UTC)
    limits = {"tolerance_mm": tolerance_mm, "rms_tolerance_mm": rms_tolerance_mm}
    files, cycle_pictures = draw_pictures(
        [(plot_strokes, (job, out / "strokes.png"))], comparisons, job, out, cycles, limits,
        lambda n: (f"plate {plate.plate_id}, cycle {n}: deviation of the scan from the design",
                   f"cycle {n}: deviation at the punches (mm)"))
    details = [("report made (UTC)", made.strftime("%Y-%m-%d %H:%M:%S")),
               ("operator", signed.operator or "(not given: --operator)"),
               ("press", signed.press_name or str(plate.press.get("name", "press"))),
               *[(f"job of cycle {c.cycle} (SHA-256)", c.job_sha256) for c in cycles]]
    page = loop_report(plate, cycles, **limits, cycle_pictures=cycle_pictures, details=details,
                       pictures=[("strokes of the first cycle's last step", (out / "strokes.png").read_bytes())],
                       intro=f"Production record of plate {plate.plate_id}.")
    report = out / "report.html"
    report.write_text(page)
    files.append(report)
    return files
