"""Benchmark: the owner's heartbeat as the PLC sees it, alone and beside 10 concurrent ``mppf status`` pollers.

An ``mppf press`` (its own process, the real master) presses a long job (about 18 s of
motion in real time) on the simulated PLC of this process (watchdog 1 s, scan 10 ms). The
PLC's Modbus server notes when each heartbeat write arrives; the PLC program notes each scan
that saw a new beat. First the master beats alone, then 10 pollers each start ``mppf status
--plc URL --json`` again and again (new processes: the load of shop-floor dashboards). Goal:
every gap under a quarter of the watchdog (0.25 s); before the heartbeat derived from the
watchdog (and the light ``mppf status``) the gap reached 0.58 s.

Run: ``python benchmarks/bench_heartbeat.py [--pollers N] [--seconds S]``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from bench_stop import long_job, mppf_command, small_press
from mppf.sim.plc.host import start_simulated_plc

WATCHDOG_S = 1.0


def gaps_in(times: list[float], start: float, end: float) -> np.ndarray:
    picked = np.array([t for t in times if start <= t <= end])
    return np.diff(picked) if picked.size > 1 else np.array([np.nan])


def poller(url: str, env: dict, until: float, runs: list[int], failures: list[str]) -> None:
    while time.monotonic() < until:
        proc = subprocess.run([*mppf_command(), "status", "--plc", url, "--json"], env=env, capture_output=True,
                              text=True, timeout=60)
        runs.append(1)
        if proc.returncode != 0:
            failures.append(proc.stderr[-200:])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pollers", type=int, default=10)
    parser.add_argument("--seconds", type=float, default=8.0, help="length of each phase (s)")
    args = parser.parse_args()
    press = small_press()
    with tempfile.TemporaryDirectory() as tmp:
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env.update(MPPF_HOME=tmp, PYTHONPYCACHEPREFIX=str(Path(tmp) / "pyc"))  # compiled once, as installed
        # this installation's press and seal key: the job is sealed here and pressed by the subprocess
        from mppf.core.paths import seal_key_path
        from mppf.model.press import press_to_toml

        (Path(tmp) / "press.toml").write_text(press_to_toml(press))
        env["MPPF_SEAL_KEY"] = str(seal_key_path())
        job = long_job(press, Path(tmp) / "job.json")
        with start_simulated_plc(press, time_scale=1.0, watchdog_s=WATCHDOG_S, scan_s=0.01) as sim:
            subprocess.run([*mppf_command(), "status", "--plc", sim.url], env=env, capture_output=True, timeout=60)
            address = sim.plc.map["heartbeat_counter"].address  # the first register of the beat (map 3)
            arrivals: list[float] = []
            sim.server.on_write = lambda a, values, t: a == address and arrivals.append(t)
            master = subprocess.Popen([*mppf_command(), "press", str(job), "--plc", sim.url, "--yes"], env=env,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            while sim.state() != "EXECUTING":
                if master.poll() is not None:
                    raise RuntimeError(f"mppf press failed: {master.communicate()[1]}")
                time.sleep(0.02)
            # phase 1: the master alone
            t1 = time.monotonic()
            time.sleep(args.seconds)
            # phase 2: pollers beside it
            t2 = time.monotonic()
            runs: list[int] = []
            failures: list[str] = []
            threads = [threading.Thread(target=poller, args=(sim.url, env, t2 + args.seconds, runs, failures))
                       for _ in range(args.pollers)]
            for thread in threads:
                thread.start()
            for thread in threads:
                thread.join()
            t3 = time.monotonic()
            lease_ok = sim.status_bits()["lease_ok"] and sim.state() == "EXECUTING"
            _, err = master.communicate(timeout=60)
            scans = list(sim.plc.beats)
        load = os.getloadavg()
    print(f"heartbeat of an mppf press during its job (watchdog {WATCHDOG_S:g} s: goal every gap < "
          f"{WATCHDOG_S / 4:g} s); load average before the end {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} "
          f"on {os.cpu_count()} cores")
    print(f"{'phase':<44} {'where':<22} {'beats':>6} {'median':>8} {'p99':>8} {'max':>8}  goal")
    for name, start, end in (("the master alone", t1, t2),
                             (f"{args.pollers} pollers ({len(runs)} mppf status runs)", t2, t3)):
        for where, times in (("arrival at the server", arrivals), ("seen by a PLC scan", scans)):
            gaps = gaps_in(times, start, end)
            print(f"{name:<44} {where:<22} {gaps.size + 1:>6} {np.median(gaps):>7.3f}s {np.percentile(gaps, 99):>7.3f}s "
                  f"{gaps.max():>7.3f}s  {'met' if gaps.max() < WATCHDOG_S / 4 else 'MISSED'}")
    print(f"lease kept and the job still running at the end of the pollers: {lease_ok}; mppf press exit code "
          f"{master.returncode}{'' if master.returncode == 0 else ': ' + err.strip()[-200:]}; "
          f"failed status runs: {len(failures)}")


if __name__ == "__main__":
    main()
