"""How the loop commands show cycles: the cycle table and the line after each compare."""

from __future__ import annotations

from mppf.cli._common import err_console


def cycle_table(cycles, title: str):
    """One row per cycle: state, steps, deviations, share within tolerance, gain, decision.

    A rich renderable: the title line (rich markup, user text escaped), the table, the legend line. Title and legend are
    plain lines of their own (a table's title and caption would be wrapped to the table's
    width, in logs too).
    """
    from rich.console import Group
    from rich.table import Table
    from rich.text import Text

    table = Table()
    for name, justify in (("cycle", "right"), ("state", "left"), ("steps", "right"), ("form max", "right"),
                          ("RMS", "right"), ("within%", "right"), ("gain", "right"), ("decision", "left")):
        table.add_column(name, justify=justify, no_wrap=True)
    for c in cycles:
        table.add_row(
            str(c.cycle), c.state + (" (interrupted)" if c.interrupted else ""),
            f"{c.steps_done}/{len(c.steps)}",
            "-" if c.max_abs_mm is None else f"{c.max_abs_mm:.2f}",
            "-" if c.rms_mm is None else f"{c.rms_mm:.2f}",
            "-" if c.within_pct is None else f"{c.within_pct:.1f}",
            "-" if c.gain is None else f"{c.gain:.2f}",
            c.decision or "-",
        )
    legend = "deviations in mm; within% = share of the scan within the tolerance; gain = mean correction gain of the strokes"
    return Group(Text.from_markup(title), table, Text(legend))


def print_cycle(record, comparison) -> None:
    """The line printed after each compare while the loop runs (an ``on_cycle`` callback)."""
    if record.state == "compared":
        err_console.print(
            f"[bold]cycle {record.cycle}[/]: form max {record.max_abs_mm:.2f} mm, RMS {record.rms_mm:.2f} mm, "
            f"{record.within_pct:.1f} % within tolerance -> [bold]{record.decision}[/]"
        )
