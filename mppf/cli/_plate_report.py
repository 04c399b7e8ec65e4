"""The per-plate report of ``mppf loop`` (on by default) and ``mppf history --report PLATE``."""

from __future__ import annotations

from pathlib import Path


def write_report(history, plate_id: str, comparisons: dict, *, operator: str | None, reporter) -> Path:
    """Write the plate's pictures and ``report.html`` into its work folder; return the report's path.

    ``comparisons`` holds the comparisons made in this process (cycle -> Comparison); those
    of the other measured cycles are made again from their recorded scans (nothing is recorded).
    """
    from mppf.loop.measuring import compare_recorded, read_checked
    from mppf.loop.settings import LoopSettings
    from mppf.planning.job import load_job
    from mppf.report.plate_report import Signature, write_plate_report

    plate = history.plate(plate_id)
    cycles = history.cycles(plate_id)
    settings = LoopSettings.from_dict(plate.settings["loop"])
    comparisons = dict(comparisons)
    missing = [c for c in cycles if c.cycle not in comparisons and c.scan_path and c.rms_mm is not None]
    if missing:
        design = read_checked(plate.design_path, plate.design_sha256, "design", plate.settings.get("units", "mm"))
        for c in missing:
            if Path(c.scan_path).exists():
                reporter.info(f"report of plate {plate_id}: comparing the scan of cycle {c.cycle} again")
                comparisons[c.cycle] = compare_recorded(plate, c, design, settings)
    out = Path(plate.settings["work_dir"])
    files = write_plate_report(out, plate, cycles, comparisons, load_job(cycles[0].job_path, require_seal=False),
                               tolerance_mm=settings.tolerance_mm, rms_tolerance_mm=settings.rms_tolerance_mm,
                               signed=Signature(operator, str(plate.press.get("name", "press"))))
    return files[-1]
