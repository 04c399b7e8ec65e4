"""Register map v3 in the simulated PLC's program: nonces, the owner's acknowledgement, the PLC's own
neighbour-step and tip-gap checks, the definition of "at rest", and the quirks of misread PLCs.

Scan by scan, no Modbus: a raw master stores into the register image as a PLC's Modbus server
does, and a second raw master plays the foreign master that reads everything readable.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from driver_helpers import RawMaster
from mppf.drivers import codec
from mppf.drivers import regmap as rm
from mppf.sim.plc.program import PlcProgram
from mppf.sim.plc.quirks import FOREIGN_MASTER, parse_quirk

from mppf.core.errors import InputError
from mppf.model.press import example_press_path, load_press

MAP = rm.load_register_map()
PRESS = dataclasses.replace(load_press(example_press_path()), rows=4, cols=6)
SCAN_S = 0.01
OWNER_ID = 0x11111111


def _master(program: PlcProgram, master_id: int) -> RawMaster:
    def write(address, words):
        assert program.store(address, words) is None

    return RawMaster(MAP, write, program.read, lambda: program.advance(SCAN_S), master_id, program.word_order)


def _program(**kwargs) -> PlcProgram:
    return PlcProgram(PRESS, watchdog_s=1.0, scan_s=SCAN_S, **kwargs)


def _owner(program) -> RawMaster:
    owner = _master(program, OWNER_ID)
    assert owner.command("CLAIM") == "ACCEPTED"
    return owner


def _targets(shift=0.0):
    rng = np.random.default_rng(3)
    return rng.uniform(40.0, 60.0, PRESS.shape).round(2) + shift, rng.uniform(-60.0, -40.0, PRESS.shape).round(2)


def _validated(owner, sequence=1, upper=None, lower=None):
    if upper is None:
        upper, lower = _targets()
    crc = owner.upload(upper, lower)
    owner.scan()
    return crc, owner.command("VALIDATE", sequence, crc)


def _run(program, owner, states, limit_s=60.0):
    waited = 0.0
    while owner.state() not in states:
        owner.beat()
        program.advance(0.02)
        waited += 0.02
        assert waited < limit_s, f"still {owner.state()}"
    return waited


def test_the_nonce_is_returned_masked_and_the_claim_key_is_cleared():
    program = _program()
    owner = _owner(program)
    assert owner.nonce == program.nonce != 0
    assert owner.field("command_crc") == 0  # the claim key is gone from the mailbox after the scan
    image = program.read(0, MAP["upper_setpoints"].address)
    pairs = {codec.words_to_u32(image[a:a + 2], "ABCD") for a in range(len(image) - 1)}
    assert program.nonce not in pairs  # no register shows the nonce, in any alignment


def test_a_master_borrowing_the_owners_id_cannot_command_or_keep_the_lease():
    program = _program()
    owner = _owner(program)
    crc, result = _validated(owner)
    assert result == "ACCEPTED"
    thief = _master(program, 0x22222222)
    token = (thief.field("validated_sequence"), thief.field("validated_crc"))  # readable by anyone
    assert thief.command("GO", *token, master=OWNER_ID) == "BAD_AUTH"
    assert thief.command("CLAIM", master=OWNER_ID) == "OWNED_BY_OTHER"
    assert thief.command("RELEASE", master=OWNER_ID) == "BAD_AUTH"
    assert owner.state() == "VALIDATED" and owner.field("owner_master") == OWNER_ID
    assert owner.field("owner_ack_counter") != thief.counter  # the owner's acknowledgement is untouched
    assert owner.command("GO", 1, crc) == "ACCEPTED"
    for _ in range(8):  # the owner dies; the thief beats with its id every 0.2 s: the lease still lapses
        thief.beat(master=OWNER_ID)
        program.advance(0.2)
    assert owner.state() == "FAULT" and MAP.faults.name(owner.field("fault_code")) == "WATCHDOG"


def test_a_replayed_owner_command_is_refused():
    program = _program()
    owner = _owner(program)
    owner.send("RESET")
    saved = program.read(MAP["command"].address, 9)
    owner.scan()
    assert owner.result() == "ACCEPTED"
    owner.stop()  # someone stops the press; the owner goes on with a newer command
    owner.scan()
    assert owner.command("NONE") == "ACCEPTED" and owner.state() == "STOPPED"
    program.store(MAP["command"].address, saved)  # the owner's old RESET, auth and all, written again
    program.advance(SCAN_S)
    assert owner.result() == "BAD_AUTH" and owner.state() == "STOPPED"


def test_a_foreign_none_after_go_leaves_the_owners_acknowledgement():
    program = _program(quirks=["none-after-go"])
    owner = _owner(program)
    crc, _ = _validated(owner)
    owner.send("GO", 1, crc)
    owner.scan()  # GO taken; the foreign master writes NONE right after this scan
    go_counter = owner.counter
    program.advance(SCAN_S)  # the NONE taken
    assert owner.field("ack_master") == FOREIGN_MASTER and MAP.commands.name(owner.field("ack_command")) == "NONE"
    assert owner.field("owner_ack_counter") == go_counter
    assert MAP.commands.name(owner.field("owner_ack_command")) == "GO" and owner.field("owner_result_code") == 0
    assert (owner.field("motion_sequence"), owner.field("motion_crc")) == (1, crc)


def test_validate_refuses_a_neighbour_step_beyond_the_dimpling_limit():
    program = _program()
    owner = _owner(program)
    upper, lower = _targets()
    upper[1, 2] += PRESS.max_neighbour_diff_mm + 5.0  # one pair raised: its moves differ from its neighbours'
    lower[1, 2] += PRESS.max_neighbour_diff_mm + 5.0
    _, result = _validated(owner, 1, upper, lower)
    assert result == "NEIGHBOUR_STEP" and owner.state() == "LOADED"
    assert owner.field("dimpling_limit") == round(PRESS.max_neighbour_diff_mm * 100)


def test_validate_refuses_a_tip_gap_below_the_plcs_minimum():
    program = _program(limits={"tip_gap_min_mm": 5.0})
    owner = _owner(program)
    upper, lower = _targets()
    upper[2, 3] = lower[2, 3] + 4.0
    # keep the neighbour step within the limit: the tip gap alone is wrong
    _, result = _validated(owner, 1, upper, lower)
    assert result in ("TIP_GAP", "NEIGHBOUR_STEP")
    lower2 = lower.copy()
    upper2 = lower2 + 4.0  # every pair 4 mm apart: the moves are alike, only the gap is wrong
    _, result = _validated(owner, 2, upper2 + 0.0, lower2)
    assert result in ("TIP_GAP",)


def test_parked_pairs_are_left_out_of_both_checks():
    program = _program()
    owner = _owner(program)
    upper, lower = _targets()
    upper[0, 0], lower[0, 0] = PRESS.upper.park_mm, PRESS.lower.park_mm
    _, result = _validated(owner, 1, upper, lower)
    assert result == "ACCEPTED"


def test_a_literal_plc_reports_complete_in_the_scan_of_go_while_the_punches_move():
    program = _program(quirks=["literal-complete"])
    owner = _owner(program)
    crc, _ = _validated(owner)
    assert owner.command("GO", 1, crc) == "ACCEPTED"
    assert owner.state() == "COMPLETE"
    owner.scan()
    owner.scan()
    flags = owner.flags()
    assert owner.state() == "COMPLETE" and flags["busy"] and not flags["in_position"]
    assert program.hydraulics.moving


def test_the_map_plc_completes_only_at_rest_in_the_band():
    program = _program()
    owner = _owner(program)
    crc, _ = _validated(owner)
    assert owner.command("GO", 1, crc) == "ACCEPTED" and owner.state() == "EXECUTING"
    _run(program, owner, ("COMPLETE",))
    assert owner.flags()["in_position"] and not owner.flags()["busy"]


def test_a_stuck_punch_latches_stuck_punch_after_the_positioning_timeout():
    program = _program(limits={"positioning_timeout_s": 0.5})
    owner = _owner(program)
    assert owner.field("positioning_timeout_ms") == 500
    program.inject("stuck", matrix="lower", row=2, col=3, percent=25)
    crc, _ = _validated(owner)
    assert owner.command("GO", 1, crc) == "ACCEPTED"
    _run(program, owner, ("COMPLETE", "FAULT"))
    assert owner.state() == "FAULT" and MAP.faults.name(owner.field("fault_code")) == "STUCK_PUNCH"
    bits = codec.unpack_bits(program.read(MAP["lower_fault_bits"].address, 2), 24)
    assert bits[2 * 6 + 3] and bits.sum() == 1


def test_stop_in_complete_brakes_what_still_moves():
    program = _program(quirks=["literal-complete"])
    owner = _owner(program)
    crc, _ = _validated(owner)
    assert owner.command("GO", 1, crc) == "ACCEPTED" and owner.state() == "COMPLETE"
    program.advance(0.5)
    owner.stop()
    program.advance(SCAN_S)
    assert owner.state() == "STOPPED"
    _run(program, owner, ("STOPPED",))
    for _ in range(200):
        program.advance(0.02)
    assert not program.hydraulics.moving and not owner.flags()["busy"]
    assert not owner.flags()["in_position"]  # braked short of the goal


def test_late_status_publishes_the_status_word_n_scans_late():
    program = _program(quirks=["late-status:3"])
    owner = _owner(program)
    crc, _ = _validated(owner)
    owner.send("GO", 1, crc)
    owner.scan()
    assert owner.state() == "EXECUTING" and not owner.flags()["busy"]  # the bits of 3 scans ago
    for _ in range(3):
        owner.scan()
    assert owner.flags()["busy"]


def test_a_foreign_stop_arrives_during_the_motion():
    program = _program(quirks=["foreign-stop@0.3"])
    owner = _owner(program)
    crc, _ = _validated(owner)
    assert owner.command("GO", 1, crc) == "ACCEPTED"
    program.advance(0.4)  # the foreign master writes its STOP after this scan
    program.advance(SCAN_S)
    assert owner.state() == "STOPPING" and owner.field("validated_sequence") == 0  # STOP drops the token at once
    _run(program, owner, ("STOPPED",))
    assert owner.field("stop_count") == 1 and owner.field("last_stop_master") == FOREIGN_MASTER


@pytest.mark.parametrize("spec, message", [("literal", "unknown PLC quirk"), ("late-status:0", "from 1 to 10"),
                                           ("late-status:x", "must be a number"), ("borrow-ids:3", "takes no value")])
def test_bad_quirk_specs_are_named(spec, message):
    with pytest.raises(InputError) as info:
        parse_quirk(spec)
    assert message in info.value.message and spec in info.value.message


def test_mppf_sim_refuses_an_unknown_quirk_with_exit_2(capsys):
    from mppf.cli import main

    assert main(["sim", "--port", "0", "--quirk", "literal", "--duration", "0.1"]) == 2
    assert "unknown PLC quirk 'literal'" in capsys.readouterr().err


def test_mppf_sim_names_a_bad_plc_setting(capsys):
    from mppf.cli import main

    assert main(["sim", "--port", "0", "--tip-gap-min", "-3", "--duration", "0.1"]) == 2
    assert "--tip-gap-min must be a number >= 0, got -3" in capsys.readouterr().err
