"""Register encodings shared by the driver and the simulated PLC (pure numpy, no pymodbus).

Positions are signed int32 counts of 0.01 mm; 32-bit values take two registers in a word
order (``"ABCD"``: high word first, ``"CDAB"``: low word first; the bytes inside a register
are always high byte first); the setpoint blocks carry a CRC-32; long writes are cut into
frames that never split an int32; per-punch bits are packed 16 to a register. The register
numbers themselves are :mod:`mppf.drivers.regmap`'s.

numpy is imported inside the functions that work on arrays: the scalar helpers
(:func:`words_to_u32`, :func:`u32_to_words`, :func:`detect_word_order`) are what
``mppf status`` / ``stop`` / ``reset`` need, and they start without it.
"""

from __future__ import annotations

import zlib

from mppf.core.errors import InputError, LimitError

WORD_ORDERS = ("ABCD", "CDAB")
INT32_MIN = -(2**31)
INT32_MAX = 2**31 - 1

EXCEPTION_NAMES = {  # Modbus exception codes, as a master reports them
    1: "illegal function",
    2: "illegal data address",
    3: "illegal data value",
    4: "server device failure",
    5: "acknowledge",
    6: "server device busy",
    8: "memory parity error",
    10: "gateway path unavailable",
    11: "gateway target device failed to respond",
}


def check_word_order(word_order: str) -> str:
    """Return ``word_order`` if it is ``"ABCD"`` or ``"CDAB"``, else raise InputError."""
    if word_order not in WORD_ORDERS:
        raise InputError(
            f"word order must be one of {WORD_ORDERS}, got {word_order!r}",
            hint="ABCD = high word first (big-endian), CDAB = low word first",
        )
    return word_order


def mm_to_counts(values_mm, count_mm: float = 0.01) -> np.ndarray:
    """Millimetres to position counts (0.01 mm), rounded to the nearest count.

    Parameters
    ----------
    values_mm : array_like of float, any shape
    count_mm : float
        Millimetres per count.

    Returns
    -------
    counts : int64 array, same shape

    Raises
    ------
    LimitError
        A value is not finite or does not fit a signed int32 after scaling.
    """
    import numpy as np

    values = np.asarray(values_mm, dtype=float)
    if not np.all(np.isfinite(values)):
        bad = values[~np.isfinite(values)].ravel()[0]
        raise LimitError(f"position {bad} mm is not a finite number", hint="fill inactive punches with parking heights")
    counts = np.rint(values / count_mm)
    if values.size and (counts.min() < INT32_MIN or counts.max() > INT32_MAX):
        worst = values.ravel()[np.argmax(np.abs(counts.ravel()))]
        raise LimitError(
            f"position {worst} mm does not fit a signed 32-bit register in {count_mm} mm counts",
            hint=f"positions must lie within +-{INT32_MAX * count_mm:.0f} mm",
        )
    return counts.astype(np.int64)


def counts_to_mm(counts, count_mm: float = 0.01) -> np.ndarray:
    """Position counts to millimetres (float array of the same shape)."""
    import numpy as np

    return np.asarray(counts, dtype=np.int64) * count_mm


def encode_int32(values, word_order: str = "ABCD") -> list[int]:
    """Signed int32 values to 16-bit register words.

    Parameters
    ----------
    values : array_like of int, (n,)
    word_order : {"ABCD", "CDAB"}
        ABCD: high word first; CDAB: low word first (bytes within a word stay big-endian).

    Returns
    -------
    words : list of int, 2n values in 0..65535

    Raises
    ------
    LimitError
        A value outside the int32 range.
    """
    import numpy as np

    check_word_order(word_order)
    vals = np.asarray(values, dtype=np.int64).ravel()
    if vals.size and (vals.min() < INT32_MIN or vals.max() > INT32_MAX):
        raise LimitError(f"value {vals[np.argmax(np.abs(vals))]} does not fit a signed int32")
    unsigned = vals & 0xFFFFFFFF
    return _split_words(unsigned, word_order)


def encode_uint32(values, word_order: str = "ABCD") -> list[int]:
    """Unsigned 32-bit values (0..2**32-1) to register words (see :func:`encode_int32`)."""
    import numpy as np

    check_word_order(word_order)
    vals = np.asarray(values, dtype=np.int64).ravel()
    if vals.size and (vals.min() < 0 or vals.max() > 0xFFFFFFFF):
        raise LimitError(f"value {vals[np.argmax(np.abs(vals))]} does not fit an unsigned 32-bit register pair")
    return _split_words(vals, word_order)


def _split_words(unsigned: np.ndarray, word_order: str) -> list[int]:
    import numpy as np

    high = (unsigned >> 16) & 0xFFFF
    low = unsigned & 0xFFFF
    pairs = (high, low) if word_order == "ABCD" else (low, high)
    return np.column_stack(pairs).ravel().astype(int).tolist()


def _join_words(words, word_order: str) -> np.ndarray:
    import numpy as np

    check_word_order(word_order)
    arr = np.asarray(words, dtype=np.int64).ravel()
    if arr.size % 2:
        raise InputError(f"32-bit values need an even number of registers, got {arr.size}")
    if arr.size and (arr.min() < 0 or arr.max() > 0xFFFF):
        raise InputError("register words must lie in 0..65535")
    first, second = arr[0::2], arr[1::2]
    high, low = (first, second) if word_order == "ABCD" else (second, first)
    return (high << 16) | low


