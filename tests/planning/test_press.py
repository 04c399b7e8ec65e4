"""This machine's press: --press, else the installed one; the bundled example only for dry runs; never the job's."""

from __future__ import annotations

import pytest
from driver_helpers import small_press

from mppf.core.errors import ConfigError
from mppf.model.press import example_press_path, load_press, press_to_toml
from mppf.planning.press import check_installed_press, machine_press


@pytest.fixture
def home(tmp_path, monkeypatch):
    monkeypatch.setenv("MPPF_HOME", str(tmp_path / "home"))
    (tmp_path / "home").mkdir()
    return tmp_path / "home"


def test_the_press_is_the_given_then_the_installed_then_for_dry_runs_the_example(home, tmp_path):
    example = load_press(example_press_path())
    assert machine_press(None, dry_run=True) == (example, "the example press (dry run, no press installed)")
    with pytest.raises(ConfigError, match="no press description for this machine") as info:
        machine_press(None)
    assert str(home / "press.toml") in info.value.message
    (home / "press.toml").write_text(press_to_toml(small_press()))
    press, source = machine_press(None)
    assert press == small_press() and source == f"the installed press {home / 'press.toml'}"
    given = tmp_path / "given.toml"
    given.write_text(press_to_toml(example))
    assert machine_press(given) == (example, str(given))


def test_a_press_that_is_not_the_installed_one_is_refused(home):
    check_installed_press(small_press(), "the loop's press")  # nothing installed: nothing to compare
    (home / "press.toml").write_text(press_to_toml(small_press()))
    check_installed_press(small_press(), "the loop's press")
    with pytest.raises(ConfigError, match=r"the loop's press is not this machine's press.*\[matrix\] rows is 5"):
        check_installed_press(small_press(5, 6), "the loop's press")


def test_press_to_toml_reads_back_equal(tmp_path):
    for press in (load_press(example_press_path()), small_press(3, 4, max_neighbour_diff_mm=12.5)):
        path = tmp_path / "p.toml"
        path.write_text(press_to_toml(press))
        assert load_press(path) == press
