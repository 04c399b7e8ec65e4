"""What ``mppf panel`` serves, and the rule for where it may listen.

:class:`PanelConfig` is the one settings object of the panel (frozen; the token is never
part of its ``repr``, so it cannot leak into a log or a traceback). :func:`check_bind`
refuses to listen on any address other than loopback without a token.
"""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass, field
from pathlib import Path

from mppf.core.errors import InputError
from mppf.model.press import PressConfig

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8450
MIN_TOKEN_CHARS = 16
"""Shortest token accepted (a guessable token on a shop network is no protection)."""


@dataclass(frozen=True)
class PanelConfig:
    """Settings of one panel (one press).

    Attributes
    ----------
    history_path, audit_path : Path
        The plate history and the audit log (read; STOP is appended to the audit log).
    plc_url : str or None
        The PLC to watch; None: the one a running ``mppf loop`` / ``mppf press`` drives
        (:func:`mppf.panel.sources.running_plc`), else the plate's recorded PLC.
    press : PressConfig or None
        The press description (matrix size, pitch, tolerance); None: taken from the history.
    job_path : Path or None
        A job file to show in "Lay the plate" instead of the history's next cycle.
    host, port : str, int
        Where the panel listens (recorded for the messages and the Host check).
    token : str or None
        The access token (None: loopback only, no login).
    base : int
        First row / column number of punch names (1: "R1 C1" is the first punch).
    """

    history_path: Path
    audit_path: Path
    plc_url: str | None = None
    press: PressConfig | None = None
    job_path: Path | None = None
    host: str = DEFAULT_HOST
    port: int = DEFAULT_PORT
    token: str | None = field(default=None, repr=False)
    base: int = 1


def is_loopback(host: str) -> bool:
    """True for ``localhost`` and addresses in 127.0.0.0/8 or ``::1``."""
    host = host.strip().strip("[]")
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def check_bind(host: str, token: str | None) -> None:
    """Refuse a non-loopback address without a token, and a short token.

    Raises
    ------
    InputError
        ``host`` is not a loopback address and no token is given, or the token is shorter
        than :data:`MIN_TOKEN_CHARS` (the message never contains the token).
    """
    if token is not None and len(token) < MIN_TOKEN_CHARS:
        raise InputError(f"the panel token is too short: {len(token)} characters, at least {MIN_TOKEN_CHARS} needed",
                         hint="use a long random token, e.g. from 'python3 -c \"import secrets; "
                              "print(secrets.token_urlsafe(24))\"'")
    if not is_loopback(host) and not token:
        raise InputError(
            f"refusing to serve the panel on {host}: it is not a loopback address and no --token was given "
            "(the panel can STOP the press, so on a network it must ask for a token)",
            hint="give --token (or set MPPF_PANEL_TOKEN), or serve on 127.0.0.1",
        )


def default_audit_path(history_path: Path) -> Path:
    """The audit log next to the history (where ``mppf loop`` writes it by default)."""
    return Path(history_path).parent / "audit.sqlite"
