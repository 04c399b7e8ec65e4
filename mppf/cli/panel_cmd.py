"""``mppf panel``: the operator's panel, a local web server beside the press (thin over :mod:`mppf.panel`).

See ``docs/panel.md``. It listens on 127.0.0.1:8450 unless told otherwise; any other
address needs ``--token``. It reads the plate history, the audit log and the PLC, and
sends nothing to the press but STOP.
"""

from __future__ import annotations

import socket
from pathlib import Path

import click

from mppf.cli._common import console
from mppf.cli.history_cmd import history_option
from mppf.core.errors import InputError


def _check_port_free(host: str, port: int) -> None:
    """InputError when ``host:port`` cannot be bound (in use, or not an address of this computer)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host.strip("[]"), port))
        except OSError as exc:
            raise InputError(f"cannot serve the panel on {host}:{port}: {exc.strerror}",
                             hint="choose another --port, or stop the program using it") from None


@click.command("panel")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on; anything but loopback needs --token.")
@click.option("--port", type=click.IntRange(1, 65535), default=8450, show_default=True, help="TCP port.")
@click.option("--plc", "plc_url", metavar="URL",
              help="PLC to watch (tcp://HOST:PORT?unit=1) [default: the PLC a running 'mppf loop' or "
                   "'mppf press' drives, from the audit log; else the current plate's].")
@click.option("--press", "press_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Press description (TOML) [default: the current plate's, from the history].")
@click.option("--job", "job_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Show this job in 'Lay the plate' (for 'mppf press') instead of the history's next cycle.")
@history_option
@click.option("--audit", "audit_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Audit log [default: next to the history].")
@click.option("--token", envvar="MPPF_PANEL_TOKEN", metavar="TOKEN",
              help="Access token (at least 16 characters; or the MPPF_PANEL_TOKEN variable, which keeps it out "
                   "of the process list). Required on any address but loopback.")
def panel(host, port, plc_url, press_path, job_path, history_path, audit_path, token):
    """Serve the operator's panel: where to lay the plate, the live press, the loop, the history, STOP.

    One page per press, in a browser beside the press (a panel PC or a tablet). It reads
    the plate history, the audit log and the PLC, and sends nothing to the press but
    STOP (a software stop: every punch decelerates to a standstill; the e-stop stays the
    press's own). Ctrl-C ends it; the press is not touched.
    """
    from mppf.loop.history import default_history_path
    from mppf.model.press import load_press
    from mppf.panel.config import PanelConfig, check_bind, default_audit_path

    check_bind(host, token)
    if plc_url:
        from mppf.drivers.url import parse_plc_url

        parse_plc_url(plc_url)
    if job_path is not None:  # read, checked and its seal verified now: a job that cannot be pressed is not served
        from mppf.planning.job import load_job

        load_job(job_path)
    history_path = history_path or default_history_path()
    cfg = PanelConfig(history_path=history_path, audit_path=audit_path or default_audit_path(history_path),
                      plc_url=plc_url, press=load_press(press_path) if press_path else None, job_path=job_path,
                      host=host, port=port, token=token)
    _check_port_free(host, port)
    serve(cfg)


def serve(cfg) -> None:
    """Run the panel until Ctrl-C (uvicorn; the access log names paths only, never the token)."""
    import uvicorn

    from mppf.panel.app import create_app

    app = create_app(cfg)
    shown = f"[{cfg.host}]" if ":" in cfg.host else cfg.host
    console.print(f"mppf panel on http://{shown}:{cfg.port}/ ({'token required' if cfg.token else 'loopback, no token'}"
                  f"); history {cfg.history_path}; Ctrl-C to end", soft_wrap=True)
    uvicorn.run(app, host=cfg.host.strip("[]"), port=cfg.port, log_level="info", timeout_graceful_shutdown=1)
    console.print("mppf panel stopped")


COMMANDS = [panel]
