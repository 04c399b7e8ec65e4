"""The bad-input corpus: what a new user gets wrong, over every command and file kind, answered cleanly.

Each case is data (:data:`CASES`): a command line (``{name}`` fields are files of the case,
``{tmp}`` its folder, ``{design}`` ``{flat}`` ``{press}`` ``{job}`` ``{history}`` good inputs)
and the words the one error message must hold (the file or option and the value seen). Every
case is run in-process through :func:`mppf.cli.main` and must give: exit 2, one
``error:`` message with those words and a hint, no traceback, no connection to a PLC (every
socket connect fails the case), and the plate already in the history untouched.
A handful run again through a real ``python -m mppf``.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import sqlite3
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mppf.cli import main
from mppf.core.errors import EXIT_INPUT
from mppf.loop.history import History
from mppf.loop.options import PlateFiles
from mppf.model.press import example_press_path

from test_bad_inputs_corpus import CASES, FILES  # the corpus (data), beside this file
from test_bad_inputs_issue38 import CASES38, FILES38  # issue 38's cases: sealed jobs, the machine's press, ...

CASES = CASES + CASES38
FILES = {**FILES, **FILES38}


@pytest.fixture(scope="session")
def good_inputs(tmp_path_factory) -> dict[str, str]:
    """Good files the cases lean on: a small curved plate (1.2 x 0.9 m), its flat, the press, a job, a history.

    Small on purpose: unfolded and planned in well under a second, so the corpus stays fast.
    """
    from mppf.geometry.unfold import unfold
    from mppf.geometry.write import write_points
    from mppf.model.press import load_press
    from mppf.planning.job import save_job
    from mppf.planning.plan import plan_job

    folder = tmp_path_factory.mktemp("good")
    x, y = np.meshgrid(np.linspace(-600.0, 600.0, 25), np.linspace(-450.0, 450.0, 19))
    points = np.column_stack([x.ravel(), y.ravel(), (x**2 / 16000.0 + y**2 / 40000.0).ravel()])
    design = write_points(folder / "design.csv", points)
    flat = write_points(folder / "flat.csv", unfold(points).flat)
    press = load_press(example_press_path())
    job = save_job(plan_job(points, np.loadtxt(flat, delimiter=",", comments="#"), press, 20.0),
                   folder / "good.job.json")
    sectional = save_job(_sectional_plan(press), folder / "sectional.job.json")
    history = folder / "history.sqlite"
    with History(history) as hist:
        hist.create_plate("KEEP-1", PlateFiles(design, "0" * 64, flat, "0" * 64), thickness_mm=20.0,
                          press=press.to_dict(), settings={"loop": {}})
        hist.add_cycle("KEEP-1", 1, job_path=job, job_sha256="0" * 64, steps=[])
    return {"design": str(design), "flat": str(flat), "press": str(example_press_path()), "job": str(job),
            "sectional_job": str(sectional), "history_template": str(history)}


def _sectional_plan(press):
    """A plate larger than the bed (7.5 x 2.4 m cylinder): 6 sections on the example press."""
    from mppf.examples.analytic import cylinder_plate
    from mppf.planning.sectional import plan_plate

    design, flat = cylinder_plate(7500.0, 2400.0, 20000.0)
    job = plan_plate(design, flat, press, 20.0)
    assert len(job.sections) == 6
    return job


def _snapshot(db: Path) -> list:
    with sqlite3.connect(db) as con:
        return con.execute("SELECT plate_id, status, (SELECT COUNT(*) FROM cycles c WHERE c.plate_id = p.plate_id) "
                           "FROM plates p ORDER BY plate_id").fetchall()


def _materialise(case: dict, tmp_path: Path, good: dict) -> list[str]:
    """The case's files written into ``tmp_path``; its command line with every field filled in."""
    fields = {**good, "tmp": str(tmp_path), "history": str(tmp_path / "history.sqlite")}
    shutil.copy(good["history_template"], fields["history"])
    for key in case.get("files", ()):
        name, content = FILES[key]
        path = tmp_path / name
        if isinstance(content, bytes):
            path.write_bytes(content)
        elif callable(content):
            content(path, good)
        elif content is not None:  # None: the file is missing
            path.write_text(content)
        fields[key] = str(path)
    return [arg.format(**fields) for arg in case["args"]]


@pytest.fixture()
def no_plc(monkeypatch):
    """Any connection to a PLC fails the case (no case may reach a press)."""
    def refuse(self, address):
        raise AssertionError(f"a bad-input case connected to {address}")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr("mppf.sim.plc.host.run_simulated_plc", lambda *a, **k: pytest.fail("a PLC was started"))


def _audited(audit: Path) -> list[str]:
    from mppf.drivers.audit import AuditLog

    with AuditLog(audit) as log:
        return [e.action for e in log.entries()]