def decode_int32(words, word_order: str = "ABCD") -> np.ndarray:
    """Register words (2n) to signed int32 values, int64 array (n,)."""
    import numpy as np

    unsigned = _join_words(words, word_order)
    return np.where(unsigned >= 2**31, unsigned - 2**32, unsigned)


def decode_uint32(words, word_order: str = "ABCD") -> np.ndarray:
    """Register words (2n) to unsigned 32-bit values, int64 array (n,)."""
    return _join_words(words, word_order)


def words_to_u32(words, word_order: str = "ABCD") -> int:
    """Two register words to one unsigned 32-bit value (pure Python, no numpy)."""
    check_word_order(word_order)
    first, second = (int(w) for w in words)
    high, low = (first, second) if word_order == "ABCD" else (second, first)
    return (high << 16) | low


def u32_to_words(value: int, word_order: str = "ABCD") -> list[int]:
    """One unsigned 32-bit value to two register words (pure Python, no numpy)."""
    check_word_order(word_order)
    value = int(value)
    if not 0 <= value <= 0xFFFFFFFF:
        raise LimitError(f"value {value} does not fit an unsigned 32-bit register pair")
    high, low = value >> 16, value & 0xFFFF
    return [high, low] if word_order == "ABCD" else [low, high]


def words_to_i32(words, word_order: str = "ABCD") -> int:
    """Two register words to one signed 32-bit value (pure Python, no numpy)."""
    value = words_to_u32(words, word_order)
    return value - 2**32 if value >= 2**31 else value


def detect_word_order(words, magic: int) -> str:
    """Word order in which the two ``magic`` registers decode to ``magic``.

    Raises
    ------
    InputError
        Neither order gives the magic (not an mppf PLC, or a wrong register map).
    """
    for order in WORD_ORDERS:
        if len(words) == 2 and words_to_u32(words, order) == magic:
            return order
    raise InputError(
        f"registers {list(words)} are not the magic 0x{magic:08X} in either word order",
        hint="is this an mppf press PLC with the same register map?",
    )


def setpoint_crc32(upper_words, lower_words) -> int:
    """CRC-32 of the setpoint registers in use, as written.

    The CRC is the IEEE 802.3 CRC-32 (as ``zlib.crc32``, initial value 0xFFFFFFFF,
    reflected, final XOR 0xFFFFFFFF) over the bytes of the upper setpoint registers in
    use (``2 * rows * cols`` registers from ``upper_setpoints``, in address order)
    followed by those of the lower block, each register as two bytes, high byte first
    (as on the wire). It therefore depends on the word order.

    Parameters
    ----------
    upper_words, lower_words : sequence of int, (2 * rows * cols,)
        Register words in address order.

    Returns
    -------
    crc : int, 0..2**32-1
    """
    import numpy as np

    data = np.concatenate(
        [np.asarray(upper_words, dtype=np.int64).ravel(), np.asarray(lower_words, dtype=np.int64).ravel()]
    )
    if data.size and (data.min() < 0 or data.max() > 0xFFFF):
        raise InputError("register words must lie in 0..65535")
    return zlib.crc32(data.astype(">u2").tobytes()) & 0xFFFFFFFF


def auth_crc32(nonce: int, words) -> int:
    """The auth word of an owner's request: CRC-32 of the nonce and the request's other registers.

    The bytes are the nonce as 4 bytes, most significant first, then each register word as
    two bytes, high byte first (the same CRC-32 as :func:`setpoint_crc32`; no numpy).

    Parameters
    ----------
    nonce : int, 0..2**32-1
        The owner's nonce (the PLC's, from the CLAIM's ``claim_reply``).
    words : sequence of int, (n,)
        The request's registers in address order, without the auth registers.

    Returns
    -------
    int, 0..2**32-1
    """
    data = (int(nonce) & 0xFFFFFFFF).to_bytes(4, "big") + b"".join(int(w & 0xFFFF).to_bytes(2, "big") for w in words)
    return zlib.crc32(data) & 0xFFFFFFFF


def chunks(start: int, words, max_regs: int = 122) -> list[tuple[int, list[int]]]:
    """Split a write of ``words`` at register ``start`` into requests of at most ``max_regs``.

    Every chunk but the last has an even length, so with ``start`` even no int32
    (register pair) is split across two requests.

    Returns
    -------
    list of (address, words)
    """
    if max_regs < 2:
        raise InputError(f"max_regs must be at least 2, got {max_regs}")
    step = max_regs - (max_regs % 2)
    words = list(words)
    return [(start + i, words[i : i + step]) for i in range(0, len(words), step)]


def pack_bits(flags) -> list[int]:
    """Booleans (n,) to registers, 16 per register, least significant bit first."""
    import numpy as np

    bits = np.asarray(flags, dtype=bool).ravel()
    padded = np.zeros(-(-bits.size // 16) * 16, dtype=np.int64)
    padded[: bits.size] = bits
    weights = 1 << np.arange(16, dtype=np.int64)
    return (padded.reshape(-1, 16) @ weights).astype(int).tolist()


def unpack_bits(words, n: int):
    """Registers to ``n`` booleans (inverse of :func:`pack_bits`)."""
    import numpy as np

    arr = np.asarray(words, dtype=np.int64).ravel()
    bits = ((arr[:, None] >> np.arange(16)) & 1).astype(bool).ravel()
    if bits.size < n:
        raise InputError(f"{arr.size} registers hold {bits.size} bits, {n} needed")
    return bits[:n]
