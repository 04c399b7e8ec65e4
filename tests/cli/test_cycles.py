"""How the loop commands show cycles: the table from a real plate history, and the line after each compare."""

from __future__ import annotations

import dataclasses

from panel_helpers import layout_job, record_loop
from rich.console import Console
from rich.markup import escape

from mppf.cli._cycles import cycle_table, print_cycle


def _cycles(tmp_path, measured: int = 2):
    history = record_loop(tmp_path / "history.sqlite", layout_job(), tmp_path / "plate", plate_id="B12-P3",
                          measured=measured)
    try:
        return history.cycles("B12-P3")
    finally:
        history.close()


def _render(renderable) -> list[str]:
    console = Console(width=140, record=True, color_system=None)
    console.print(renderable)
    return console.export_text().splitlines()


def test_one_row_per_cycle_with_its_figures_and_dashes_where_nothing_is_measured(tmp_path):
    cycles = _cycles(tmp_path, measured=2)
    lines = _render(cycle_table(cycles, f"[bold]plate[/] {escape('B12-P3 [x]')}"))
    assert lines[0] == "plate B12-P3 [x]"  # the title is markup: escaped user text is printed as it is
    assert lines[-1].startswith("deviations in mm; within% = share of the scan")
    rows = [line for line in lines if line.lstrip("│ ").split(" ")[0].isdigit()]
    assert len(rows) == 3  # two measured cycles and the planned third
    first = rows[0]
    assert f"{cycles[0].max_abs_mm:.2f}" in first and f"{cycles[0].rms_mm:.2f}" in first and "40.0" in first
    assert "continue" in first
    planned = rows[2].split("│")
    assert [cell.strip() for cell in planned[4:8]] == ["-", "-", "-", "0.80"]  # not measured yet; its gain


def test_an_interrupted_cycle_says_so(tmp_path):
    cycles = _cycles(tmp_path, measured=1)
    interrupted = dataclasses.replace(cycles[-1], interrupted=True)
    lines = _render(cycle_table([interrupted], "t"))
    assert any("(interrupted)" in line for line in lines)


def test_the_line_after_a_compare_names_cycle_deviations_and_decision(tmp_path, capsys):
    cycles = _cycles(tmp_path, measured=1)
    print_cycle(dataclasses.replace(cycles[0], state="compared"), None)
    err = capsys.readouterr().err
    assert f"cycle 1: form max {cycles[0].max_abs_mm:.2f} mm, RMS {cycles[0].rms_mm:.2f} mm" in err
    assert "40.0 % within tolerance -> continue" in err
