"""``mppf compare``: what was not measured in the table and the JSON, the gap options (issue 20.4)."""

from __future__ import annotations

import json

import numpy as np

import scan_helpers as sh
from mppf.cli import main
from mppf.core.transform import apply_tf
from mppf.geometry.write import write_points


def _files(tmp_path):
    """The analytic plate's design and a scan of it with a 300 mm rim band along v = 1000 not scanned."""
    rng = np.random.default_rng(5)
    u, v = rng.uniform(-1500, 1500, 6000), rng.uniform(-1000, 700, 6000)
    pts = np.column_stack([u, v, sh.height(u, v)]) + rng.normal(0.0, 0.2, (u.size, 3))
    return (write_points(tmp_path / "design.csv", sh.design()),
            write_points(tmp_path / "scan.csv", apply_tf(sh.pose(), pts)))


def test_compare_names_the_areas_not_measured_and_takes_the_gap_options(tmp_path, capsys):
    design, scan = _files(tmp_path)
    assert main(["compare", str(design), str(scan), "--json"]) == 6  # needs review (README, "Exit codes")
    doc = json.loads(capsys.readouterr().out)
    assert doc["verdict"]["kind"] == "needs_review" and doc["verdict"]["uncovered_regions"] >= 1
    cov = doc["coverage"]
    assert not cov["complete"] and cov["gap_mm"] == 100.0 and cov["max_gap_mm"] == 300.0
    assert cov["regions"][0]["on_rim"] and cov["regions"][0]["gap_mm"] > cov["allowed_gap_mm"]
    assert doc["badly_formed"] is None
    # the table says it too
    assert main(["compare", str(design), str(scan)]) == 6
    out = capsys.readouterr().out
    assert "not measured" in out and "NEEDS REVIEW" in out
    # a larger allowed gap (the shop's call) passes the band
    assert main(["compare", str(design), str(scan), "--gap", "400", "--max-gap", "400", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["coverage"]["complete"] and doc["verdict"]["kind"] == "in_tolerance"


def test_bad_gap_options_exit_2(tmp_path, capsys):
    design, scan = _files(tmp_path)
    assert main(["compare", str(design), str(scan), "--gap", "0"]) == 2
    assert "allowed gap" in capsys.readouterr().err
    assert main(["compare", str(design), str(scan), "--gap", "200", "--max-gap", "100"]) == 2
    assert "largest allowed gap" in capsys.readouterr().err
