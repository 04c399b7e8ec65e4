"""The one exception hierarchy (mppf.core.errors): the README's exit codes, the built-in each one also is,
messages with their hint."""

from __future__ import annotations

import pytest

from mppf.core.errors import (
    EXIT_BUG,
    EXIT_CANCELLED,
    EXIT_INPUT,
    EXIT_LINK,
    EXIT_PRESS,
    Cancelled,
    ConfigError,
    FileFormatError,
    GeometryError,
    InputError,
    LimitError,
    LinkError,
    MppfError,
    PlcError,
    PressFault,
    PressRefused,
)


@pytest.mark.parametrize(("error", "code", "builtin"), [
    (MppfError, 1, Exception), (InputError, 2, ValueError), (ConfigError, 2, ValueError),
    (GeometryError, 2, ValueError), (LimitError, 2, ValueError), (LinkError, 3, ConnectionError),
    (PlcError, 4, Exception), (PressFault, 4, Exception), (PressRefused, 4, Exception), (Cancelled, 130, Exception),
])
def test_each_error_has_the_readme_s_exit_code_and_is_its_builtin_too(error, code, builtin):
    caught = error("what happened", hint="what to do")
    assert caught.exit_code == code and isinstance(caught, MppfError) and isinstance(caught, builtin)
    assert str(caught) == "what happened (what to do)" and caught.message == "what happened"


def test_the_exit_codes_and_the_siblings():
    assert (EXIT_BUG, EXIT_INPUT, EXIT_LINK, EXIT_PRESS, EXIT_CANCELLED) == (1, 2, 3, 4, 130)
    assert not issubclass(PlcError, LinkError)  # a refusal with the link fine is not a failed link
    assert issubclass(PressRefused, PressFault) and not issubclass(LinkError, ValueError)


def test_a_file_format_error_names_the_file_and_the_line():
    with_line = FileFormatError("plate.csv", "3 columns expected, got 2", line=7, hint="check the delimiter")
    assert str(with_line) == "plate.csv, line 7: 3 columns expected, got 2 (check the delimiter)"
    assert (with_line.path, with_line.line, with_line.exit_code) == ("plate.csv", 7, 2)
    assert str(FileFormatError("scan.ply", "not a PLY file")) == "scan.ply: not a PLY file"
    assert str(InputError("no hint")) == "no hint" and InputError("no hint").hint is None
