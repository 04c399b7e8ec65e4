"""The operator's panel as an ASGI application (Starlette, Jinja2 templates, server-sent events).

:func:`create_app` wires the views (:mod:`mppf.panel.views`), the live PLC reader
(:class:`mppf.panel.plc.PlcMonitor`) and the guard (:mod:`mppf.panel.security`):

==================  =====================================================================
``/place``          Lay the plate (the job of the next cycle, or ``--job``)
``/live``           Live press: state, fault, refusal, link, both matrices, progress
``/loop``           Loop: cycle and state, verdict, deviation maps, convergence, correction
``/history``        Plates; ``/history/ID`` a plate's cycles, events and reports
``/events``         server-sent events: the live snapshot four times a second
``/api/live``       the live snapshot once (JSON)
``POST /stop``      STOP to the press (software stop; the only command the panel sends)
==================  =====================================================================

Every view is also served as a fragment (header ``X-Fragment: 1``) that the page reloads
when the history changes.
"""

from __future__ import annotations

import asyncio
import html
import json
import threading
import time
from contextlib import asynccontextmanager
from urllib.parse import parse_qs

from jinja2 import Environment, PackageLoader, select_autoescape
from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import FileResponse, HTMLResponse, JSONResponse, RedirectResponse, StreamingResponse
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from mppf import __version__
from mppf.core.errors import InputError, LinkError, MppfError, PressFault
from mppf.drivers.audit import AuditLog
from mppf.panel import views
from mppf.panel.config import PanelConfig
from mppf.panel.plc import PERIOD_S, PlcMonitor, send_stop
from mppf.panel.security import COOKIE, Guard, session_value, token_matches
from mppf.panel.sources import HistoryReader, PlcTarget, next_cycle, report_files, running_plc

STOP_REASON = "software STOP from the operator's panel"


def locator(cfg: PanelConfig):
    """Where the PLC is: ``--plc``, else the running master's (audit log), else the current plate's."""

    def locate() -> PlcTarget | None:
        if cfg.plc_url:
            return PlcTarget(cfg.plc_url, "given with --plc")
        found = running_plc(cfg.audit_path)
        if found is not None:
            return found
        current = HistoryReader(cfg.history_path).current()
        url = current[0].settings.get("plc") if current else None
        return PlcTarget(url, f"recorded with plate {current[0].plate_id}") if url else None

    return locate


class _Brief:
    """The loop's one-line state for the status bar and the history's revision, read at most once a second."""

    def __init__(self, cfg: PanelConfig):
        self.reader = HistoryReader(cfg.history_path)
        self.rev, self.text, self.read_s = "", "", -1.0
        self._lock = threading.Lock()

    def get(self) -> tuple[str, str]:
        with self._lock:
            if time.monotonic() - self.read_s >= 1.0:
                self.read_s = time.monotonic()
                try:
                    rev = self.reader.revision()
                    if rev != self.rev:
                        self.rev, self.text = rev, self._read()
                except MppfError as exc:
                    self.rev, self.text = "error", f"history: {exc.message}"
            return self.rev, self.text

    def _read(self) -> str:
        current = self.reader.current()
        if current is None:
            return ""
        plate, cycles = current
        cycle = next_cycle(cycles)
        step = f", step {cycle.step_started} of {len(cycle.steps)}" if cycle.state == "pressing" else ""
        return f"plate {plate.plate_id} ({plate.status}): cycle {cycle.cycle} {cycle.state}{step}"


