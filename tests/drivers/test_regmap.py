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
    assert rmap["map_version"].address == 2
    assert set(rmap.commands) >= {"GO", "STOP", "RESET"}
    assert len(set(rmap.commands.values())) == len(rmap.commands)
    assert len(set(rmap.status_bits.values())) == len(rmap.status_bits)


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
    for name in ("magic", "status_word", "fault_code", "acknowledged_sequence", "plc_heartbeat", "upper_actuals"):
        assert not rmap[name].writable, name
    for name in ("command", "command_arg", "setpoint_crc", "job_sequence", "master_heartbeat", "lower_setpoints"):
        assert rmap[name].writable, name


def test_overlapping_map_is_refused():
    data = tomllib.loads(rm.default_map_path().read_text())
    data["register"][1]["address"] = 1  # map_version onto the magic
    with pytest.raises(ConfigError, match="overlap"):
        rm.register_map_from_dict(data, "broken.toml")


def test_unknown_register_names_the_known_ones(rmap):
    with pytest.raises(ConfigError, match="no register named 'magik'"):
        rmap["magik"]


def test_status_word_round_trip(rmap):
    word = rmap.status_word(ready=True, fault=True, data_valid=True)
    flags = rmap.status_flags(word)
    assert {k for k, v in flags.items() if v} == {"ready", "fault", "data_valid"}
    assert "CRC_MISMATCH" in rmap.fault_text(rmap.fault("CRC_MISMATCH"))
    assert rmap.fault_text(999) == "unknown fault code 999"


def test_committed_doc_equals_rendering(rmap):
    assert DOC.read_text() == rmap.render_markdown(), (
        "docs/register-map.md is out of date: run python -m mppf.drivers.regmap > docs/register-map.md"
    )
