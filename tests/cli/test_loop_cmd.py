"""``mppf loop``'s own checks: which plate --resume continues, a bad --plc or scan folder, option values."""

from __future__ import annotations

import pytest
from panel_helpers import layout_job, record_loop

from mppf.cli.loop_cmd import _check_link_and_scanner, _check_options, _pick_plate
from mppf.core.errors import InputError
from mppf.loop.states import PlateStatus


@pytest.fixture
def history(tmp_path):
    job = layout_job()
    history = record_loop(tmp_path / "history.sqlite", job, tmp_path / "a", plate_id="B12-P3")
    record_loop(tmp_path / "history.sqlite", job, tmp_path / "b", plate_id="B12-P4").close()
    yield history
    history.close()


def test_resume_without_a_plate_id_takes_the_one_unfinished_plate(history):
    history.set_plate_status("B12-P3", PlateStatus.IN_TOLERANCE)
    assert _pick_plate(history, None).plate_id == "B12-P4"
    assert _pick_plate(history, "B12-P3").plate_id == "B12-P3"  # named: finished or not


def test_resume_with_two_unfinished_plates_asks_which_one(history):
    with pytest.raises(InputError) as caught:
        _pick_plate(history, None)
    assert "2 unfinished plates in the history: B12-P3, B12-P4" in str(caught.value)
    assert "--plate-id" in caught.value.hint


def test_resume_of_a_plate_not_in_the_history_names_the_known_ones(history):
    with pytest.raises(InputError, match="'B12-P9' is not in the history") as caught:
        _pick_plate(history, "B12-P9")
    assert "B12-P3" in caught.value.hint


def test_a_malformed_plc_url_or_a_missing_scan_folder_is_refused_before_any_work(tmp_path):
    _check_link_and_scanner(None, "sim")
    _check_link_and_scanner("tcp://127.0.0.1:1502", str(tmp_path))
    with pytest.raises(InputError):
        _check_link_and_scanner("http://press:502", "sim")
    with pytest.raises(InputError, match="no-such-folder"):
        _check_link_and_scanner(None, str(tmp_path / "no-such-folder"))


@pytest.mark.parametrize(("values", "option"), [((0.0, 60.0, 0, None), "--thickness"),
                                                ((250.0, 60.0, 0, None), "--thickness"),
                                                ((20.0, 0.0, 0, None), "--scan-timeout"),
                                                ((20.0, 60.0, -1, None), "--seed"),
                                                ((20.0, 60.0, 1.5, None), "--seed")])
def test_option_values_out_of_range_are_refused_naming_the_option(values, option):
    with pytest.raises(InputError, match=option):
        _check_options(*values)


def test_an_audit_log_that_is_a_folder_is_refused_and_good_values_pass(tmp_path):
    _check_options(20.0, 60.0, 3, tmp_path / "audit.sqlite")
    _check_options(None, 1800.0, 0, None)  # --resume: the thickness is the plate's
    with pytest.raises(InputError, match="--audit"):
        _check_options(20.0, 60.0, 0, tmp_path)
