"""The panel's guard on its own, in front of a small ASGI app: Host, Origin, token, cookie."""

from __future__ import annotations

import pytest
from starlette.applications import Starlette
from starlette.responses import PlainTextResponse
from starlette.routing import Route
from starlette.testclient import TestClient

from mppf.panel.security import COOKIE, OPEN_PATHS, Guard, session_value, token_matches

TOKEN = "a-long-enough-token-0123"
LOCAL = "http://127.0.0.1:8450"


def _app() -> Starlette:
    async def hello(request):
        return PlainTextResponse("behind the guard")
    return Starlette(routes=[Route("/", hello, methods=["GET", "POST"]), Route("/login", hello),
                             Route("/static/panel.css", hello)])


def _client(token: str | None, base_url: str = LOCAL) -> TestClient:
    return TestClient(Guard(_app(), token), base_url=base_url)


def test_the_session_cookie_is_a_keyed_hash_never_the_token():
    value = session_value(TOKEN)
    assert TOKEN not in value and len(value) == 64
    assert value == session_value(TOKEN) and value != session_value(TOKEN + "x")


@pytest.mark.parametrize(("given", "expected"), [(TOKEN, True), (TOKEN + " ", False), ("", False), (TOKEN[:-1], False)])
def test_token_matches_only_the_exact_token(given, expected):
    assert token_matches(TOKEN, given) is expected
    assert token_matches(None, given) is False  # no token set: nothing matches


def test_without_a_token_only_loopback_host_names_are_answered():
    with _client(None) as client:
        assert client.get("/").text == "behind the guard"
        assert client.get("/", headers={"Host": "[::1]:8450"}).status_code == 200
        refused = client.get("/", headers={"Host": "rebound.example:8450"})
        assert refused.status_code == 403 and "'rebound.example'" in refused.text


def test_a_post_from_another_origin_is_refused_and_from_its_own_origin_served():
    with _client(None) as client:
        assert client.post("/", headers={"Origin": "http://evil.example"}).status_code == 403
        assert client.post("/", headers={"Origin": LOCAL}).status_code == 200
        assert client.post("/").status_code == 200  # no Origin header (curl, a script): the Host check holds


def test_with_a_token_a_page_asks_for_the_login_and_an_api_call_gets_401():
    with _client(TOKEN, base_url="http://panel.shop:8450") as client:
        page = client.get("/", headers={"Accept": "text/html"}, follow_redirects=False)
        assert page.status_code == 303 and page.headers["location"] == "/login"
        api = client.get("/", headers={"Accept": "application/json"})
        assert api.status_code == 401 and api.json()["ok"] is False
        for path in ("/login", "/static/panel.css"):  # OPEN_PATHS
            assert any(path.startswith(p) for p in OPEN_PATHS)
            assert client.get(path).status_code == 200


@pytest.mark.parametrize(("header", "served"), [
    ({"Authorization": f"Bearer {TOKEN}"}, True),
    ({"Authorization": f"bearer  {TOKEN}"}, True),
    ({"Authorization": "Bearer wrong-token-but-long-enough"}, False),
    ({"Cookie": f"{COOKIE}={session_value(TOKEN)}"}, True),
    ({"Cookie": f"{COOKIE}={TOKEN}"}, False),  # the token itself is not a session
    ({"Cookie": f"{COOKIE}={session_value('another-long-token-456789')}"}, False),
    ({"Cookie": 'broken="'}, False),  # a malformed cookie header is no session, not an error
])
def test_a_request_is_served_with_the_bearer_token_or_the_session_cookie(header, served):
    guard = Guard(_app(), TOKEN)
    assert guard.authorised({k.lower(): v for k, v in header.items()}) is served
    with _client(TOKEN, base_url="http://panel.shop:8450") as client:
        client.cookies.clear()
        reply = client.get("/", headers=header)
        assert (reply.status_code == 200) is served
