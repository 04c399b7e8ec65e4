"""The per-plate report of ``mppf loop`` and ``mppf history --report``: written into the plate's work folder."""

from __future__ import annotations

import pytest
from panel_helpers import layout_job, record_loop

from mppf.cli._plate_report import write_report
from mppf.core.errors import FileFormatError


class Notes:
    """A reporter that keeps what it is told."""

    def __init__(self):
        self.lines: list[str] = []

    def info(self, message: str) -> None:
        self.lines.append(message)


def test_a_plate_not_yet_measured_gets_its_report_and_pictures_in_its_work_folder(tmp_path):
    work_dir = tmp_path / "plates" / "B12-P3"
    history = record_loop(tmp_path / "history.sqlite", layout_job(), work_dir, measured=0)
    notes = Notes()
    try:
        report = write_report(history, "B12-P3", {}, operator="A. Welder", reporter=notes)
    finally:
        history.close()
    assert report == work_dir / "report.html"
    assert {"report.html", "strokes.png", "convergence.png"} <= {p.name for p in work_dir.iterdir()}
    html = report.read_text()
    assert "B12-P3" in html and "A. Welder" in html
    assert notes.lines == []  # nothing to compare again


def test_measured_cycles_whose_design_file_is_gone_are_refused_naming_it(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the recorded design path is relative: design.csv, not here
    work_dir = tmp_path / "plates" / "B12-P3"
    history = record_loop(tmp_path / "history.sqlite", layout_job(), work_dir, measured=1)
    try:
        with pytest.raises(FileFormatError, match="design.csv"):
            write_report(history, "B12-P3", {}, operator=None, reporter=Notes())
    finally:
        history.close()
    assert not (work_dir / "report.html").exists()
