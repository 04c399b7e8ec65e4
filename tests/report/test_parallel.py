"""Pictures drawn partly in a helper process (mppf.report.parallel): the same files, and drawn here when it fails."""

from __future__ import annotations

import logging

import scan_helpers as sh
from mppf.report import parallel
from mppf.report.deviation import plot_deviation, plot_histogram


def _tasks(comparison, folder):
    return [(plot_deviation if i % 2 else plot_histogram, (comparison, folder / f"picture-{i}.png")) for i in range(5)]


def test_pictures_drawn_with_a_helper_are_the_bytes_drawn_here(tmp_path, caplog):
    _, _, c = sh.bump_result()
    (tmp_path / "here").mkdir()
    (tmp_path / "helped").mkdir()
    here = parallel.draw(_tasks(c, tmp_path / "here"), helper=False)
    with caplog.at_level(logging.INFO, logger="mppf"):
        helped = parallel.draw(_tasks(c, tmp_path / "helped"), helper=True)
    assert "failed" not in caplog.text  # the helper drew its share
    assert [p.name for p in helped] == [p.name for p in here] == [f"picture-{i}.png" for i in range(5)]
    for a, b in zip(here, helped):
        assert a.read_bytes() == b.read_bytes() and a.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _tagged(path, text):
    path.write_text(text)
    return path


def test_a_helper_that_cannot_run_its_tasks_leaves_them_to_this_process(tmp_path, caplog):
    # the tasks' function lives in this test module, which the helper cannot import: it fails, and
    # every task is run here all the same
    tasks = [(_tagged, (tmp_path / f"f{i}.txt", f"task {i}")) for i in range(6)]
    with caplog.at_level(logging.INFO, logger="mppf"):
        done = parallel.draw(tasks, helper=True)
    assert [p.read_text() for p in done] == [f"task {i}" for i in range(6)]
    assert "helper process failed (exit 1)" in caplog.text and "ModuleNotFoundError" in caplog.text


def test_few_pictures_or_one_thread_draw_here_only(monkeypatch, tmp_path):
    monkeypatch.setattr(parallel.subprocess, "Popen", None)  # any helper start would fail loudly
    tasks = [(_tagged, (tmp_path / f"f{i}.txt", "x")) for i in range(parallel.MIN_TASKS - 1)]
    assert len(parallel.draw(tasks)) == len(tasks)
    monkeypatch.setenv("MPPF_THREADS", "1")
    assert len(parallel.draw(tasks * 3)) == len(tasks) * 3
