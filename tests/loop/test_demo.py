"""The demo as a library function: its inputs and its default press (the whole run: tests/cli/test_demo_cmd.py)."""

from __future__ import annotations

import pytest

from mppf.core.errors import InputError
from mppf.loop.demo import DEMO_PLATE, bundled_plate, in_process_press, run_demo
from mppf.model.press import example_press_path, load_press
from mppf.sim.plc.link import InProcessPress


def test_an_unknown_plate_is_refused_naming_the_bundled_ones_before_anything_is_written(tmp_path):
    with pytest.raises(InputError, match="no bundled plate named 'nope'") as info:
        run_demo(tmp_path / "out", plate_name="nope")
    assert DEMO_PLATE in info.value.hint and not (tmp_path / "out").exists()
    assert bundled_plate(DEMO_PLATE).n_points > 1000


def test_the_default_press_is_the_in_process_press():
    press = load_press(example_press_path())
    with in_process_press(press) as link:
        assert isinstance(link, InProcessPress) and link.status().ready and link.url == "inprocess://simulated-plc"
