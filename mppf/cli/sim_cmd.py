"""``mppf sim``: run the simulated press PLC in the foreground (see docs/simulator.md).

Besides its options, the running simulator takes commands on its standard input, one per
line, as an operator at the machine would act: ``estop``, ``release`` (the e-stop),
``key local`` / ``key remote`` (the remote-enable key switch), ``fault SPEC`` (inject a
fault, e.g. ``fault overpressure@2``), ``clear`` (remove injected faults), ``restart``,
``status``, ``help`` and ``quit``.
"""

from __future__ import annotations

import math
import queue
import sys
import threading
import time

import click

from mppf.core.errors import InputError

STDIN_HELP = ("commands: estop | release | key local | key remote | fault SPEC | clear | restart | status | "
              "help | quit")


def _status_line(sim) -> str:
    plc = sim.plc
    flags = sim.status_bits()
    on = [name for name, value in flags.items() if value] or ["-"]
    text = f"{sim.state()} | {' '.join(on)}"
    code = sim.fault_code()
    if code:
        text += f" | fault {plc.map.fault_text(code)}"
    if plc.owner:
        text += f" | owner 0x{plc.owner:08X}"
    upper, lower = sim.actual_positions_mm()
    return (f"{time.strftime('%H:%M:%S')} {text} | job validated {plc.validated[0]}, motion {plc.motion[0]} | "
            f"upper {upper.min():.1f}..{upper.max():.1f} mm, lower {lower.min():.1f}..{lower.max():.1f} mm")


def _read_stdin(lines: queue.Queue) -> None:
    """Hand the lines of standard input to the main loop (until end of input)."""
    try:
        for line in sys.stdin:
            lines.put(line.strip())
    except (OSError, ValueError):  # stdin closed or not readable: no commands
        pass


def _command(sim, line: str, echo) -> bool:
    """Carry out one operator command; False for ``quit``."""
    from mppf.sim.faults import parse_fault_spec

    words = line.split()
    if not words:
        return True
    name, args = words[0].lower(), words[1:]
    try:
        if name == "quit":
            return False
        if name == "estop" and not args:
            sim.inject("estop")
        elif name == "release" and not args:
            sim.release_estop()
        elif name == "key" and args in (["local"], ["remote"]):
            sim.set_remote(args[0] == "remote")
        elif name == "fault" and len(args) == 1:
            sim.inject_spec(parse_fault_spec(args[0]))
        elif name == "clear" and not args:
            sim.clear_faults()
        elif name == "restart" and not args:
            sim.restart()
        elif name == "help" and not args:
            echo(STDIN_HELP)
            return True
        elif name != "status":
            echo(f"unknown command {line!r}; {STDIN_HELP}")
            return True
    except InputError as exc:
        echo(f"refused: {exc.message}")
        return True
    echo(_status_line(sim))
    return True


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
    help="Watchdog and lease time in s: the owner's heartbeat must change within it (0 = off).",
)
@click.option("--scan-ms", type=float, default=10.0, show_default=True,
              help="Scan time of the PLC program in ms (above 0, at most 200): writes are acted on at the next scan.")
@click.option("--key", type=click.Choice(["remote", "local"]), default="remote", show_default=True,
              help="Position of the remote-enable key switch at start (local: GO is refused).")
@click.option(
    "--fault",
    "fault_specs",
    multiple=True,
    metavar="SPEC",
    help="Inject a fault (repeatable): stuck:upper:3:5@40, estop[@T], overpressure[@T], freeze[@T], local[@T], "
    "slow:MS[@T], drop[:D][@T], restart[@T]; T = seconds into the motion. See docs/simulator.md.",
)
@click.option("--tip-gap-min", type=float, default=5.0, show_default=True,
              help="The PLC's smallest tip gap (upper - lower setpoint of a pair) VALIDATE accepts, mm.")
