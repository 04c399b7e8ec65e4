"""Start-up time of the light commands and of shell completion: each a fresh ``mppf`` process.

Run: ``python benchmarks/bench_startup.py [--runs 7]``. A simulated PLC is started in this
process for ``status``, ``stop`` and ``reset``; every command runs ``--runs`` times as its
own process (``python -m mppf``, as the console script does), and the table gives the median
wall time from start to exit, the median CPU time of the child (user + system: what the
command costs when the machine is not shared), the goal, and whether the median meets it.
For ``stop`` the time also covers the STOP reaching the PLC and its reply.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time

GOAL_S = 0.5
"""Every command of the table answers within this (s): the issue's figure for this machine."""


def _commands(url: str) -> list[tuple[str, list[str], dict]]:
    complete = {"_MPPF_COMPLETE": "bash_complete"}
    return [
        ("mppf --version", ["--version"], {}),
        ("mppf status --plc URL", ["status", "--plc", url], {}),
        ("mppf stop --plc URL", ["stop", "--plc", url], {}),
        ("mppf reset --plc URL", ["reset", "--plc", url], {}),
        ("TAB: mppf lo<TAB>", [], {**complete, "COMP_WORDS": "mppf lo", "COMP_CWORD": "1"}),
        ("TAB: mppf loop --<TAB>", [], {**complete, "COMP_WORDS": "mppf loop --", "COMP_CWORD": "2"}),
        ("TAB: mppf press --<TAB>", [], {**complete, "COMP_WORDS": "mppf press --", "COMP_CWORD": "2"}),
    ]


def _run_once(args: list[str], env: dict) -> tuple[float, float]:
    """(wall s, child CPU s) of one ``python -m mppf ARGS``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "mppf", *args], env={**os.environ, **env},
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, check=False, timeout=60)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"mppf {' '.join(args)} failed ({proc.returncode}): {proc.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=7, help="runs of each command (the median is reported)")
    runs = parser.parse_args().runs

    from mppf.sim.plc.host import run_simulated_plc

    rows = []
    with run_simulated_plc(watchdog_s=None) as sim:
        for name, args, env in _commands(sim.url):
            _run_once(args, env)  # warm the file cache
            times = [_run_once(args, env) for _ in range(runs)]
            wall = statistics.median(t[0] for t in times)
            cpu = statistics.median(t[1] for t in times)
            rows.append((name, wall, cpu))
    width = max(len(name) for name, _, _ in rows)
    print(f"{'command':<{width}}  {'median wall (s)':>15}  {'median CPU (s)':>14}  {'goal (s)':>8}  meets")
    for name, wall, cpu in rows:
        print(f"{name:<{width}}  {wall:>15.3f}  {cpu:>14.3f}  {GOAL_S:>8.1f}  {'yes' if wall <= GOAL_S else 'NO'}")
    print(f"load average now: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (wall times grow with it)")


if __name__ == "__main__":
    main()
