"""Benchmark: the time from starting ``mppf stop`` to its STOP request on the wire.

The simulated PLC runs in this process and notes the moment the write to ``stop_request``
reaches its Modbus server; ``mppf stop --plc URL`` is started as the operator starts it (the
``mppf`` console script, a new process) just before. Cases:

1. an idle PLC;
2. beside a running job: an ``mppf press`` in another process owns the PLC and the punches
   move (the STOP ends its job, so each repetition presses afresh).

For reference: the start of a bare Python process (``python -c pass``) and of one that
imports pymodbus's client (what a command speaking Modbus through pymodbus could not go
below). Goal: under 0.3 s (before the light command path: 2.45 s). The commands run with
their modules compiled to bytecode, as in an installation (``PYTHONPYCACHEPREFIX`` in a
temporary folder, one untimed run first), since this machine's environment sets
``PYTHONDONTWRITEBYTECODE``; the first, compiling run is reported too.

Run: ``python benchmarks/bench_stop.py [--repeat N] [--beside M]``.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from mppf.model.job import Job
from mppf.model.job_parts import StepStrokes
from mppf.model.press import example_press_path, load_press, press_from_dict
from mppf.planning.job import save_job
from mppf.sim.plc.host import start_simulated_plc

GOAL_S = 0.3


def small_press():
    doc = load_press(example_press_path()).to_dict()
    doc["matrix"].update(rows=4, cols=6)
    return press_from_dict(doc)


def long_job(press, path: Path) -> Path:
    """One step from the parking heights to a flat 20 mm plate: about 18 s of motion in real time."""
    active = np.ones(press.shape, bool)
    lower = np.full(press.shape, 10.0)
    return save_job(Job(press=press, thickness_mm=20.0, steps=[StepStrokes(lower + 20.0, lower, active)]), path)


def install_press(path: Path) -> None:
    """The 4 x 6 press as this machine's press (``mppf press --plc`` validates against it)."""
    text = example_press_path().read_text()
    text = re.sub(r"(?m)^rows = \d+", "rows = 4", text)
    text = re.sub(r"(?m)^cols = \d+", "cols = 6", text)
    path.write_text(text)


def mppf_command() -> list[str]:
    """The installed console script beside this Python (not a version manager's shim, which adds a shell)."""
    script = Path(sys.executable).with_name("mppf")
    if not script.is_file():
        script = shutil.which("mppf")
    return [str(script)] if script else [sys.executable, "-m", "mppf"]


def timed_stop(sim, arrivals: list[float], env: dict) -> tuple[float, float]:
    """Start ``mppf stop``; return (start to STOP on the wire, start to the command's exit) in s."""
    arrivals.clear()
    started = time.monotonic()
    proc = subprocess.run([*mppf_command(), "stop", "--plc", sim.url], env=env, capture_output=True, text=True,
                          timeout=60)
    ended = time.monotonic()
    if proc.returncode != 0 or not arrivals:
        raise RuntimeError(f"mppf stop failed: {proc.stdout}{proc.stderr}")
    return arrivals[0] - started, ended - started


def process_start(args: list[str], repeat: int) -> list[float]:
    out = []
    for _ in range(repeat):
        t = time.monotonic()
        subprocess.run([sys.executable, *args], check=True, timeout=60)
        out.append(time.monotonic() - t)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=10, help="STOPs on the idle PLC")
    parser.add_argument("--beside", type=int, default=3, help="STOPs beside a running job")
    parser.add_argument("--load", type=int, default=0, help="busy-looping background processes during the run")
    args = parser.parse_args()
    press = small_press()
    rows = []
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.load)]
    try:
        run(args, press, rows)
    finally:
        for proc in burners:
            proc.kill()
            proc.wait()
    report(rows, args.load)


def run(args, press, rows) -> None:
    """The timed STOPs (idle PLC, then beside a running job) into ``rows``."""
    with tempfile.TemporaryDirectory() as tmp:
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env.update(MPPF_HOME=tmp, PYTHONPYCACHEPREFIX=str(Path(tmp) / "pyc"))
        os.environ["MPPF_HOME"] = tmp  # the job is sealed with the key of the installation that presses it
        job = long_job(press, Path(tmp) / "job.json")
        install_press(Path(tmp) / "press.toml")
        with start_simulated_plc(press, time_scale=1.0, watchdog_s=1.0) as sim:
            stop_address = sim.plc.map["stop_request"].address
            arrivals: list[float] = []
            sim.server.on_write = lambda address, values, t: address == stop_address and arrivals.append(t)
            # 1. idle PLC: the first run compiles the modules, the others run as installed
            first = timed_stop(sim, arrivals, env)
            rows.append(("idle PLC, first run (compiling the modules)", [first[0]], [first[1]]))
            idle = [timed_stop(sim, arrivals, env) for _ in range(args.repeat)]
            rows.append(("idle PLC", [w for w, _ in idle], [e for _, e in idle]))
            # 2. beside a running job of another master
            beside = []
            for _ in range(args.beside):
                sim.restart(downtime_s=0.05)  # a fresh PLC (IDLE) for the next job
                time.sleep(0.2)
                press_proc = subprocess.Popen([*mppf_command(), "press", str(job), "--plc", sim.url, "--yes"], env=env,
                                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                deadline = time.monotonic() + 30.0
                while sim.state() != "EXECUTING":
                    if time.monotonic() > deadline or press_proc.poll() is not None:
                        raise RuntimeError("mppf press did not start its job")
                    time.sleep(0.02)
                time.sleep(0.5)
                beside.append(timed_stop(sim, arrivals, env))
                press_proc.wait(timeout=30)
            rows.append(("beside a running job (mppf press in another process)", [w for w, _ in beside],
                         [e for _, e in beside]))

def report(rows, load_processes: int) -> None:
    """The table, with the reference process starts (taken with the load gone)."""
    floor = process_start(["-c", "pass"], 5)
    pymodbus = process_start(["-c", "import pymodbus.client"], 5)
    started_ms = statistics.median(floor) * 1000
    load = os.getloadavg()
    print(f"mppf stop: start of the command to its STOP request on the wire (goal < {GOAL_S} s); "
          f"load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} on {os.cpu_count()} cores, "
          f"{load_processes} busy-looping process(es) of this benchmark beside")
    print(f"{'case':<58} {'n':>3} {'to wire median':>15} {'min':>7} {'max':>7} {'command ends':>13}  goal")
    for name, wire, total in rows:
        print(f"{name:<58} {len(wire):>3} {statistics.median(wire):>13.3f} s {min(wire):>7.3f} {max(wire):>7.3f} "
              f"{statistics.median(total):>11.3f} s  {'met' if statistics.median(wire) < GOAL_S else 'MISSED'}"
              f" ({statistics.median(wire) * 1000 / started_ms:.1f} x python -c pass)")
    for name, times in (("reference: python -c pass", floor), ("reference: python -c 'import pymodbus.client'",
                                                                 pymodbus)):
        print(f"{name:<58} {len(times):>3} {statistics.median(times):>13.3f} s {min(times):>7.3f} {max(times):>7.3f}")


if __name__ == "__main__":
    main()
