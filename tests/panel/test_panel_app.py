"""The panel's pages, fragments and guard, through Starlette's test client (no browser, no PLC)."""

from __future__ import annotations

import pytest
from starlette.testclient import TestClient

from panel_helpers import layout_job, record_loop

from mppf.panel.app import create_app
from mppf.panel.config import PanelConfig
from mppf.panel.security import COOKIE
from mppf.model.press import example_press_path, load_press

TOKEN = "s3cret-token-for-the-panel-0123"
LOCAL = "http://127.0.0.1:8450"


class FakeMonitor:
    """Stands in for the PLC reader: a fixed snapshot, no PLC."""

    target = None

    def __init__(self, snapshot=None, press=None):
        self.press = press if press is not None else load_press(example_press_path())
        self._snapshot = snapshot or {"state": "LINK LOST", "link": {"ok": False, "url": "", "error": "test"}}
        self.started = self.closed = False

    def start(self):
        self.started = True
        return self

    def close(self):
        self.closed = True

    def snapshot(self):
        return self._snapshot


@pytest.fixture
def plate_history(tmp_path):
    job = layout_job()
    record_loop(tmp_path / "history.sqlite", job, tmp_path / "plates" / "B12-P3", measured=2).close()
    return tmp_path / "history.sqlite"


def _client(history_path, **cfg):
    config = PanelConfig(history_path=history_path, audit_path=history_path.parent / "audit.sqlite", **cfg)
    return TestClient(create_app(config, monitor=FakeMonitor()), base_url=LOCAL)


def test_every_view_renders_from_the_history(plate_history):
    with _client(plate_history) as client:
        place = client.get("/place")
        assert place.status_code == 200
        assert "plate <b>B12-P3</b>, cycle <b>3</b> (planned)" in place.text
        assert place.text.count('class="mark-row"') == 1 and 'data-corner="D"' in place.text
        assert "-1200" in place.text and "cut-outline" in place.text
        loop = client.get("/loop")
        assert "OUT OF TOLERANCE" in loop.text and "the next cycle corrects the strokes" in loop.text
        assert "cycle 2: deviation at the punches" in loop.text and "cycle 1: deviation at the punches" in loop.text
        assert "Next correction" in loop.text and "2 punch(es) held at a limit" in loop.text
        assert "R1 C1" in loop.text  # the largest deviations are at the corners, named as the press names them
        history = client.get("/history")
        assert "/history/B12-P3" in history.text
        plate = client.get("/history/B12-P3")
        assert plate.text.count("<tr><td class=\"num\">") == 3 and "corrected" in plate.text
        live = client.get("/live")
        for side in ("upper", "lower"):
            for kind in ("target", "actual"):
                assert f'id="{side}-{kind}-r16-c24"' in live.text
        assert "STOP" in live.text and "software stop" in live.text
        assert "emergency" not in (place.text + loop.text + history.text + live.text).lower()


def test_the_loop_view_shows_the_wait_for_the_scan(tmp_path):
    from mppf.loop.history import History

    job = layout_job()
    record_loop(tmp_path / "history.sqlite", job, tmp_path / "work", measured=1).close()
    with History(tmp_path / "history.sqlite") as history:
        history.mark_step_started("B12-P3", 2, 1)
        with _client(tmp_path / "history.sqlite") as client:
            assert "cycle <b id=\"loop-cycle\">2</b>: <b id=\"loop-state\">pressing</b> step 1 of 1" in \
                client.get("/loop").text
            assert client.get("/api/live").json()["loop"] == "plate B12-P3 (active): cycle 2 pressing, step 1 of 1"
            upper, lower = job.steps[0].setpoints_mm(job.press)
            result = {"sequence": 2, "max_error_mm": 0.0, "duration_s": 1.0, "actual_upper_mm": upper.tolist(),
                      "actual_lower_mm": lower.tolist()}
            history.mark_step_done("B12-P3", 2, 1, result)
            history.mark_pressed("B12-P3", 2)
            text = client.get("/loop").text
    assert "WAITING FOR THE SCAN of cycle 2 for" in text
    assert "cycle 1: largest |dev| <b>6.00</b> mm" in text


def test_fragments_are_the_view_alone(plate_history):
    with _client(plate_history) as client:
        fragment = client.get("/loop", headers={"X-Fragment": "1"})
        assert fragment.status_code == 200
        assert "<html" not in fragment.text and "OUT OF TOLERANCE" in fragment.text


def test_an_empty_history_is_reported_not_created(tmp_path):
    path = tmp_path / "none" / "history.sqlite"
    with _client(path) as client:
        assert "no plate in the history" in client.get("/place").text
        assert "No plate in the history" in client.get("/loop").text
        assert "No history at" in client.get("/history").text
        assert client.get("/history/X").status_code == 404
    assert not path.exists()


