"""The simulated PLC's settings: the transport's keyword arguments split from the program's."""

import pytest
from mppf.sim.plc.program import PlcProgram
from mppf.sim.plc.settings import PlcSettings, SimTransport, split_options

from mppf.model.press import example_press_path, load_press

PRESS = load_press(example_press_path())


def test_split_options_takes_the_transport_fields_and_leaves_the_rest():
    transport, rest = split_options({"port": 5020, "rtu_port": "/dev/ttyS0", "baud": 9600, "seed": 3,
                                     "watchdog_s": None})
    assert transport == SimTransport(port=5020, rtu_port="/dev/ttyS0", baud=9600)
    assert transport.serial
    assert rest == {"seed": 3, "watchdog_s": None}
    assert not split_options({"host": "127.0.0.1"})[0].serial
    assert split_options({"rtu": True})[0].serial


def test_program_takes_its_settings_by_keyword():
    program = PlcProgram(PRESS, word_order="CDAB", scan_s=0.05, watchdog_s=0, remote=False,
                         limits={"tip_gap_min_mm": 7.0})
    assert (program.word_order, program.scan_s, program.watchdog_s, program.remote_key) == ("CDAB", 0.05, None, False)
    assert program.tip_gap_min_mm == 7.0
    assert PlcSettings().word_order == "ABCD"
    with pytest.raises(TypeError, match="scan_ms"):
        PlcProgram(PRESS, scan_ms=10)
