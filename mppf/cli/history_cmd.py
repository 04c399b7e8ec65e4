"""``mppf history``: the plates of the history and their press cycles (thin over :mod:`mppf.loop.history`)."""

from __future__ import annotations

from pathlib import Path

import click

from mppf.cli._common import console, esc, print_json
from mppf.cli._cycles import cycle_table
from mppf.core.errors import InputError

history_option = click.option(
    "--history", "history_path", type=click.Path(dir_okay=False, path_type=Path),
    help="History database [default: $MPPF_HOME/history.sqlite or ~/.local/share/mppf/].",
)


def open_history(path):
    """The plate history at ``path`` (None: the default one)."""
    from mppf.loop.history import History

    return History(path)


@click.command("history")
@history_option
@click.option("--plate-id", help="Show this plate's cycles only.")
@click.option("--json", "as_json", is_flag=True, help="Print as JSON (with strokes and deviation grids).")
@click.option("--report", "report_plate", metavar="PLATE",
              help="Write this plate's pictures and report.html into its work folder (scans compared again).")
@click.option("--operator", help="With --report: who ran the plate (printed in the report).")
def history(history_path, plate_id, as_json, report_plate, operator):
    """List the plates of the history and their press cycles, or write a plate's report (--report PLATE)."""
    if history_path is not None and not history_path.exists():
        raise InputError(f"history {history_path} does not exist", hint="check the path given with --history")
    if report_plate is not None:
        _report(history_path, report_plate, operator)
        return
    with open_history(history_path) as hist:
        plates = [hist.plate(plate_id)] if plate_id else hist.plates()
        if as_json:
            print_json({"history": str(hist.path), "plates": [
                {**p.to_dict(), "cycles": [c.to_dict() for c in hist.cycles(p.plate_id)]} for p in plates]})
            return
        if not plates:
            console.print(f"no plates in {hist.path}", markup=False)
            return
        console.print(_plates_table(hist, plates))
        if plate_id:
            console.print(cycle_table(hist.cycles(plate_id), f"cycles of {esc(plate_id)}"))


def _report(history_path, plate_id: str, operator: str | None) -> None:
    from mppf.cli._common import RichReporter
    from mppf.cli._plate_report import write_report

    reporter = RichReporter()
    with open_history(history_path) as hist:
        plate = hist.plate(plate_id)  # InputError naming the plates for an unknown id
        if not hist.cycles(plate.plate_id):
            raise InputError(f"plate {plate_id} has no cycles recorded: there is nothing to report",
                             hint="run the plate with 'mppf loop' first")
        try:
            path = write_report(hist, plate.plate_id, {}, operator=operator, reporter=reporter)
        finally:
            reporter.finish()
    console.print(f"report of plate {esc(plate.plate_id)}: {esc(str(path))}")


def _plates_table(hist, plates):
    """The title line, the table of plates and the legend line (as plain lines: a table's title and caption
    would be wrapped to the table's width, in logs too)."""
    from rich.console import Group
    from rich.table import Table
    from rich.text import Text

    table = Table()
    for name in ("plate", "status", "cycles", "form max", "RMS", "t", "updated (UTC)"):
        table.add_column(name, no_wrap=name == "status", overflow="fold", min_width=5 if name != "t" else 2)
    for p in plates:
        cycles = hist.cycles(p.plate_id)
        done = [c for c in cycles if c.max_abs_mm is not None]
        table.add_row(esc(p.plate_id), p.status, str(len(cycles)),
                      f"{done[-1].max_abs_mm:.2f}" if done else "-", f"{done[-1].rms_mm:.2f}" if done else "-",
                      f"{p.thickness_mm:g}", p.updated_utc[:16].replace("T", " "))
    legend = "form max, RMS: deviations (mm) of the last measured cycle; t: thickness (mm)"
    return Group(Text.from_markup(f"plates in {esc(str(hist.path))}"), table, Text(legend))


COMMANDS = [history]