def test_a_job_given_is_what_lay_the_plate_shows(tmp_path):
    from mppf.planning.job import save_job

    job_path = save_job(layout_job(), tmp_path / "job.json")
    with _client(tmp_path / "history.sqlite", job_path=job_path) as client:
        text = client.get("/place").text
    assert str(job_path) in text and 'data-corner="A"' in text


def test_the_live_snapshot_and_the_stream(plate_history):
    with _client(plate_history) as client:
        doc = client.get("/api/live").json()
        assert doc["live"]["state"] == "LINK LOST"
        assert doc["loop"] == "plate B12-P3 (active): cycle 3 planned"


def test_only_loopback_host_names_without_a_token(plate_history):
    with _client(plate_history) as client:
        assert client.get("/live", headers={"Host": "evil.example:8450"}).status_code == 403
        assert client.get("/live", headers={"Host": "localhost:8450"}).status_code == 200


def test_stop_refuses_a_request_from_another_site(plate_history):
    with _client(plate_history) as client:
        reply = client.post("/stop", headers={"Origin": "http://evil.example"})
        assert reply.status_code == 403


def test_stop_without_a_known_plc_says_it_was_not_sent(plate_history):
    with _client(plate_history) as client:
        reply = client.post("/stop", headers={"Origin": LOCAL})
    assert reply.status_code == 503 and reply.json()["message"].startswith("STOP NOT SENT")


def test_stop_to_a_plc_that_does_not_answer_says_it_was_not_sent(plate_history):
    with _client(plate_history, plc_url="tcp://127.0.0.1:9?unit=1") as client:
        reply = client.post("/stop")
    assert reply.status_code == 502
    assert "STOP NOT SENT" in reply.json()["message"] and "stop the press at the machine" in reply.json()["message"]


def test_with_a_token_everything_but_the_login_needs_it(plate_history):
    with _client(plate_history, token=TOKEN) as client:
        assert client.get("/live", headers={"Accept": "text/html"}, follow_redirects=False).headers["location"] == \
            "/login"
        assert client.get("/api/live").status_code == 401
        assert client.post("/stop").status_code == 401
        assert client.get("/events").status_code == 401
        assert client.get("/static/panel.css").status_code == 200
        assert "Wrong token" in client.post("/login", content="token=nope",
                                            headers={"Content-Type": "application/x-www-form-urlencoded"}).text
        login = client.post("/login", content=f"token={TOKEN}", follow_redirects=False,
                            headers={"Content-Type": "application/x-www-form-urlencoded"})
        assert login.status_code == 303
        cookie = login.cookies[COOKIE]
        assert TOKEN not in cookie and TOKEN not in str(login.headers)
        assert "httponly" in login.headers["set-cookie"].lower()
        page = client.get("/live")
        assert page.status_code == 200 and TOKEN not in page.text
        assert client.get("/api/live").status_code == 200
    with _client(plate_history, token=TOKEN) as client:
        assert client.get("/api/live", headers={"Authorization": f"Bearer {TOKEN}"}).status_code == 200
        assert client.get("/api/live", headers={"Authorization": "Bearer wrong"}).status_code == 401
        client.cookies.set(COOKIE, "forged")
        assert client.get("/api/live").status_code == 401


def test_with_a_token_any_host_name_is_served(plate_history):
    with _client(plate_history, token=TOKEN) as client:
        reply = client.get("/api/live", headers={"Host": "panel.shop:8450", "Authorization": f"Bearer {TOKEN}"})
        assert reply.status_code == 200


def test_the_monitor_lives_with_the_app(plate_history):
    monitor = FakeMonitor()
    config = PanelConfig(history_path=plate_history, audit_path=plate_history.parent / "audit.sqlite")
    with TestClient(create_app(config, monitor=monitor), base_url=LOCAL):
        assert monitor.started and not monitor.closed
    assert monitor.closed


def test_the_token_is_not_in_the_settings_repr(tmp_path):
    config = PanelConfig(history_path=tmp_path / "h", audit_path=tmp_path / "a", token=TOKEN)
    assert TOKEN not in repr(config)


def test_a_plate_id_that_is_a_path_is_answered_404_without_a_traceback(plate_history, caplog):
    with _client(plate_history) as client:
        for view in ("/place", "/loop"):
            response = client.get(view, params={"plate": "../../x"})
            assert response.status_code == 404 and "plate &#x27;../../x&#x27; is not in the history" in response.text
    assert "Traceback" not in caplog.text


def test_a_job_whose_seal_is_broken_is_not_shown_as_the_instruction(tmp_path):
    import json

    from mppf.planning.job import save_job

    job_path = save_job(layout_job(), tmp_path / "job.json")
    doc = json.loads(job_path.read_text())
    doc["plate"]["outline_mm"][0][0] += 300.0  # the placement moved by hand
    job_path.write_text(json.dumps(doc))
    with _client(tmp_path / "history.sqlite", job_path=job_path) as client:
        text = client.get("/place").text
    assert "changed after it was sealed" in text and "plate layout" in text and 'data-corner="A"' not in text
