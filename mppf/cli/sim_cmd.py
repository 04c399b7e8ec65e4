"""``mppf sim``: run the simulated press PLC in the foreground (see docs/simulator.md)."""

from __future__ import annotations

import math
import time

import click

from mppf.cli._common import console
from mppf.core.errors import InputError
from mppf.planning.press import example_press_path, load_press


def _status_line(sim) -> str:
    flags = sim.status_bits()
    on = [name for name, value in flags.items() if value] or ["-"]
    text = " ".join(on)
    code = sim.fault_code()
    if code:
        text += f" | fault {sim.plc.map.fault_text(code)}"
    upper, lower = sim.actual_positions_mm()
    return (
        f"{time.strftime('%H:%M:%S')} {text} | seq {sim.plc.ack_sequence}/{sim.plc.motion_sequence} | "
        f"upper {upper.min():.1f}..{upper.max():.1f} mm, lower {lower.min():.1f}..{lower.max():.1f} mm"
    )


@click.command("sim")
@click.option("--host", default=None, help="Address to bind (default 127.0.0.1; 0.0.0.0 = every interface).")
@click.option("--port", type=click.IntRange(0, 65535), default=None, help="TCP port (default 5020; 0 = a free port).")
@click.option(
    "--rtu",
    "rtu_port",
    metavar="PORT",
    default=None,
    help="Serve Modbus RTU on this serial device instead of TCP; 'pty' makes a pseudo-terminal pair.",
)
@click.option("--baud", type=click.IntRange(300, 4_000_000), default=115200, show_default=True, help="RTU baud rate.")
@click.option("--parity", type=click.Choice(["N", "E", "O"]), default="E", show_default=True, help="RTU parity.")
@click.option("--paced", is_flag=True, help="With --rtu pty: pace the pseudo-terminals at the baud rate.")
@click.option(
    "--press",
    "press_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Press description (TOML); default: the bundled example press.",
)
@click.option("--time-scale", type=float, default=1.0, show_default=True, help="Motion runs this many times faster.")
@click.option("--word-order", type=click.Choice(["ABCD", "CDAB"]), default="ABCD", show_default=True)
@click.option("--unit", type=click.IntRange(1, 247), default=1, show_default=True, help="Modbus unit id.")
@click.option(
    "--watchdog",
    type=float,
    default=1.0,
    show_default=True,
    help="Seconds without a master-heartbeat change that stop motion (0 = off).",
)
@click.option(
    "--fault",
    "fault_specs",
    multiple=True,
    metavar="SPEC",
    help="Inject a fault (repeatable): stuck:upper:3:5@40, estop[@T], overpressure[@T], freeze[@T], slow:MS, "
    "drop[:D][@T], restart[@T]. See docs/simulator.md.",
)
@click.option("--status-every", type=float, default=5.0, show_default=True, help="Seconds between status lines.")
@click.option("--duration", type=float, default=None, help="Stop after this many seconds (default: until Ctrl-C).")
def sim_command(
    host, port, rtu_port, baud, parity, paced, press_path, time_scale, word_order, unit, watchdog,
    fault_specs, status_every, duration,
):  # fmt: skip
    """Run the simulated press PLC until Ctrl-C.

    It serves the register map of docs/register-map.md over Modbus TCP (127.0.0.1:5020
    unless told otherwise) or RTU, moves the punches like the hydraulics would, and
    prints its URL and a status line now and then.
    """
    from mppf.sim.faults import parse_fault_spec
    from mppf.sim.plc.host import start_simulated_plc

    if rtu_port and (host is not None or port is not None):
        raise InputError("--rtu cannot be combined with --host/--port", hint="serve either TCP or RTU")
    for name, value, low in (("--time-scale", time_scale, None), ("--watchdog", watchdog, 0.0),
                             ("--status-every", status_every, None), ("--duration", duration, 0.0)):
        if value is not None and not (math.isfinite(value) and (value > 0 if low is None else value >= low)):
            raise InputError(f"{name} must be a {'positive number' if low is None else 'number >= 0'}, got {value}")
    faults = [parse_fault_spec(spec) for spec in fault_specs]
    press = load_press(press_path or example_press_path())
    sim = start_simulated_plc(
        press,
        host=host or "127.0.0.1",
        port=5020 if port is None else port,
        rtu=rtu_port == "pty",
        rtu_port=rtu_port if rtu_port not in (None, "pty") else None,
        baud=baud,
        parity=parity,
        paced=paced,
        faults=faults,
        word_order=word_order,
        unit=unit,
        time_scale=time_scale,
        watchdog_s=watchdog or None,
    )
    try:
        console.print(f"simulated PLC listening on {sim.url}", soft_wrap=True)
        console.print(
            f"{press.name}: {press.rows} x {press.cols} punches, word order {word_order}, "
            f"time scale {time_scale:g}, watchdog {watchdog:g} s; Ctrl-C to stop",
            soft_wrap=True,
        )
        started = time.monotonic()
        next_status = started
        while duration is None or time.monotonic() - started < duration:
            if time.monotonic() >= next_status:
                console.print(_status_line(sim), soft_wrap=True)
                next_status += status_every
            time.sleep(0.05)
    except KeyboardInterrupt:
        pass
    finally:
        sim.stop()
    console.print("simulated PLC stopped")


COMMANDS = [sim_command]
