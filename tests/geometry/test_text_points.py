"""Text point files (mppf.geometry.text_points): headers, comments, both separators, and each real-world
mistake refused by name with the file and the line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mppf.core.errors import FileFormatError
from mppf.geometry.text_points import parse_text, split_fields

PATH = Path("plate.csv")


@pytest.mark.parametrize("text", [
    "x,y,z\n1.5,2,3\n-4,5e1,6.25\n",
    "# exported by the scanner\n  1.5 2 3 \n\n-4\t50\t6.25   # a comment\n",
    "X Y Z intensity\n1.5 2 3 0.9\n-4 50 6.25 0.1\n",
])
def test_a_point_file_reads_past_its_header_and_comments(text):
    np.testing.assert_array_equal(parse_text(PATH, text.encode()), [[1.5, 2.0, 3.0], [-4.0, 50.0, 6.25]])


def test_a_utf8_byte_order_mark_is_read_past():
    assert parse_text(PATH, "\ufeff1,2,3\n".encode()).tolist() == [[1.0, 2.0, 3.0]]


@pytest.mark.parametrize(("data", "message", "line"), [
    ("x;y;z\n1,5;2,0;3,0\n".encode(), "separates its fields with semicolons and writes decimal commas", 2),
    (b"1,5 2,0 3,0\n", "writes decimal commas between spaces or tabs", 1),
    (b"-600,5,-450,0,27,6\n-601,5,-450,0,27,6\n", "6 comma-separated columns and not one decimal point", 1),
    (b'"1.0","2.0","3.0"\n', "writes its numbers in double quotes", 1),
    ("1,2,3\n".encode("utf-16"), "is UTF-16 text", None),
    (b"\x00\x01\x02binary", "is binary", None),
    (b"1,2\n3,4\n", "has 2 column(s)", 1),
    (b"1,2,3\n4,5\n", "has 2 column(s), expected 3 like the first data line", 2),
    (b"1,2,3\n4,five,6\n", "non-numeric field 'five' in column 2", 2),
    (b"1,2,3\n4,nan,6\n", "'nan' (NaN or infinite) in column 2", 2),
    (b"# only a comment\nx,y,z\n", "has no numeric data lines", None),
])
def test_each_mistake_is_named_with_the_file_and_the_line(data, message, line):
    with pytest.raises(FileFormatError) as caught:
        parse_text(PATH, data)
    assert message in caught.value.message and caught.value.path == PATH and caught.value.line == line
    assert caught.value.hint


def test_fields_are_comma_separated_else_whitespace_separated():
    assert split_fields(" 1, 2 ,3") == ["1", "2", "3"] and split_fields("1 \t2  3") == ["1", "2", "3"]
