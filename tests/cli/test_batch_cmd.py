"""``mppf batch`` on the command line: design files or a manifest, progress, summaries, resuming, exit codes."""

from __future__ import annotations

import csv

import pytest

from mppf.cli import main
from mppf.examples.analytic import cylinder_plate
from mppf.geometry.write import write_points
from mppf.planning.job import load_job


@pytest.fixture(scope="module")
def designs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("batch_cli")
    short, _ = cylinder_plate(2800.0, 1800.0, 9000.0, spacing_mm=150.0)
    long_design, _ = cylinder_plate(4800.0, 1800.0, 15000.0, spacing_mm=150.0)
    return write_points(folder / "short.csv", short), write_points(folder / "long.csv", long_design)


def _rows(out):
    with (out / "summary.csv").open() as f:
        return {r["plate"]: r for r in csv.DictReader(f)}


def test_batch_of_design_files_plans_resumes_and_summarises(designs, tmp_path, capsys):
    out = tmp_path / "out"
    args = ["batch", *map(str, designs), "--thickness", "20", "-o", str(out), "--jobs", "1"]
    assert main(args) == 0
    captured = capsys.readouterr()
    assert "[1/2] short: planned, 1 section(s)" in captured.err and "[2/2] long: planned, 2 section(s)" in captured.err
    assert "2 plate(s): 2 planned, 0 skipped (unchanged), 0 failed" in captured.out
    rows = _rows(out)
    assert rows["long"]["sections"] == "2" and float(rows["long"]["length_mm"]) == pytest.approx(4800.0, abs=2)
    assert len(load_job(out / "long.job.json").sections) == 2 and (out / "long.flat.csv").is_file()
    assert "<table>" in (out / "summary.html").read_text()
    assert main(args) == 0
    assert "0 planned, 2 skipped (unchanged)" in capsys.readouterr().out
    assert _rows(out)["short"]["status"] == "skipped"


def test_a_bad_plate_does_not_stop_the_batch(designs, tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("1,2,3\n")
    manifest = tmp_path / "plates.csv"
    manifest.write_text(f"name,design,thickness_mm\nbad,bad.csv,20\nshort,{designs[0]},16\n")
    out = tmp_path / "out"
    assert main(["batch", "--manifest", str(manifest), "-o", str(out), "--jobs", "2"]) == 2
    err = capsys.readouterr().err
    assert "1 of 2 plate(s) failed (bad:" in err and "what to do:" in err and "Traceback" not in err
    rows = _rows(out)
    assert rows["short"]["status"] == "planned" and rows["bad"]["status"] == "failed" and rows["bad"]["reason"]


@pytest.mark.parametrize("extra, message", [
    ([], "no plates given"),
    (["--manifest", "M.csv", "D.csv"], "either design files or --manifest"),
    (["D.csv", "--thickness", "-2"], "--thickness"),
    (["D.csv"], "thickness is missing"),
    (["--manifest", "missing.csv"], "manifest .*missing.csv does not exist"),
    (["D.csv", "--thickness", "20", "--springback"], "--springback needs the plate material"),
])
def test_bad_input_is_exit_2_with_a_message(designs, tmp_path, capsys, extra, message):
    import re

    extra = [str(designs[0]) if a == "D.csv" else str(tmp_path / a) if a.endswith(".csv") else a for a in extra]
    assert main(["batch", *extra, "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err) and "Traceback" not in err


def test_output_that_is_a_file_is_refused(designs, tmp_path, capsys):
    target = tmp_path / "file"
    target.write_text("")
    assert main(["batch", str(designs[0]), "--thickness", "20", "-o", str(target)]) == 2
    assert "is a file" in capsys.readouterr().err


def test_the_default_worker_count_is_the_cores_this_process_may_run_on(designs, tmp_path, capsys, monkeypatch):
    # a process held to one core (CPU affinity, a container's CPU set) of a machine with many: no pool of
    # os.cpu_count() workers fighting over it, the plates are planned in this process
    import os

    from mppf.planning import batch_pool

    def no_pool(*args, **kwargs):
        raise AssertionError("a process pool was started on a process that may run on one core")

    monkeypatch.setattr(os, "cpu_count", lambda: 8)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0}, raising=False)
    monkeypatch.setattr(batch_pool, "ProcessPoolExecutor", no_pool)
    assert main(["batch", str(designs[0]), "--thickness", "20", "-o", str(tmp_path / "out")]) == 0
    assert "1 plate(s): 1 planned" in capsys.readouterr().out
