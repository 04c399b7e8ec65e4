"""``mppf history`` in a log (not a terminal): the plate table's title and legend are whole lines."""

from __future__ import annotations

import os
import subprocess
import sys

from mppf.loop.history import History
from mppf.loop.options import PlateFiles
from mppf.model.press import example_press_path, load_press


def test_plate_table_title_and_legend_are_not_wrapped_in_a_log(tmp_path):
    folder = tmp_path / ("a_long_folder_name_for_the_history_of_the_hull_block_B12_" * 2)
    folder.mkdir()
    path = folder / "history.sqlite"
    press = load_press(example_press_path())
    with History(path) as history:
        history.create_plate("PLATE-A", PlateFiles("/d.csv", "a" * 64, "/f.csv", "b" * 64), thickness_mm=20.0,
                             press=press.to_dict(), settings={"loop": {"tolerance_mm": 2.5}})
    env = {**os.environ, "COLUMNS": "80"}
    out = subprocess.run([sys.executable, "-m", "mppf", "history", "--history", str(path)], capture_output=True,
                         text=True, env=env, timeout=60, check=True).stdout
    lines = out.splitlines()
    assert f"plates in {path}" in lines
    assert "form max, RMS: deviations (mm) of the last measured cycle; t: thickness (mm)" in lines
    assert any("PLATE-A" in line for line in lines)
