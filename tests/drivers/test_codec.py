"""Register encodings: word orders, int32 and mm counts, the setpoint CRC, chunking, bits."""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mppf.drivers import codec, regmap as rm
from mppf.core.errors import InputError, LimitError


@pytest.fixture(scope="module")
def rmap() -> rm.RegisterMap:
    return rm.load_register_map()


@pytest.mark.parametrize("word_order", ["ABCD", "CDAB"])
def test_magic_words_per_word_order(rmap, word_order):
    words = codec.encode_uint32([rmap.magic], word_order)
    expected = [0x4D50, 0x5046] if word_order == "ABCD" else [0x5046, 0x4D50]
    assert words == expected
    assert codec.detect_word_order(words, rmap.magic) == word_order
    with pytest.raises(InputError, match="not the magic"):
        codec.detect_word_order([0x1234, 0x5678], rmap.magic)


@pytest.mark.parametrize("word_order", ["ABCD", "CDAB"])
@given(st.lists(st.integers(min_value=codec.INT32_MIN, max_value=codec.INT32_MAX), max_size=50))
def test_int32_round_trip(word_order, values):
    words = codec.encode_int32(values, word_order)
    assert len(words) == 2 * len(values)
    assert all(0 <= w <= 0xFFFF for w in words)
    assert codec.decode_int32(words, word_order).tolist() == values


def test_int32_encoding_matches_struct():
    values = [-1, 1, -123456789, 2**31 - 1, -(2**31)]
    abcd = codec.encode_int32(values, "ABCD")
    assert abcd == list(struct.unpack(">10H", struct.pack(">5i", *values)))
    cdab = codec.encode_int32(values, "CDAB")
    assert cdab == [w for a, b in zip(abcd[0::2], abcd[1::2]) for w in (b, a)]
    with pytest.raises(LimitError):
        codec.encode_int32([2**31], "ABCD")
    with pytest.raises(InputError, match="word order"):
        codec.encode_int32([1], "BADC")


def test_mm_counts_rounding_and_limits():
    counts = codec.mm_to_counts([[1.004, -1.006], [0.0, 21474836.47]])
    assert counts.tolist() == [[100, -101], [0, 2**31 - 1]]
    assert codec.counts_to_mm(counts)[0].tolist() == pytest.approx([1.0, -1.01])
    with pytest.raises(LimitError, match="21474836.48 mm"):
        codec.mm_to_counts([0.0, 21474836.48])
    with pytest.raises(LimitError, match="not a finite"):
        codec.mm_to_counts([np.nan])


def test_setpoint_crc_is_zlib_crc32_of_big_endian_register_bytes():
    upper = codec.encode_int32(codec.mm_to_counts([12.34, -5.0]), "ABCD")
    lower = codec.encode_int32(codec.mm_to_counts([-400.0, 0.01]), "ABCD")
    raw = struct.pack(">4i", 1234, -500, -40000, 1)
    assert codec.setpoint_crc32(upper, lower) == zlib.crc32(raw)
    # bytes high byte first, upper block before lower block
    words = list(struct.unpack(">4H", b"MPPF-job"))
    assert codec.setpoint_crc32(words[:2], words[2:]) == zlib.crc32(b"MPPF-job")
    assert codec.setpoint_crc32(words[2:], words[:2]) == zlib.crc32(b"-jobMPPF")
    # the CRC depends on the word order, as documented
    cdab = codec.encode_int32(codec.mm_to_counts([12.34, -5.0]), "CDAB")
    assert codec.setpoint_crc32(cdab, lower) != codec.setpoint_crc32(upper, lower)


@pytest.mark.parametrize("n_words", [1, 2, 121, 122, 123, 244, 2048])
def test_chunks_never_split_an_int32(n_words):
    words = list(range(n_words))
    parts = codec.chunks(1024, words, max_regs=123)
    assert [w for _, part in parts for w in part] == words
    for address, part in parts:
        assert len(part) <= 122
        assert address % 2 == 0  # every chunk starts on a register pair
    assert all(len(part) % 2 == 0 for _, part in parts[:-1])


def test_bits_round_trip():
    flags = np.zeros(24 * 16, dtype=bool)
    flags[[0, 17, 383]] = True
    words = codec.pack_bits(flags)
    assert len(words) == 24
    assert words[0] == 1 and words[1] == 2 and words[23] == 0x8000
    assert np.array_equal(codec.unpack_bits(words, flags.size), flags)


def test_scalar_words_need_no_numpy_and_agree_with_the_arrays():
    for order in ("ABCD", "CDAB"):
        for value in (0, 1, 0x4D505046, 0xFFFFFFFF):
            words = codec.u32_to_words(value, order)
            assert words == codec.encode_uint32([value], order)
            assert codec.words_to_u32(words, order) == value
        for value in (-1, -123456, 2**31 - 1):
            assert codec.words_to_i32(codec.encode_int32([value], order), order) == value
    with pytest.raises(LimitError):
        codec.u32_to_words(-1)
