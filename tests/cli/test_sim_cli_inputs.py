"""``mppf sim`` and ``start_simulated_plc`` refuse bad settings with one message (exit 2)."""

from __future__ import annotations

import pytest

from mppf.cli import main
from mppf.core.errors import InputError
from mppf.sim.plc.host import run_simulated_plc, start_simulated_plc


def test_a_port_in_use_is_an_input_error_with_the_reason(capfd):
    with run_simulated_plc(watchdog_s=None) as sim:
        with pytest.raises(InputError, match=f"cannot serve on 127.0.0.1:{sim.port}: .*address already in use"):
            start_simulated_plc(port=sim.port)
        assert main(["sim", "--port", str(sim.port), "--duration", "0.1"]) == 2
    out, err = capfd.readouterr()
    assert err.startswith(f"error: the simulated PLC cannot serve on 127.0.0.1:{sim.port}")  # no pymodbus log line
    assert "Traceback" not in err and "internal error" not in err


@pytest.mark.parametrize(
    "args, message",
    [
        (["--rtu", "/nonexistent/ttyX"], "cannot serve on serial device /nonexistent/ttyX"),
        (["--port", "0", "--time-scale", "inf"], "--time-scale must be a positive number, got inf"),
        (["--port", "0", "--time-scale", "0"], "--time-scale must be a positive number"),
        (["--port", "0", "--watchdog", "nan"], "--watchdog must be a number >= 0, got nan"),
        (["--port", "0", "--status-every", "0"], "--status-every must be a positive number"),
        (["--port", "0", "--duration", "nan"], "--duration must be a number >= 0, got nan"),
        (["--rtu", "pty", "--baud", "0"], "0 is not in the range"),
    ],
)
def test_bad_sim_settings_exit_2_with_one_message(capsys, args, message):
    assert main(["sim", *args, "--duration", "0.1"] if "--duration" not in args else ["sim", *args]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert message in err and "Traceback" not in err


def test_nan_watchdog_and_infinite_time_scale_are_refused_by_the_api():
    with pytest.raises(InputError, match="watchdog_s must be a number of seconds >= 0"):
        start_simulated_plc(watchdog_s=float("nan"))
    with pytest.raises(InputError, match="time_scale must be a positive number, got inf"):
        start_simulated_plc(time_scale=float("inf"))
