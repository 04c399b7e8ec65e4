"""How the command line drives a press: the dry run, the question before motion, SIGTERM and SIGHUP as Ctrl-C."""

from __future__ import annotations

import os
import signal
import threading

import pytest

from mppf.cli.press_policy import (
    HungUp,
    confirm_motion,
    press_description,
    press_link,
    reset_question,
    sigterm_as_ctrl_c,
)
from mppf.core.errors import Cancelled, PressRefused
from mppf.core.progress import NULL_REPORTER
from mppf.model.press import example_press_path, load_press


class Notes:
    """A reporter that keeps what it is told."""

    def __init__(self):
        self.lines: list[str] = []

    def __getattr__(self, name):
        return getattr(NULL_REPORTER, name)

    def info(self, message: str) -> None:
        self.lines.append(message)


@pytest.fixture(scope="module")
def press():
    return load_press(example_press_path())


def test_without_a_plc_the_link_is_a_dry_run_on_the_simulated_plc_in_this_process(press, tmp_path):
    notes = Notes()
    with press_link(press, None, reporter=notes) as link:
        url = str(link.url)
        assert url.startswith("tcp://127.0.0.1:")
        described = press_description(link)
        assert (link.identity.rows, link.identity.cols) == (press.rows, press.cols)
    assert described == f"the press at {url} ({press.rows} x {press.cols} punches)"
    assert len(notes.lines) == 1 and notes.lines[0].startswith("DRY RUN against the simulated PLC at ")
    assert "no press moves" in notes.lines[0]


def test_motion_is_refused_without_a_terminal_and_allowed_with_yes(press):
    with press_link(press, None) as link:
        confirm_motion(link, "job K3 (2 steps)", yes=True)  # --yes: no question
        with pytest.raises(PressRefused) as caught:  # pytest's stdin is no terminal
            confirm_motion(link, "job K3 (2 steps)", yes=False)
    assert "job K3 (2 steps)" in str(caught.value) and "stdin is not a terminal" in str(caught.value)
    assert "--yes" in caught.value.hint


def test_the_reset_question_is_answered_by_yes_and_else_refused_without_a_terminal(capsys):
    assert reset_question(True)("Reset the STOP of master 0x12345678") is True
    assert "NOTE: Reset the STOP of master 0x12345678: yes (--yes)" in capsys.readouterr().err
    assert reset_question(False)("Reset the STOP of master 0x12345678") is False


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_interrupt_like_ctrl_c_and_the_handlers_are_restored(sig):
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signal handlers are set only in the main thread (the signal would end this test process)")
    before = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGHUP)}
    expected = HungUp if sig == signal.SIGHUP else KeyboardInterrupt
    with pytest.raises(expected) as caught:
        with sigterm_as_ctrl_c():
            os.kill(os.getpid(), sig)  # the handler runs in this (the main) thread before kill returns to us
            pytest.fail("the signal did not interrupt")
    if sig == signal.SIGHUP:
        assert caught.value.exit_code == 129 and isinstance(caught.value, Cancelled)
        assert "SIGHUP (the terminal or session was lost)" in str(caught.value)
    else:
        assert "SIGTERM" in str(caught.value)
    assert {s: signal.getsignal(s) for s in before} == before
