"""PLC URL parsing."""

import pytest

from mppf.drivers.url import parse_plc_url
from mppf.core.errors import InputError


def test_tcp_url_with_defaults_and_options():
    url = parse_plc_url("tcp://127.0.0.1:5020?unit=3&timeout=0.5&retries=1")
    assert (url.scheme, url.host, url.port, url.unit, url.timeout_s, url.retries) == (
        "tcp", "127.0.0.1", 5020, 3, 0.5, 1)
    plain = parse_plc_url("tcp://plc-7")
    assert (plain.port, plain.unit) == (502, 1)
    assert str(plain) == "tcp://plc-7:502?unit=1"


def test_rtu_url_and_char_time():
    url = parse_plc_url("rtu:///dev/ttyUSB0?baud=115200&parity=e&stopbits=1&unit=2&timeout=2")
    assert (url.scheme, url.device, url.baud, url.parity, url.stopbits, url.unit, url.timeout_s) == (
        "rtu", "/dev/ttyUSB0", 115200, "E", 1, 2, 2.0)
    # 8E1: start + 8 data + parity + stop = 11 bits per byte
    assert url.char_time_s == pytest.approx(11 / 115200)
    assert parse_plc_url("rtu:///dev/ttyS0?parity=N&stopbits=2").char_time_s == pytest.approx(11 / 19200)


@pytest.mark.parametrize(
    "text, words",
    [
        ("", "non-empty"),
        ("http://plc:502", "unknown scheme"),
        ("tcp://", "no host"),
        ("tcp://plc:notaport", "cannot be parsed"),
        ("tcp://plc:0", "port 0"),
        ("tcp://plc:502/path", "unexpected path"),
        ("tcp://plc?baud=9600", "unknown option"),
        ("tcp://plc?unit=0", "unit=0"),
        ("tcp://plc?unit=1&unit=2", "more than once"),
        ("tcp://plc?timeout=fast", "not a number"),
        ("rtu://host/dev/ttyS0", "three slashes"),
        ("rtu://", "no serial device"),
        ("rtu:///dev/ttyS0?baud=12345", "standard rate"),
        ("rtu:///dev/ttyS0?parity=X", "parity"),
        ("rtu:///dev/ttyS0?stopbits=3", "stopbits=3"),
    ],
)
def test_bad_urls_say_what_is_wrong(text, words):
    with pytest.raises(InputError) as info:
        parse_plc_url(text)
    assert words in str(info.value)
