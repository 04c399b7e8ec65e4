"""``mppf stop`` over TCP: STOP on a bare socket before anything else is loaded, recorded just after."""

from __future__ import annotations

import subprocess
import sys

import pytest

from mppf.drivers.audit import AuditLog
from mppf.drivers.fast_stop import NotHere, fast_map, parse_tcp, stop_over_tcp
from mppf.drivers.regmap import load_register_map
from mppf.sim.plc.host import run_simulated_plc

from driver_helpers import small_press


def test_the_fast_map_reads_what_the_full_loader_reads():
    fast, full = fast_map(), load_register_map()
    assert (fast.version, fast.magic) == (full.version, full.magic)
    assert fast.address == {name: (f.address, f.count) for name, f in full.fields.items()}
    assert fast.states == {s.code: s.name for s in full.states}


@pytest.mark.parametrize("url, expected", [
    ("tcp://127.0.0.1:5020", ("127.0.0.1", 5020, 1, 1.0)),
    ("tcp://plc-7.shop:502?unit=3", ("plc-7.shop", 502, 3, 1.0)),
    ("tcp://plc:502?unit=2&timeout=0.5", ("plc", 502, 2, 0.5)),  # anything more: the full parser
])
def test_plain_tcp_urls_are_read_without_urllib(url, expected):
    assert parse_tcp(url) == expected


def test_an_rtu_url_takes_the_full_path():
    with pytest.raises(NotHere):
        parse_tcp("rtu:///dev/ttyUSB0?baud=115200")


@pytest.mark.parametrize("word_order", ["ABCD", "CDAB"])
def test_mppf_stop_stops_a_moving_press_and_records_it(tmp_path, word_order, capsys):
    from mppf.cli import main

    press = small_press()
    audit = tmp_path / "audit.sqlite"
    with run_simulated_plc(press, word_order=word_order, time_scale=1.0) as sim:
        assert main(["stop", "--plc", sim.url, "--audit", str(audit)]) == 0
        assert sim.state() == "STOPPED"
        stop_count = sim._call(lambda: sim.plc.stop_count)
        master = sim._call(lambda: sim.plc.last_stop_master)
    out = capsys.readouterr().out
    assert "the PLC took it (state STOPPED)" in out and stop_count == 1
    with AuditLog(audit) as log:
        rows = [e for e in log.entries() if e.action == "stop"]
    assert [(e.outcome) for e in rows] == ["ok"] and f"master 0x{master:08X}" in rows[0].detail


def test_a_device_that_is_not_an_mppf_plc_gets_no_fast_stop(tmp_path):
    press = small_press()
    with run_simulated_plc(press) as sim:
        address = load_register_map()["map_version"].address
        # another map version, in the registers and the PLC's shadow at once (one call: no scan between them)
        sim._call(lambda: (sim.plc.regs.__setitem__(address, 2), sim.plc._shadow.__setitem__(address, 2)))
        with pytest.raises(NotHere):
            stop_over_tcp(sim.url)
        assert sim._call(lambda: sim.plc.stop_count) == 0  # nothing written


def test_the_fast_stop_path_loads_neither_pymodbus_nor_tomllib(tmp_path):
    press = small_press()
    with run_simulated_plc(press) as sim:
        script = ("import sys; from mppf.drivers.fast_stop import stop_over_tcp; "
                  f"sent = stop_over_tcp({sim.url!r}); sent['sock'].close(); "
                  "print(sorted(m for m in ('pymodbus', 'tomllib', 'numpy', 'sqlite3', 'mppf.drivers.session') "
                  "if m in sys.modules))")
        out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"
