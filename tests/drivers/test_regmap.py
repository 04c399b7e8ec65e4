"""The register map: loading, layout, encodings, CRC and the generated document."""

from __future__ import annotations

import struct
import tomllib
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mppf.drivers import regmap as rm
from mppf.core.errors import ConfigError, InputError, LimitError

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


@pytest.mark.parametrize("word_order", ["ABCD", "CDAB"])
def test_magic_words_per_word_order(rmap, word_order):
    words = rm.encode_uint32([rmap.magic], word_order)
    expected = [0x4D50, 0x5046] if word_order == "ABCD" else [0x5046, 0x4D50]
    assert words == expected
    assert rm.detect_word_order(words, rmap.magic) == word_order
    with pytest.raises(InputError, match="not the magic"):
        rm.detect_word_order([0x1234, 0x5678], rmap.magic)


@pytest.mark.parametrize("word_order", ["ABCD", "CDAB"])
@given(st.lists(st.integers(min_value=rm.INT32_MIN, max_value=rm.INT32_MAX), max_size=50))
def test_int32_round_trip(word_order, values):
    words = rm.encode_int32(values, word_order)
    assert len(words) == 2 * len(values)
    assert all(0 <= w <= 0xFFFF for w in words)
    assert rm.decode_int32(words, word_order).tolist() == values


def test_int32_encoding_matches_struct():
    values = [-1, 1, -123456789, 2**31 - 1, -(2**31)]
    abcd = rm.encode_int32(values, "ABCD")
    assert abcd == list(struct.unpack(">10H", struct.pack(">5i", *values)))
    cdab = rm.encode_int32(values, "CDAB")
    assert cdab == [w for a, b in zip(abcd[0::2], abcd[1::2]) for w in (b, a)]
    with pytest.raises(LimitError):
        rm.encode_int32([2**31], "ABCD")
    with pytest.raises(InputError, match="word order"):
        rm.encode_int32([1], "BADC")


def test_mm_counts_rounding_and_limits():
    counts = rm.mm_to_counts([[1.004, -1.006], [0.0, 21474836.47]])
    assert counts.tolist() == [[100, -101], [0, 2**31 - 1]]
    assert rm.counts_to_mm(counts)[0].tolist() == pytest.approx([1.0, -1.01])
    with pytest.raises(LimitError, match="21474836.48 mm"):
        rm.mm_to_counts([0.0, 21474836.48])
    with pytest.raises(LimitError, match="not a finite"):
        rm.mm_to_counts([np.nan])


def test_setpoint_crc_is_zlib_crc32_of_big_endian_register_bytes():
    upper = rm.encode_int32(rm.mm_to_counts([12.34, -5.0]), "ABCD")
    lower = rm.encode_int32(rm.mm_to_counts([-400.0, 0.01]), "ABCD")
    raw = struct.pack(">4i", 1234, -500, -40000, 1)
    assert rm.setpoint_crc32(upper, lower) == zlib.crc32(raw)
    # bytes high byte first, upper block before lower block
    words = list(struct.unpack(">4H", b"MPPF-job"))
    assert rm.setpoint_crc32(words[:2], words[2:]) == zlib.crc32(b"MPPF-job")
    assert rm.setpoint_crc32(words[2:], words[:2]) == zlib.crc32(b"-jobMPPF")
    # the CRC depends on the word order, as documented
    cdab = rm.encode_int32(rm.mm_to_counts([12.34, -5.0]), "CDAB")
    assert rm.setpoint_crc32(cdab, lower) != rm.setpoint_crc32(upper, lower)


@pytest.mark.parametrize("n_words", [1, 2, 121, 122, 123, 244, 2048])
def test_chunks_never_split_an_int32(n_words):
    words = list(range(n_words))
    parts = rm.chunks(1024, words, max_regs=123)
    assert [w for _, part in parts for w in part] == words
    for address, part in parts:
        assert len(part) <= 122
        assert address % 2 == 0  # every chunk starts on a register pair
    assert all(len(part) % 2 == 0 for _, part in parts[:-1])


def test_bits_round_trip():
    flags = np.zeros(24 * 16, dtype=bool)
    flags[[0, 17, 383]] = True
    words = rm.pack_bits(flags)
    assert len(words) == 24
    assert words[0] == 1 and words[1] == 2 and words[23] == 0x8000
    assert np.array_equal(rm.unpack_bits(words, flags.size), flags)


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
