"""``mppf sim --station DIR``: the simulated PLC and scanner station of a dry run as a yard runs it, in its own process.

``mppf loop --plc URL --scanner DIR`` (another process) presses the plate on the simulator and
waits for scans in DIR; the simulator's station presses its simulated plate with the tips its
PLC reached and answers each scan request with a scan and a mark file (docs/simulator.md).
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from station_helpers import asymmetric_points, plate_files

from mppf.cli import main
from mppf.model.press import example_press_path


def _start_sim(folder: Path, *options: str) -> tuple[subprocess.Popen, list[str], str]:
    """``mppf sim --station folder`` in its own process: (process, its lines as they come, its URL)."""
    sim = subprocess.Popen([sys.executable, "-m", "mppf", "sim", "--port", "0", "--time-scale", "50",
                            "--status-every", "600", "--station", str(folder), *options],
                           stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    sim.reader = threading.Thread(target=lambda: lines.extend(iter(sim.stdout.readline, "")), daemon=True)
    sim.reader.start()
    deadline = time.monotonic() + 60.0
    while not any("listening on" in line for line in lines):
        if sim.poll() is not None or time.monotonic() > deadline:
            sim.kill()
            pytest.fail(f"mppf sim --station did not start: {''.join(lines)}")
        time.sleep(0.1)
    url = next(line for line in lines if "listening on" in line).split()[-1]
    return sim, lines, url


def _stop_sim(sim: subprocess.Popen) -> None:
    try:
        sim.stdin.write("quit\n")
        sim.stdin.flush()
        sim.wait(timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        sim.kill()
        sim.wait()
    sim.reader.join(timeout=10)
    sim.stdin.close()
    sim.stdout.close()


def _dry_run(tmp_path: Path, cycles: int, *sim_options: str, timeout_s: float) -> tuple[subprocess.CompletedProcess,
                                                                                           list[str], Path]:
    """The small asymmetric plate looped on ``mppf sim --station``: (the loop's run, the simulator's lines, DIR)."""
    design, flat = plate_files(tmp_path, "bump", asymmetric_points())
    folder = tmp_path / "scans"
    env = {**os.environ, "MPPF_HOME": str(tmp_path / "home")}
    sim, lines, url = _start_sim(folder, *sim_options)
    try:
        loop = subprocess.run([sys.executable, "-m", "mppf", "loop", str(design), str(flat), "--press",
                               str(example_press_path()), "--thickness", "20", "--plc", url, "--scanner", str(folder),
                               "--yes", "--time-scale", "50", "--max-cycles", str(cycles), "--rescans", "0",
                               "--history", str(tmp_path / "h.sqlite"), "--plate-id", "BUMP"],
                              capture_output=True, text=True, env=env, timeout=timeout_s, check=False)
    finally:
        _stop_sim(sim)
    return loop, [line.rstrip("\n") for line in lines], folder


@pytest.mark.slow  # two processes, two loop cycles: about 30 s
def test_a_dry_run_through_mppf_sim_and_the_scan_folder_on_the_fd_plate(tmp_path):
    loop, lines, folder = _dry_run(tmp_path, 2, timeout_s=240.0)
    assert loop.returncode in (0, 5, 6), loop.stdout + loop.stderr
    assert "station: plate BUMP: 20 mm, the fd plate, seed 0" in lines
    # the loop pressed two steps in cycle 1: the station pressed its plate with both, then with cycle 2's
    assert "station: BUMP cycle 1: pressing 2 motion(s) on the fd plate" in lines, lines
    assert any(line.startswith("station: BUMP cycle 2: pressing ") for line in lines), lines
    for cycle in (1, 2):
        assert (folder / f"BUMP-cycle-{cycle:02d}.ply").stat().st_size > 10_000
        assert f"cycle {cycle}: scan BUMP-cycle-{cycle:02d}.ply with its reference mark" in loop.stdout + loop.stderr
    assert not list(folder.glob("*.scan-request.json"))
    assert "simulated PLC stopped" in lines[-1]


@pytest.mark.slow  # CalculiX: two ccx runs of a 1.6 x 1.1 m plate
def test_a_dry_run_through_mppf_sim_and_the_scan_folder_on_the_fe_plate(tmp_path):
    loop, lines, folder = _dry_run(tmp_path, 1, "--physics", "fe", "--plate-seed", "3", timeout_s=600.0)
    assert loop.returncode in (0, 5, 6), loop.stdout + loop.stderr
    assert "station: plate BUMP: 20 mm, the fe plate, seed 3" in lines
    assert "station: BUMP cycle 1: pressing 2 motion(s) on the fe plate" in lines, lines
    assert any(line.startswith("station: ccx: step ") for line in lines) or any(
        "pressed in" in line for line in lines)
    assert (folder / "BUMP-cycle-01.ply").stat().st_size > 10_000
    assert (folder / "BUMP-cycle-01.ply.mark.json").exists()
    assert "form max" in loop.stdout


def test_station_options_without_the_station_exit_2(capsys):
    assert main(["sim", "--port", "0", "--physics", "fe", "--duration", "0.1"]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "--physics and --plate-seed are options of the simulated scanner station" in err
    assert "add --station DIR" in err and "Traceback" not in err


def test_the_fe_station_without_ccx_says_how_to_install_it(capsys, monkeypatch, tmp_path):
    monkeypatch.setenv("MPPF_CCX", "no-such-ccx-program")
    assert main(["sim", "--port", "0", "--station", str(tmp_path / "scans"), "--physics", "fe",
                 "--duration", "0.1"]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "CalculiX (ccx) not found: install the Debian package calculix-ccx" in err and "Traceback" not in err