@pytest.mark.parametrize("case", CASES, ids=[c["id"] for c in CASES])
def test_bad_input_is_answered_with_exit_2_and_one_clear_message(case, tmp_path, good_inputs, request, capsys,
                                                                monkeypatch):
    monkeypatch.setenv("MPPF_HOME", str(tmp_path / "home"))  # no press installed: dry runs use the example press
    args = _materialise(case, tmp_path, good_inputs)
    if case.get("dry_run"):  # the job validator runs against the (simulated) PLC: nothing may be written
        args += ["--audit", str(tmp_path / "audit.sqlite")]
    else:
        request.getfixturevalue("no_plc")
    before = _snapshot(tmp_path / "history.sqlite")
    code = main(args)
    out, err = capsys.readouterr()
    text = " ".join(err.split())
    assert code == case.get("exit", EXIT_INPUT), f"exit {code}: {text}"
    assert "Traceback" not in err and "internal error" not in err, text
    assert text.count("error:") + text.count("Error:") == 1, text  # one message
    assert "what to do:" in text or "Try 'mppf" in text, text  # and a hint
    for words in case["expect"]:
        assert words in text, f"{words!r} missing from: {text}"
    if "--json" in args:
        assert json.loads(err.strip().splitlines()[-1])["error"]["exit_code"] == code
    assert _snapshot(tmp_path / "history.sqlite") == before  # nothing recorded lost (or added)
    if case.get("dry_run"):
        assert {"upload", "go"}.isdisjoint(_audited(tmp_path / "audit.sqlite")), "a job was written to the PLC"
    assert not list(tmp_path.glob("plates/*")), "a plate folder was made"


SUBPROCESS_CASES = ["plate id with path traversal", "plate id with markup", "truncated binary STL -> fit",
                    "issue 38: pair_up_2 -> press --plc", "issue 38: section2_centre_1000 -> press (dry run)",
                    "issue 38: a space in the PLC host -> press"]


@pytest.mark.parametrize("case_id", SUBPROCESS_CASES)
def test_bad_input_through_a_real_process(case_id, tmp_path, good_inputs):
    case = next(c for c in CASES if c["id"] == case_id)
    args = _materialise(case, tmp_path, good_inputs)
    proc = subprocess.run([sys.executable, "-m", "mppf", *args], capture_output=True, text=True, timeout=120,
                          env={"MPPF_HOME": str(tmp_path / "home"), "PATH": "/usr/bin:/bin", "COLUMNS": "80",
                               "MPPF_SEAL_KEY": os.environ["MPPF_SEAL_KEY"]})  # the key the good jobs were sealed with
    text = " ".join(proc.stderr.split())
    assert proc.returncode == EXIT_INPUT, text
    assert "Traceback" not in proc.stderr and text.startswith("error:"), text
    for words in case["expect"]:
        assert words in text, f"{words!r} missing from: {text}"
    for words in case["expect"]:
        assert words in text
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 2  # no hard wrapping in a pipe: the message and its hint, one line each


def test_the_corpus_covers_every_command_and_file_kind():
    commands = {c["args"][0] for c in CASES}
    assert {"fit", "unfold", "plan", "loop", "press", "status", "stop", "reset", "sim", "history", "extract",
            "demo"} <= commands
    kinds = {c["kind"] for c in CASES}
    assert {"points", "mesh", "press", "job", "plc", "option", "scan folder", "plate id"} <= kinds
    assert len(CASES) >= 200


def test_markup_in_a_file_name_is_printed_as_it_is(tmp_path, capsys):
    path = tmp_path / "P3[rev2].csv"
    assert main(["unfold", str(path), "-o", str(tmp_path / "flat.csv")]) == EXIT_INPUT
    assert "P3[rev2].csv: file not found" in capsys.readouterr().err


def test_a_plate_in_metres_read_as_mm_is_refused_naming_the_file_and_units(tmp_path, hull_dir, capsys):
    points = np.loadtxt(hull_dir / "K2_fwd_bilge_convex.csv", delimiter=",", comments="#") / 1000.0
    path = tmp_path / "in-metres.csv"
    np.savetxt(path, points, delimiter=",")
    for args in (["fit", str(path), "--json"], ["unfold", str(path), "-o", str(tmp_path / "flat.csv")],
                 ["plan", str(path), str(path), "--thickness", "20"]):
        assert main(args) == 2
        err = " ".join(capsys.readouterr().err.split())
        assert "in-metres.csv: the plate is only 2.98 mm across (--units mm)" in err and "--units m" in err, err
    assert main(["fit", str(path), "--units", "m"]) == 0  # read in metres: a plate of 2.98 m


def test_a_whole_binary_stl_whose_header_says_solid_is_read(tmp_path):
    from mppf.geometry.read import read_points

    triangle = struct.pack("<12fH", 0, 0, 1, 0, 0, 0, 100, 0, 0, 0, 100, 0, 0)
    path = tmp_path / "solid-header.stl"
    path.write_bytes(b"solid exported by a CAD program".ljust(80, b" ") + struct.pack("<I", 1) + triangle)
    assert read_points(path).n_points == 3


def test_progress_in_a_pipe_is_plain_timestamped_lines(good_inputs, tmp_path, capsys):
    code = main(["plan", good_inputs["design"], good_inputs["flat"], "--thickness", "20", "-o",
                 str(tmp_path / "job.json")])
    err = capsys.readouterr().err
    assert code == 0, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert lines and all(re.match(r"^\d\d:\d\d:\d\d \S", line) for line in lines), err
    assert "\x1b[" not in err and "━" not in err  # no colours, no bars


def test_a_design_too_large_to_unfold_is_refused_before_the_work(tmp_path, monkeypatch, good_inputs, capsys):
    monkeypatch.setattr("mppf.cli._common.DESIGN_MAX_POINTS", 100)  # the good design has 475 points
    for args in (["unfold", good_inputs["design"], "-o", str(tmp_path / "flat.csv")],
                 ["plan", good_inputs["design"], good_inputs["flat"], "--thickness", "20"]):
        assert main(args) == EXIT_INPUT
        err = " ".join(capsys.readouterr().err.split())
        assert "design.csv has 475 points; a design may have at most 100" in err and "what to do:" in err
    assert not (tmp_path / "flat.csv").exists()
