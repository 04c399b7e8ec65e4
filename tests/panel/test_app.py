"""Where the panel finds the PLC to watch: --plc, else the running master's, else the one recorded with the plate."""

from __future__ import annotations

from panel_helpers import layout_job

from mppf.loop.history import History
from mppf.loop.options import PlateFiles
from mppf.panel.app import locator
from mppf.panel.config import PanelConfig
from mppf.panel.sources import PlcTarget
from mppf.planning.job import save_job

RECORDED = "tcp://10.0.0.5:502?unit=1"


def _history(tmp_path, plc: str | None):
    job = layout_job()
    path = tmp_path / "history.sqlite"
    with History(path) as history:
        history.create_plate("B12-P3", PlateFiles("design.csv", "0" * 64, "flat.csv", "1" * 64),
                             thickness_mm=job.thickness_mm, press=job.press.to_dict(),
                             settings={"loop": {}, "work_dir": str(tmp_path), "plc": plc})
        history.add_cycle("B12-P3", 1, job_path=save_job(job, tmp_path / "cycle-01.job.json"),
                          job_sha256=job.sha256(), steps=job.steps)
    return path


def _config(tmp_path, history_path, plc_url=None):
    return PanelConfig(history_path=history_path, audit_path=tmp_path / "audit.sqlite", plc_url=plc_url)


def test_the_plc_given_with_plc_is_watched_whatever_the_history_says(tmp_path):
    locate = locator(_config(tmp_path, _history(tmp_path, RECORDED), plc_url="tcp://127.0.0.1:1502"))
    assert locate() == PlcTarget("tcp://127.0.0.1:1502", "given with --plc")


def test_without_plc_and_without_a_running_master_the_plates_recorded_plc_is_watched(tmp_path):
    locate = locator(_config(tmp_path, _history(tmp_path, RECORDED)))
    assert locate() == PlcTarget(RECORDED, "recorded with plate B12-P3")


def test_a_plate_pressed_in_a_dry_run_and_no_master_leave_no_plc_to_watch(tmp_path):
    assert locator(_config(tmp_path, _history(tmp_path, None)))() is None
    assert locator(_config(tmp_path, tmp_path / "empty-history.sqlite"))() is None