@click.option("--positioning-timeout", type=float, default=2.0, show_default=True,
              help="The PLC's positioning timeout in s of motion: a punch out of its band this long after every punch "
                   "came to rest latches STUCK_PUNCH.")
@click.option(
    "--quirk",
    "quirk_specs",
    multiple=True,
    metavar="QUIRK",
    help="Behave like a misread PLC or let a foreign master act (repeatable): literal-complete, late-status:N, "
    "borrow-ids, none-after-go, foreign-stop[@T]. See docs/simulator.md.",
)
@click.option("--station", "station_dir", type=click.Path(file_okay=False), default=None, metavar="DIR",
              help="Also run a simulated scanner station on DIR: it presses a simulated plate with the tips this PLC "
                   "reached and answers the scan requests of 'mppf loop --plc URL --scanner DIR' (docs/simulator.md).")
@click.option("--physics", type=click.Choice(["fd", "fe"]), default=None,
              help="With --station: the plate's physics, finite-difference steel (fd, default) or the FE plate (fe, "
                   "CalculiX).")
@click.option("--plate-seed", type=click.IntRange(0, None), default=None,
              help="With --station: seed of the simulated plates' true properties and scans (default 0).")
@click.option("--status-every", type=float, default=5.0, show_default=True, help="Seconds between status lines.")
@click.option("--duration", type=float, default=None, help="Stop after this many seconds (default: until Ctrl-C).")
def sim_command(
    host, port, rtu_port, baud, parity, paced, press_path, time_scale, word_order, unit, watchdog, scan_ms, key,
    fault_specs, tip_gap_min, positioning_timeout, quirk_specs, station_dir, physics, plate_seed, status_every,
    duration,
):  # fmt: skip
    """Run the simulated press PLC until Ctrl-C (or 'quit' on its standard input).

    It serves the register map of docs/register-map.md over Modbus TCP (127.0.0.1:5020
    unless told otherwise) or RTU, runs the PLC program every scan like a real PLC (a
    master's writes are acted on at the next scan), moves the punches like the hydraulics
    would, and prints its URL and a status line now and then. Standard input takes
    operator commands: estop, release, key local, key remote, fault SPEC, clear, restart,
    status, help, quit. With --station DIR it is also the plate and the scanner station of a
    dry run: each scan request the loop writes into DIR is answered with a scan of a simulated
    plate pressed with every motion this PLC made since that plate's last scan.
    """
    from mppf.model.press import example_press_path, load_press
    from mppf.sim.faults import parse_fault_spec
    from mppf.sim.plc.host import start_simulated_plc

    if rtu_port and (host is not None or port is not None):
        raise InputError("--rtu cannot be combined with --host/--port", hint="serve either TCP or RTU")
    for name, value, low in (("--time-scale", time_scale, None), ("--watchdog", watchdog, 0.0),
                             ("--status-every", status_every, None), ("--duration", duration, 0.0),
                             ("--tip-gap-min", tip_gap_min, 0.0), ("--positioning-timeout", positioning_timeout, 0.0)):
        if value is not None and not (math.isfinite(value) and (value > 0 if low is None else value >= low)):
            raise InputError(f"{name} must be a {'positive number' if low is None else 'number >= 0'}, got {value}",
                             hint=f"give {name} {'above 0' if low is None else 'of 0 or more'}; "
                                  "see 'mppf sim --help'")
    if not (math.isfinite(scan_ms) and 0 < scan_ms <= 200):
        raise InputError(f"--scan-ms must be above 0 and at most 200 ms, got {scan_ms}",
                         hint="a PLC scans every 1-200 ms; 10 ms is typical")
    faults = [parse_fault_spec(spec) for spec in fault_specs]
    from mppf.sim.plc.quirks import parse_quirk

    quirks = [spec for spec in quirk_specs if parse_quirk(spec)]  # a bad spec: InputError naming it
    press = load_press(press_path or example_press_path())
    station = _station(station_dir, physics, plate_seed, press)  # before the PLC: a bad option starts nothing
    sim = start_simulated_plc(
        press, host=host or "127.0.0.1", port=5020 if port is None else port, rtu=rtu_port == "pty",
        rtu_port=rtu_port if rtu_port not in (None, "pty") else None, baud=baud, parity=parity, paced=paced,
        faults=faults, word_order=word_order, unit=unit, time_scale=time_scale, watchdog_s=watchdog or None,
        scan_s=scan_ms / 1000.0, remote=key == "remote", quirks=quirks,
        limits={"tip_gap_min_mm": tip_gap_min, "positioning_timeout_s": positioning_timeout},
    )

    banner = (f"{press.name}: {press.rows} x {press.cols} punches, word order {word_order}, scan {scan_ms:g} ms, "
              f"time scale {time_scale:g}, watchdog {watchdog:g} s, key switch {key}"
              + (f", quirks {', '.join(quirks)}" if quirks else "") + f"; Ctrl-C to stop; {STDIN_HELP}")
    _serve(sim, station, banner, status_every, duration)


