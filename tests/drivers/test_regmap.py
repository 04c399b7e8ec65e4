"""The register map: loading, layout, status words and the generated document."""

from __future__ import annotations

import struct
import tomllib
from pathlib import Path

import numpy as np
import pytest
from mppf.drivers import regmap as rm
from mppf.core.errors import ConfigError, LimitError

DOC = Path(__file__).resolve().parents[2] / "docs" / "register-map.md"


@pytest.fixture(scope="module")
def rmap() -> rm.RegisterMap:
    return rm.load_register_map()


def test_map_loads_with_magic_first(rmap):
    assert rmap.magic == 0x4D505046
    assert struct.pack(">I", rmap.magic) == b"MPPF"
    assert (rmap["magic"].address, rmap["magic"].count, rmap["magic"].type) == (0, 2, "int32")
    assert rmap["map_version"].address == 2 and rmap.version == 3
    assert set(rmap.commands.by_name) == {"NONE", "CLAIM", "RELEASE", "VALIDATE", "GO", "RESET"}
    assert "STOP" not in rmap.commands  # STOP has its own register, never the mailbox
    assert len(set(rmap.status_bits.values())) == len(rmap.status_bits)
    assert "simulated" not in rmap.status_bits


def test_no_overlap_and_sizes_fit_two_32x32_matrices(rmap):
    taken = np.zeros(rmap.total_registers, dtype=int)
    for field in rmap.fields.values():
        taken[field.address : field.end] += 1
    assert taken.max() == 1
    n = 32 * 32
    for side in ("upper", "lower"):
        assert rmap[f"{side}_setpoints"].count >= 2 * n
        assert rmap[f"{side}_actuals"].count >= 2 * n
        assert rmap[f"{side}_fault_bits"].count * 16 >= n
        assert rmap[f"{side}_setpoints"].address % 2 == 0
    assert rmap.words_in_use(32, 32) == 2 * n
    with pytest.raises(LimitError, match="33 x 32"):
        rmap.words_in_use(33, 32)


def test_status_registers_are_read_only_and_control_writable(rmap):
    for name in ("magic", "watchdog_ms", "status_word", "state", "fault_code", "ack_counter", "owner_master",
                 "validated_crc", "plc_heartbeat", "refused_writes", "upper_actuals"):
        assert not rmap[name].writable, name
    for name in ("owner_ack_counter", "owner_result_code", "claim_reply", "positioning_timeout_ms", "dimpling_limit",
                 "tip_gap_min", "rest_speed", "rest_time_ms", "refused_setpoint_writes"):
        assert not rmap[name].writable, name
    for name in ("command", "command_counter", "command_master", "command_crc", "command_sequence", "command_auth",
                 "heartbeat_master", "heartbeat_counter", "heartbeat_auth", "stop_request", "stop_master",
                 "lower_setpoints"):
        assert rmap[name].writable, name
    # one request each: the mailbox, the heartbeat, the STOP
    assert rmap.span("command", "command_sequence") == (24, 9)
    assert rmap.span("heartbeat_counter", "heartbeat_auth") == (33, 5)
    assert rmap.span("stop_request", "stop_master") == (39, 3)


def test_overlapping_map_is_refused():
    data = tomllib.loads(rm.default_map_path().read_text())
    data["register"][1]["address"] = 1  # map_version onto the magic
    with pytest.raises(ConfigError, match="overlap"):
        rm.register_map_from_dict(data, "broken.toml")


def test_unknown_register_names_the_known_ones(rmap):
    with pytest.raises(ConfigError, match="no register named 'magik'"):
        rmap["magik"]


def test_status_word_round_trip(rmap):
    word = rmap.status_word(ready=True, fault=True, owned=True)
    flags = rmap.status_flags(word)
    assert {k for k, v in flags.items() if v} == {"ready", "fault", "owned"}
    assert "CRC_MISMATCH" in rmap.result_text(rmap.results.code("CRC_MISMATCH"))
    assert rmap.fault_text(999) == "unknown fault code 999"
    assert rmap.fault_text(rmap.fault("WATCHDOG")).startswith("WATCHDOG:")


