"""mppf.core helpers of the command line's robustness: plain progress lines, markup escaping, safe names, transactions."""

from __future__ import annotations

import re
import sqlite3
import threading
import time

import pytest
from rich.console import Console
from rich.markup import escape

from mppf.core.db import Transaction, open_sqlite
from mppf.core.errors import InputError
from mppf.core.markup import escape_markup
from mppf.core.progress import LineReporter
from mppf.core.validate import check_name, safe_name

STAMP = re.compile(r"^\d\d:\d\d:\d\d ")


class Lines:
    def __init__(self):
        self.lines: list[str] = []
        self._lock = threading.Lock()

    def __call__(self, line: str) -> None:
        with self._lock:
            self.lines.append(line)


def test_line_reporter_prints_timestamped_start_progress_and_end_lines():
    out = Lines()
    reporter = LineReporter(out, interval_s=0.0)
    reporter.start("motion", total=4)
    for _ in range(4):
        reporter.advance()
    reporter.finish()
    reporter.close()
    assert all(STAMP.match(line) for line in out.lines)
    assert out.lines[0].endswith("motion: started (4 to do)") and "motion: done in" in out.lines[-1]
    assert any("motion: 4/4 (100 %)" in line for line in out.lines)


def test_line_reporter_beats_during_silent_work_and_stops_when_closed():
    out = Lines()
    reporter = LineReporter(out, interval_s=0.1)
    reporter.info("comparing the scan")  # a step without progress of its own
    time.sleep(0.55)
    reporter.close()
    beats = [line for line in out.lines if "still working" in line and "comparing the scan" in line]
    assert len(beats) >= 3  # one per interval of silence
    time.sleep(0.25)
    assert len(out.lines) == 1 + len(beats)  # closed: no more lines


def test_line_reporter_heartbeat_of_a_task_without_advances():
    out = Lines()
    reporter = LineReporter(out, interval_s=0.1)
    reporter.start("waiting for the scan")
    time.sleep(0.35)
    reporter.finish()
    reporter.close()
    assert sum("waiting for the scan: working" in line for line in out.lines) >= 2


@pytest.mark.parametrize("text", ["B12[/]P3", "P3[rev2].csv", "MPP [/] press", "[bold]x[/bold]", "a\\[b]",
                                  "plain", "[/", "[@click]"])
def test_escape_markup_matches_rich_and_prints_the_text_unchanged(text):
    assert escape_markup(text) == escape(text)
    console = Console(width=200, record=True, color_system=None)
    console.print(escape_markup(text))
    assert console.export_text().rstrip("\n") == text


@pytest.mark.parametrize("name", ["B12-P3", "K2_fwd.2", "a" * 64, "0"])
def test_safe_names_pass(name):
    assert check_name("plate id", name) == name


@pytest.mark.parametrize("name", ["", "../x", "a/b", "a\\b", ".x", "-x", "a" * 65, "B12[/]P3", "a b", "x..y", None,
                                  7, "é"])
def test_unsafe_names_are_refused_naming_the_value(name):
    with pytest.raises(InputError, match="plate id") as refused:
        check_name("plate id", name)
    assert repr(name) in refused.value.message and refused.value.hint


def test_safe_name_makes_a_name_check_name_takes():
    for text in ("P3[rev2]", "../../x", "B12 P3", "", "...", "é"):
        assert check_name("id", safe_name(text)) == safe_name(text)
    assert safe_name("P3[rev2]") == "P3_rev2_"


def test_transaction_commits_rolls_back_and_nests(tmp_path):
    db = open_sqlite(tmp_path / "t.sqlite", "the test db", "CREATE TABLE IF NOT EXISTS t (x);", 1, hint="")
    with Transaction(db, "the test db"):
        db.execute("INSERT INTO t VALUES (1)")
        with Transaction(db, "the test db"):  # joins the outer one
            db.execute("INSERT INTO t VALUES (2)")
    with pytest.raises(ZeroDivisionError), Transaction(db, "the test db"):
        db.execute("INSERT INTO t VALUES (3)")
        raise ZeroDivisionError
    assert [r[0] for r in db.execute("SELECT x FROM t")] == [1, 2]
    db.close()


def test_a_full_database_is_an_input_error_and_nothing_of_the_block_is_kept(tmp_path):
    db = open_sqlite(tmp_path / "full.sqlite", "the test db", "CREATE TABLE IF NOT EXISTS t (x);", 1, hint="")
    db.execute("PRAGMA max_page_count = %d" % db.execute("PRAGMA page_count").fetchone()[0])
    with pytest.raises(InputError, match=r"cannot write the test db: the disk is full") as full:
        with Transaction(db, "the test db", hint="free some space"):
            db.execute("INSERT INTO t VALUES ('small')")
            db.execute("INSERT INTO t VALUES (?)", ("x" * 100_000,))
    assert full.value.hint == "free some space"
    assert db.execute("SELECT COUNT(*) FROM t").fetchone()[0] == 0 and not db.in_transaction
    db.close()


def test_a_read_only_database_is_an_input_error(tmp_path):
    path = tmp_path / "ro.sqlite"
    open_sqlite(path, "the test db", "CREATE TABLE IF NOT EXISTS t (x);", 1, hint="").close()
    db = sqlite3.connect(f"file:{path}?mode=ro", uri=True, isolation_level=None)
    with pytest.raises(InputError, match="read-only"), Transaction(db, "the test db"):
        db.execute("INSERT INTO t VALUES (1)")
    db.close()


def test_line_reporter_keeps_beating_after_a_task_until_closed():
    out = Lines()
    reporter = LineReporter(out, interval_s=0.1)
    reporter.start("motion")
    reporter.finish()
    time.sleep(0.35)  # e.g. the compare after the motion, which reports nothing itself
    reporter.close()
    assert any("still working" in line and "since: motion done" in line for line in out.lines)