def _serve(sim, station, banner: str, status_every_s: float, duration_s: float | None) -> None:
    """Serve the started simulator until Ctrl-C, 'quit' on standard input or ``duration_s``; then stop it.

    Parameters
    ----------
    sim : SimulatedPlc
        The running simulator (:func:`mppf.sim.plc.host.start_simulated_plc`).
    station : ScanStation or None
        The scanner station of ``--station``, started here in its own thread.
    banner : str
        The line describing the press and the simulator, printed after its URL.
    status_every_s : float
        Seconds between status lines.
    duration_s : float or None
        Stop after this many seconds; None: until Ctrl-C or 'quit'.
    """
    from mppf.cli._common import console

    def echo(text: str) -> None:
        console.print(text, soft_wrap=True, markup=False)

    stop_station = threading.Event()
    try:
        echo(f"simulated PLC listening on {sim.url}")
        if station is not None:
            station.say = echo
            station.log.follow(sim.plc)  # its next scan is observed
            threading.Thread(target=station.run, args=(stop_station,), daemon=True, name="sim-station").start()
            echo(f"scanner station on {station.folder}: the {station.physics} plate, seed {station.seed}; "
                 f"run mppf loop ... --plc {sim.url} --scanner {station.folder}")
        echo(banner)
        _operate(sim, echo, status_every_s, duration_s)
    except KeyboardInterrupt:
        pass
    finally:
        stop_station.set()
        sim.stop()
    echo("simulated PLC stopped")


def _operate(sim, echo, status_every_s: float, duration_s: float | None) -> None:
    """Act on the operator's commands from standard input and print a status line every ``status_every_s``
    seconds, until 'quit' or ``duration_s`` seconds (None: no end)."""
    lines: queue.Queue = queue.Queue()
    threading.Thread(target=_read_stdin, args=(lines,), daemon=True, name="sim-stdin").start()
    started = time.monotonic()
    next_status = started
    running = True
    while running and (duration_s is None or time.monotonic() - started < duration_s):
        if time.monotonic() >= next_status:
            echo(_status_line(sim))
            next_status += status_every_s
        try:
            running = _command(sim, lines.get(timeout=0.05), echo)
        except queue.Empty:
            pass


def _station(station_dir, physics, plate_seed, press):
    """The scanner station of ``--station`` (None without it); its options without it are refused."""
    if station_dir is None:
        if physics is not None or plate_seed is not None:
            raise InputError("--physics and --plate-seed are options of the simulated scanner station",
                             hint="add --station DIR (the folder mppf loop --scanner watches), or leave them out")
        return None
    from mppf.sim.station import MotionLog, ScanStation

    return ScanStation(station_dir, press, MotionLog(press), physics=physics or "fd", seed=plate_seed or 0)


COMMANDS = [sim_command]
