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


@pytest.mark.parametrize("value", ["0", "250", "nan"])
def test_a_scan_time_outside_1_to_200_ms_exits_2(capsys, value):
    assert main(["sim", "--port", "0", "--scan-ms", value, "--duration", "0.1"]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"--scan-ms must be above 0 and at most 200 ms, got {float(value)}" in err and "Traceback" not in err


def test_the_operator_commands_on_the_simulators_stdin(tmp_path):
    """estop / release / key local / key remote / fault / quit typed into a running ``mppf sim``."""
    import re
    import subprocess
    import sys

    from mppf.drivers.modbus_session import ModbusSession

    proc = subprocess.Popen([sys.executable, "-m", "mppf", "sim", "--port", "0", "--status-every", "100",
                             "--scan-ms", "20", "--key", "local"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = re.search(r"tcp://127\.0\.0\.1:\d+\?unit=1", proc.stdout.readline()).group(0)
        proc.stdout.readline()  # the description line
        assert "IDLE" in proc.stdout.readline()  # the first status line

        def say(line: str) -> str:
            proc.stdin.write(line + "\n")
            proc.stdin.flush()
            return proc.stdout.readline()

        with ModbusSession(url, heartbeat_s=None) as plc:
            assert plc.identity.scan_time_s == 0.02 and not plc.status().remote_enabled
            assert "IDLE" in say("key remote") and plc.status().remote_enabled
            assert "FAULT" in say("estop") and plc.status().estop
            assert "FAULT" in say("release") and not plc.status().estop and plc.status().fault
            assert "unknown command" in say("dance")
            assert "refused: unknown fault 'flood'" in say("fault flood")
            say("fault overpressure")
            assert plc.status_report()["fault_text"].startswith("ESTOP")  # the first fault keeps its code
        proc.stdin.write("quit\n")
        proc.stdin.flush()
        out, err = proc.communicate(timeout=10)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert "simulated PLC stopped" in out
