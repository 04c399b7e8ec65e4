"""Who may use the panel: the token gate, the Host and Origin checks.

:class:`Guard` is an ASGI middleware in front of the whole panel:

- **Host** (every request): without a token the panel listens on loopback only, and it
  answers only requests addressed to a loopback name (``127.0.0.1``, ``localhost``,
  ``[::1]``), so a web page elsewhere cannot reach it by DNS rebinding.
- **Origin** (every POST): a form or script of another site cannot press STOP or log in.
- **Token** (when one is set): every page, the live stream and STOP need the session
  cookie that ``POST /login`` sets after checking the token, or an
  ``Authorization: Bearer <token>`` header. The cookie holds an HMAC of the token, never
  the token; the token travels only in the login form's body or that header, never in a
  URL, so it cannot appear in an access log.
"""

from __future__ import annotations

import hashlib
import hmac
from http.cookies import SimpleCookie
from urllib.parse import urlsplit

from starlette.responses import JSONResponse, PlainTextResponse, RedirectResponse

from mppf.panel.config import is_loopback

COOKIE = "mppf_panel"
OPEN_PATHS = ("/login", "/static/")
"""Paths served without the token (the login page and its style sheet)."""


def session_value(token: str) -> str:
    """The cookie value for ``token`` (an HMAC: the cookie never holds the token itself)."""
    return hmac.new(token.encode(), b"mppf panel session v1", hashlib.sha256).hexdigest()


def token_matches(token: str | None, given: str) -> bool:
    """Constant-time comparison of a given token with the panel's."""
    return token is not None and hmac.compare_digest(token.encode(), given.encode())


def _headers(scope) -> dict[str, str]:
    return {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope.get("headers", [])}


def _host_name(host_header: str) -> str:
    return urlsplit(f"//{host_header}").hostname or ""


class Guard:
    """ASGI middleware: Host, Origin and token checks (see the module docstring).

    Parameters
    ----------
    app
        The ASGI application behind it.
    token : str or None
        The panel's token (None: no login; loopback Host names only).
    """

    def __init__(self, app, token: str | None):
        self.app = app
        self._token = token
        self._session = session_value(token) if token else None

    def authorised(self, headers: dict[str, str]) -> bool:
        """True without a token, or with the session cookie or the bearer token."""
        if self._session is None:
            return True
        auth = headers.get("authorization", "")
        if auth.lower().startswith("bearer ") and token_matches(self._token, auth[7:].strip()):
            return True
        cookie = SimpleCookie()
        try:
            cookie.load(headers.get("cookie", ""))
        except Exception:  # noqa: BLE001 - a malformed cookie header is simply no session
            return False
        got = cookie.get(COOKIE)
        return got is not None and hmac.compare_digest(got.value, self._session)

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        headers = _headers(scope)
        refusal = self._refusal(scope, headers)
        if refusal is not None:
            return await refusal(scope, receive, send)
        return await self.app(scope, receive, send)

    def _refusal(self, scope, headers):
        """The response refusing this request, or None to let it through."""
        host = _host_name(headers.get("host", ""))
        if self._token is None and not is_loopback(host):
            return PlainTextResponse(f"this panel answers only on loopback addresses, not {host!r}", status_code=403)
        origin = headers.get("origin")
        if scope["method"] == "POST" and origin and urlsplit(origin).netloc != headers.get("host", ""):
            return PlainTextResponse("cross-site request refused", status_code=403)
        path = scope["path"]
        if any(path == p or (p.endswith("/") and path.startswith(p)) for p in OPEN_PATHS) or self.authorised(headers):
            return None
        if scope["method"] == "GET" and "text/html" in headers.get("accept", ""):
            return RedirectResponse("/login", status_code=303)
        return JSONResponse({"ok": False, "message": "the panel needs its token: log in first"}, status_code=401)