class _Panel:
    """The handlers of the panel's routes for one press (see the module docstring)."""

    def __init__(self, cfg: PanelConfig, monitor: PlcMonitor | None):
        self.cfg = cfg
        self.env = Environment(loader=PackageLoader("mppf.panel", "templates"), autoescape=select_autoescape(["html"]))
        self.locate = locator(cfg)
        self.monitor = monitor or PlcMonitor(self.locate, cfg.press or self.find_press(), find_press=self.find_press,
                                             base=cfg.base)
        self.brief = _Brief(cfg)

    def find_press(self):
        return views.press_of(self.cfg, HistoryReader(self.cfg.history_path))

    def page(self, request: Request, name: str, ctx: dict) -> HTMLResponse:
        """A view rendered in the page, or alone (header ``X-Fragment: 1``)."""
        press = self.monitor.press
        common = {"layout": "fragment.html" if request.headers.get("x-fragment") == "1" else "base.html",
                  "version": __version__, "press_name": press.name if press else "",
                  "login": self.cfg.token is not None, "base": self.cfg.base}
        text = self.env.get_template(name).render(**{**common, **ctx})
        return HTMLResponse(text, headers={"Cache-Control": "no-store"})

    # -- views --------------------------------------------------------------------------

    async def home(self, request):
        return RedirectResponse("/live", status_code=303)

    async def place(self, request):
        try:
            ctx = await run_in_threadpool(views.place, self.cfg, request.query_params.get("plate"),
                                          request.query_params.get("section"))
        except InputError as exc:  # an unknown or malformed plate id (e.g. a path): said, never a traceback
            return HTMLResponse(f"<p>{html.escape(exc.message)}</p>", 404)
        return self.page(request, "place.html", ctx)

    async def live(self, request):
        return self.page(request, "live.html", views.live(self.cfg, self.monitor.press))

    async def loop(self, request):
        try:
            ctx = await run_in_threadpool(views.loop, self.cfg, request.query_params.get("plate"))
        except InputError as exc:
            return HTMLResponse(f"<p>{html.escape(exc.message)}</p>", 404)
        return self.page(request, "loop.html", ctx)

    async def history(self, request):
        return self.page(request, "history.html", await run_in_threadpool(views.history, self.cfg))

    async def plate(self, request):
        try:
            ctx = await run_in_threadpool(views.plate, self.cfg, request.path_params["plate_id"])
        except InputError as exc:
            return HTMLResponse(f"<p>{html.escape(exc.message)}</p>", 404)
        return self.page(request, "plate.html", ctx)

    async def report(self, request):
        try:
            record, _ = HistoryReader(self.cfg.history_path).plate(request.path_params["plate_id"])
        except InputError:
            return HTMLResponse("no such plate", 404)
        path = {p.name: p for p in report_files(record)}.get(request.path_params["name"])
        return FileResponse(path) if path else HTMLResponse("no such report", 404)

    # -- the live press -----------------------------------------------------------------

    def snapshot(self) -> dict:
        rev, text = self.brief.get()
        return {"live": self.monitor.snapshot(), "history_rev": rev, "loop": text}

    async def api_live(self, request):
        return JSONResponse(await run_in_threadpool(self.snapshot), headers={"Cache-Control": "no-store"})

    async def events(self, request):
        async def stream():
            while not await request.is_disconnected():
                yield f"data: {json.dumps(await run_in_threadpool(self.snapshot))}\n\n"
                await asyncio.sleep(PERIOD_S)

        return StreamingResponse(stream(), media_type="text/event-stream",
                                 headers={"Cache-Control": "no-store", "X-Accel-Buffering": "no"})

    # -- STOP -----------------------------------------------------------------------------

    async def stop(self, request):
        """STOP to the PLC watched, else (it does not answer) to the one a running master drives now."""
        try:
            url = await run_in_threadpool(self._stop)
        except LinkError as exc:
            return self._stop_reply(False, f"STOP NOT SENT: {exc.message}; stop the press at the machine", 502)
        except PressFault as exc:
            return self._stop_reply(False, f"STOP NOT CONFIRMED: {exc.message}; stop the press at the machine", 502)
        except MppfError as exc:
            return self._stop_reply(False, f"STOP refused: {exc.message}", 502)
        if url is None:
            return self._stop_reply(False, "STOP NOT SENT: no PLC known to the panel; stop the press at the machine",
                                    503)
        return self._stop_reply(True, f"STOP sent to {url}", 200)

    def _stop(self) -> str | None:
        """Send STOP; the URL it went to (None: no PLC known)."""
        watched = self.monitor.target
        with AuditLog(self.cfg.audit_path) as audit:
            if watched is not None:
                try:
                    send_stop(watched.url, audit, STOP_REASON)
                    return watched.url
                except LinkError:
                    found = self.locate()  # the PLC watched is gone: perhaps a new dry run drives another
                    if found is None or found.url == watched.url:
                        raise
            else:
                found = self.locate()
                if found is None:
                    return None
            send_stop(found.url, audit, STOP_REASON)
            return found.url

    @staticmethod
    def _stop_reply(ok: bool, message: str, status: int) -> JSONResponse:
        return JSONResponse({"ok": ok, "message": message}, status_code=status)

    # -- the token ------------------------------------------------------------------------

    async def login(self, request):
        if request.method == "GET":
            return self.page(request, "login.html", {"view": "login", "failed": False})
        form = parse_qs((await request.body()).decode(errors="replace"))
        if token_matches(self.cfg.token, (form.get("token") or [""])[0]):
            response = RedirectResponse("/live", status_code=303)
            response.set_cookie(COOKIE, session_value(self.cfg.token), httponly=True, samesite="strict", path="/")
            return response
        return self.page(request, "login.html", {"view": "login", "failed": True})


def create_app(cfg: PanelConfig, *, monitor: PlcMonitor | None = None) -> Starlette:
    """The panel for one press.

    Parameters
    ----------
    cfg : PanelConfig
    monitor : PlcMonitor, optional
        The live PLC reader (default: one on :func:`locator`, started and stopped with the app).
    """
    panel = _Panel(cfg, monitor)

    @asynccontextmanager
    async def lifespan(app):
        panel.monitor.start()
        try:
            yield
        finally:
            panel.monitor.close()

    routes = [
        Route("/", panel.home), Route("/place", panel.place), Route("/live", panel.live), Route("/loop", panel.loop),
        Route("/history", panel.history), Route("/history/{plate_id}", panel.plate),
        Route("/reports/{plate_id}/{name}", panel.report), Route("/events", panel.events),
        Route("/api/live", panel.api_live), Route("/stop", panel.stop, methods=["POST"]),
        Route("/login", panel.login, methods=["GET", "POST"]),
        Mount("/static", StaticFiles(packages=[("mppf.panel", "static")]), name="static"),
    ]
    app = Starlette(routes=routes, lifespan=lifespan)
    app.add_middleware(Guard, token=cfg.token)
    app.state.monitor = panel.monitor
    return app
