"""The panel's settings object and its listening rule: the token stays out of logs, short tokens are refused."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from mppf.core.errors import InputError
from mppf.panel.config import (
    DEFAULT_HOST,
    DEFAULT_PORT,
    MIN_TOKEN_CHARS,
    PanelConfig,
    check_bind,
    default_audit_path,
    is_loopback,
)


def test_the_token_is_never_in_the_settings_repr(tmp_path):
    token = "s3cret-token-of-24-chars"
    config = PanelConfig(history_path=tmp_path / "history.sqlite", audit_path=tmp_path / "audit.sqlite", token=token)
    assert token not in repr(config) and token not in str(config)
    assert config.token == token


def test_settings_are_frozen_with_the_documented_defaults(tmp_path):
    config = PanelConfig(history_path=tmp_path / "h.sqlite", audit_path=tmp_path / "a.sqlite")
    assert (config.host, config.port, config.token, config.base, config.plc_url) == (DEFAULT_HOST, DEFAULT_PORT,
                                                                                    None, 1, None)
    assert is_loopback(config.host)
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.port = 80


def test_the_audit_log_is_looked_for_next_to_the_history():
    assert default_audit_path(Path("/srv/press/history.sqlite")) == Path("/srv/press/audit.sqlite")
    assert default_audit_path("plates.sqlite") == Path("audit.sqlite")


def test_a_token_of_the_minimum_length_is_accepted_one_shorter_refused_without_showing_it():
    check_bind("0.0.0.0", "x" * MIN_TOKEN_CHARS)
    short = "y" * (MIN_TOKEN_CHARS - 1)
    with pytest.raises(InputError) as caught:
        check_bind("127.0.0.1", short)  # even on loopback: a token that is given must be worth having
    message = str(caught.value)
    assert f"{MIN_TOKEN_CHARS - 1} characters" in message and short not in message


@pytest.mark.parametrize(("host", "loopback"), [(" 127.0.0.1 ", True), ("LOCALHOST", True), ("[::1]", True),
                                                ("127.0.0.1.nip.io", False), ("", False), ("::ffff:10.0.0.1", False)])
def test_loopback_is_decided_by_the_address_not_by_its_spelling(host, loopback):
    assert is_loopback(host) is loopback
