"""``mppf demo``: the whole chain on a bundled hull plate, into a folder."""

from __future__ import annotations

import sqlite3

import ezdxf
import pytest

from mppf.cli import main
from mppf.loop.history import History


@pytest.mark.slow  # the whole mppf demo: a minute of simulation (several cycles over loopback Modbus)
def test_demo_runs_end_to_end_with_pictures_and_summary(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--seed", "2"]) == 0
    text = capsys.readouterr().out
    # formed to tolerance (form max and RMS): "in_tolerance", or "needs_review" when scanner artefacts set
    # aside lie beyond the tolerance (a person checks them; the plate is never passed over them)
    status = "in_tolerance" if "in_tolerance" in text else "needs_review"
    assert status in text and "simulated PLC" in text and "report.html" in text
    # the flat for the cutter, as ezdxf reads it: cut and net outlines and the mark on their layers
    drawing = ezdxf.readfile(out / "P1_midbody_bilge_smooth.flat.dxf")
    assert {e.dxf.layer for e in drawing.modelspace()} >= {"CUT", "NET", "MARK"}
    for name in ("strain.png", "strokes.png", "deviation-cycle-1.png", "convergence.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    report = (out / "report.html").read_text()
    assert report.count("data:image/png;base64,") >= 4 and status in report
    with History(out / "history.sqlite") as history:
        (plate,) = history.plates()
        cycles = history.cycles(plate.plate_id)
    assert plate.status == status == cycles[-1].decision and cycles[-1].max_abs_mm <= 2.5 and cycles[-1].rms_mm <= 1.0
    if status == "needs_review":
        assert cycles[-1].comparison["set_aside"]["beyond_tolerance"] > 0
    for c in cycles:
        assert (out / f"deviation-cycle-{c.cycle}.png").exists() and (out / f"punch-deviation-cycle-{c.cycle}.png").exists()
    # the press was driven over Modbus: one GO per step in the audit log
    (gos,) = sqlite3.connect(out / "audit.sqlite").execute(
        "SELECT COUNT(*) FROM audit WHERE action = 'go' AND outcome = 'ok'").fetchone()
    assert gos == sum(len(c.steps) for c in cycles)


def test_demo_with_an_unknown_plate_exits_2(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path / "d"), "--plate", "nope"]) == 2
    err = capsys.readouterr().err
    assert "no bundled plate named 'nope'" in err and "K1_midbody_bilge" in err