def test_committed_doc_equals_rendering(rmap):
    assert DOC.read_text() == rmap.render_markdown(), (
        "docs/register-map.md is out of date: run python -m mppf.drivers.regmap > docs/register-map.md"
    )


def test_states_commands_and_results_are_one_coherent_table(rmap):
    names = [state.name for state in rmap.states]
    assert names == ["IDLE", "LOADED", "VALIDATED", "EXECUTING", "COMPLETE", "STOPPING", "STOPPED", "FAULT"]
    assert [state.code for state in rmap.states] == list(range(1, 9))
    takes = {s.name for s in rmap.states if s.setpoints == "accept"}
    assert takes == {"IDLE", "LOADED", "VALIDATED"}
    go = [s.name for s in rmap.states if "GO" in s.commands]
    assert go == ["VALIDATED"]  # GO only on a validated job
    assert all("CLAIM" in s.commands for s in rmap.states)
    assert rmap.results.code("ACCEPTED") == 0 and rmap.results.entries[0].name == "ACCEPTED"
    assert rmap.commands.by_name["GO"].checks[-1] == "TOKEN_MISMATCH"
    assert rmap.commands.by_name["GO"].from_states and rmap.faults.entries[-1].punches is not None


def test_checks_out_of_the_order_of_precedence_are_refused():
    data = tomllib.loads(rm.default_map_path().read_text())
    go = next(c for c in data["command"] if c["name"] == "GO")
    go["checks"] = list(reversed(go["checks"]))
    with pytest.raises(ConfigError, match="the checks of GO are not in the order of"):
        rm.register_map_from_dict(data, "broken.toml")
    data = tomllib.loads(rm.default_map_path().read_text())
    data["state"][0]["commands"].append("JUMP")
    with pytest.raises(ConfigError, match=r"state IDLE: unknown commands \['JUMP'\]"):
        rm.register_map_from_dict(data, "broken.toml")


def test_the_wire_example_is_what_the_driver_writes(rmap):
    """Section 10 of register-map.md, replayed: the driver's writes on the simulated PLC, in order."""
    from driver_helpers import small_press, step_setpoints

    from mppf.drivers.codec import u32_to_words
    from mppf.drivers.regmap_doc import EXAMPLE_COLS, EXAMPLE_ROWS, wire_example
    from mppf.sim.plc.link import InProcessPress

    heartbeat = rmap.span("heartbeat_counter", "heartbeat_auth")
    mailbox = rmap["command"].address
    documented = []
    for _, request, values, _ in wire_example(rmap):
        for part in request.split(", "):
            if part.startswith("W "):
                first, last = (int(a) for a in part[2:].split("-"))
                if (first, last - first + 1) != heartbeat:
                    documented.append((first, last - first + 1, values.split(":")[0] if first == mailbox else "setpoints"))
    press = small_press(EXAMPLE_ROWS, EXAMPLE_COLS)
    link = InProcessPress(press)
    written = []
    store = link.program.store

    def record(address, words):
        if (address, len(words)) != heartbeat:
            name = rmap.commands.name(words[0]) if address == rmap["command"].address else "setpoints"
            written.append((address, len(words), name))
            if address == rmap["command"].address:
                assert words[2:4] == u32_to_words(link.master_id)  # the master id in the same request
                assert any(words[6:8])  # and the auth of the nonce
        return store(address, words)

    link.program.store = record
    with link:
        link.run_step(*step_setpoints(press))
    assert written == documented
    assert [w[2] for w in written if w[2] != "setpoints"] == ["CLAIM", "VALIDATE", "GO", "RELEASE"]


def test_the_doc_names_every_register_state_command_result_and_fault(rmap):
    text = DOC.read_text()
    for name in list(rmap.fields) + [s.name for s in rmap.states] + [c.name for c in rmap.commands] + \
            [r.name for r in rmap.results] + [f.name for f in rmap.faults] + list(rmap.status_bits):
        assert name in text, name
    assert "simulated" not in text.split("## 2. Registers")[1].split("## 3.")[0]
