"""The loop's settings: checked on construction, stored with the plate."""

from __future__ import annotations

import pytest

from mppf.core.defaults import RMS_TOLERANCE_MM, TOLERANCE_MM
from mppf.core.errors import InputError
from mppf.loop.settings import LoopSettings


@pytest.mark.parametrize("kwargs", [{"tolerance_mm": 0}, {"rms_tolerance_mm": -1}, {"max_cycles": 0},
                                    {"divergence_factor": 1.0}, {"tolerance_mm": float("nan")}])
def test_bad_loop_settings(kwargs):
    with pytest.raises(InputError):
        LoopSettings(**kwargs)


@pytest.mark.parametrize("kwargs, words", [
    ({"tolerance_mm": -1}, "loop setting tolerance_mm must be above 0, got -1"),
    ({"max_cycles": 51}, "loop setting max_cycles must be from 1 to 50, got 51"),
    ({"max_cycles": 2.5}, "loop setting max_cycles must be a whole number, got 2.5"),
    ({"divergence_factor": True}, "loop setting divergence_factor must be a number, got True"),
])
def test_bad_settings_are_named_with_the_value(kwargs, words):
    with pytest.raises(InputError, match=words):
        LoopSettings(**kwargs)


def test_defaults_are_the_shop_tolerances_and_round_trip():
    settings = LoopSettings(max_cycles=3, rescans=1)
    assert (settings.tolerance_mm, settings.rms_tolerance_mm) == (TOLERANCE_MM, RMS_TOLERANCE_MM)
    assert LoopSettings.from_dict(settings.to_dict()) == settings


def test_older_settings_with_retired_correction_keys_are_read(caplog):
    """An older plate's settings chose among corrections the loop no longer has: read, those keys ignored."""
    old = {**LoopSettings(max_cycles=3).to_dict(), "gain": 0.8, "model_gain": False, "calibrate": True,
           "learn": False}
    with caplog.at_level("INFO", logger="mppf"):
        assert LoopSettings.from_dict(old) == LoopSettings(max_cycles=3)
    assert not caplog.records  # the retired keys are known: nothing to note


def test_unknown_settings_keys_are_ignored_with_a_note(caplog):
    with caplog.at_level("INFO", logger="mppf"):
        assert LoopSettings.from_dict({"max_cycles": 4, "colour": "red"}) == LoopSettings(max_cycles=4)
    assert "ignoring unknown key(s) colour" in caplog.text
    assert "gain" not in LoopSettings().to_dict()
