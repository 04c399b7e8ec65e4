"""A third-party Modbus master (mbpoll, libmodbus) reads the simulated PLC.

mbpoll is a Debian package; CI installs it. The tests need that outside program, so they are
``slow`` (``.ci/run`` runs them after the default suite). Locally they are skipped without
it, but when the environment variable CI is "true" a missing mbpoll is a failure.
"""

from __future__ import annotations

import dataclasses
import os
import re
import shutil
import subprocess

import pytest

from mppf.drivers import regmap as rm
from mppf.model.press import example_press_path, load_press
from mppf.sim.plc.host import run_simulated_plc

pytestmark = pytest.mark.slow  # needs mbpoll

MAP = rm.load_register_map()
PRESS = dataclasses.replace(load_press(example_press_path()), rows=3, cols=4)


@pytest.fixture(scope="module")
def mbpoll() -> str:
    path = shutil.which("mbpoll")
    if path is None:
        if os.environ.get("CI") == "true":
            pytest.fail("mbpoll is not installed on CI (apt-get install mbpoll)")
        pytest.skip("mbpoll is not installed")
    return path


def run_mbpoll(mbpoll, *args) -> dict[int, str]:
    """Run mbpoll once; return {reference: value text} of its output (a value above 32767 is followed by its
    signed reading in brackets, left out)."""
    result = subprocess.run([mbpoll, "-1", "-0", *args], capture_output=True, text=True, timeout=20)
    assert result.returncode == 0, result.stdout + result.stderr
    return {int(ref): value for ref, value in re.findall(r"^\[(\d+)\]:\s+(\S+)", result.stdout, re.M)}


@pytest.mark.parametrize("word_order", ["ABCD", "CDAB"])
def test_mbpoll_reads_magic_and_a_setpoint_over_tcp(mbpoll, word_order):
    with run_simulated_plc(PRESS, word_order=word_order, watchdog_s=None) as sim:
        sim.write_foreign_setpoint("upper", 1, 2, -123.45)
        port = str(sim.port)
        magic = run_mbpoll(mbpoll, "-p", port, "-a", "1", "-r", "0", "-c", "2", "-t", "4:hex", "127.0.0.1")
        expected = ["0x4D50", "0x5046"] if word_order == "ABCD" else ["0x5046", "0x4D50"]
        assert [magic[0], magic[1]] == expected
        # the setpoint as an int32 (mbpoll's default is CDAB; -B reads ABCD)
        address = MAP["upper_setpoints"].address + 2 * MAP.punch_index(1, 2, PRESS.cols)
        order_flag = ["-B"] if word_order == "ABCD" else []
        values = run_mbpoll(
            mbpoll, *order_flag, "-p", port, "-a", "1", "-r", str(address), "-c", "1", "-t", "4:int", "127.0.0.1"
        )
        assert int(values[address]) == -12345
        # identity and status as a third-party master reads them
        identity = run_mbpoll(mbpoll, "-p", port, "-a", "1", "-r", "2", "-c", "4", "-t", "4", "127.0.0.1")
        assert [int(identity[a]) for a in (2, 3, 4)] == [MAP.version, PRESS.rows, PRESS.cols]
        status = run_mbpoll(mbpoll, "-p", port, "-a", "1", "-r", str(MAP["status_word"].address), "-c", "3",
                            "-t", "4", "127.0.0.1")
        flags = MAP.status_flags(int(status[MAP["status_word"].address]))
        assert flags["ready"] and not flags["busy"] and not flags["owned"]
        assert MAP.states.name(int(status[MAP["state"].address])) == "LOADED"  # the setpoint written above
        assert int(status[MAP["fault_code"].address]) == 0


@pytest.mark.rtu
def test_mbpoll_reads_magic_over_rtu_on_a_pty(mbpoll):
    with run_simulated_plc(PRESS, rtu=True, baud=19200, watchdog_s=None) as sim:
        parity = {"N": "none", "E": "even", "O": "odd"}[re.search(r"parity=([NEO])", sim.url).group(1)]
        magic = run_mbpoll(
            mbpoll, "-m", "rtu", "-b", "19200", "-P", parity, "-a", "1", "-r", "0", "-c", "2", "-t", "4:hex", sim.serial_port
        )
        assert [magic[0], magic[1]] == ["0x4D50", "0x5046"]


def test_a_bare_master_claims_with_a_key_and_cannot_borrow_the_owners_id(mbpoll):
    """Section 7 of the map with mbpoll alone: CLAIM with a claim key returns the nonce masked, never in clear;
    the same id without the auth is refused BAD_AUTH (a PLC programmer's check)."""
    from mppf.drivers import codec

    with run_simulated_plc(PRESS, watchdog_s=None) as sim:
        port = str(sim.port)
        mailbox = MAP["command"].address
        key = 0x12345678
        # CLAIM: command 1, counter 7, master 0x0000ABCD, claim key, auth 0 0, sequence 0 (ABCD word order)
        words = [MAP.command("CLAIM"), 7, 0, 0xABCD] + codec.u32_to_words(key) + [0, 0, 0]
        run_mbpoll(mbpoll, "-p", port, "-a", "1", "-r", str(mailbox), "-t", "4", "127.0.0.1", *map(str, words))
        sim.scans(3)
        status = run_mbpoll(mbpoll, "-p", port, "-a", "1", "-r", str(MAP["owner_master"].address), "-c", "8",
                            "-t", "4", "127.0.0.1")
        first = MAP["owner_master"].address
        owner = codec.words_to_u32([int(status[first]), int(status[first + 1])])
        reply_at = MAP["claim_reply"].address
        reply = codec.words_to_u32([int(status[reply_at]), int(status[reply_at + 1])])
        assert owner == 0xABCD and MAP.results.name(int(status[MAP["owner_result_code"].address])) == "ACCEPTED"
        nonce = sim._call(lambda: sim.plc.nonce)
        assert reply == nonce ^ key and reply != nonce
        assert run_mbpoll(mbpoll, "-p", port, "-a", "1", "-r", str(MAP["command_crc"].address), "-c", "2", "-t", "4",
                          "127.0.0.1") == {MAP["command_crc"].address: "0", MAP["command_crc"].address + 1: "0"}
        # RESET in the owner's name without its auth: BAD_AUTH
        words = [MAP.command("RESET"), 8, 0, 0xABCD, 0, 0, 0, 0, 0]
        run_mbpoll(mbpoll, "-p", port, "-a", "1", "-r", str(mailbox), "-t", "4", "127.0.0.1", *map(str, words))
        sim.scans(3)
        assert sim.result() == "BAD_AUTH"
