"""``mppf tryout``: bad settings and files exit 2 with one message, before CalculiX runs and before anything is written.

The try-out itself (the first cycle on the FE plate) needs minutes of CalculiX: tests/sim/ covers the FE plate.
"""

from __future__ import annotations

import pytest

from mppf.cli import main
from mppf.planning.job import save_job


@pytest.fixture
def job_files(tmp_path, planned_plate, plate_files):
    _, _, _, job = planned_plate
    design, flat = plate_files
    return save_job(job, tmp_path / "cycle-01.job.json"), design, flat


@pytest.mark.parametrize(("option", "value"), [("--seed", "-1"), ("--layers", "0"), ("--layers", "9"),
                                               ("--cells-per-pitch", "9")])
def test_a_setting_out_of_range_exits_2_naming_the_option(job_files, tmp_path, capsys, option, value):
    job, design, flat = job_files
    out = tmp_path / "tryout"
    code = main(["tryout", str(job), "--design", str(design), "--flat", str(flat), "-o", str(out), option, value])
    err = capsys.readouterr().err
    assert code == 2 and option in err and "Traceback" not in err
    assert not out.exists()


def test_a_missing_job_file_exits_2_and_writes_nothing(job_files, tmp_path, capsys):
    _, design, flat = job_files
    out = tmp_path / "tryout"
    code = main(["tryout", str(tmp_path / "no.job.json"), "--design", str(design), "--flat", str(flat), "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error:") and "Traceback" not in err
    assert not out.exists()


def test_a_missing_flat_file_exits_2_and_writes_nothing(job_files, tmp_path, capsys):
    job, design, _ = job_files
    out = tmp_path / "tryout"
    code = main(["tryout", str(job), "--design", str(design), "--flat", str(tmp_path / "no_flat.csv"), "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert ("no_flat.csv" in err) if _has_ccx() else ("ccx" in err.lower())  # CalculiX is looked for first
    assert not out.exists()


def _has_ccx() -> bool:
    from mppf.sim.fe.ccx import find_ccx

    from mppf.core.errors import MppfError

    try:
        find_ccx()
    except MppfError:
        return False
    return True
