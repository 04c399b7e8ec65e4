"""Running CalculiX (``ccx``) on a deck: a temporary folder, progress lines, the log kept on failure.

:func:`run_ccx` writes the deck (and the restart file of the run before, ``<job>.rin``) into a
temporary folder, runs ``ccx -i <job>`` there with one thread, reports the step and increment
it is at every :data:`PROGRESS_S` seconds (from ``<job>.sta``), and returns the .frd text (and the
restart file when the deck writes one). When ccx fails (exit status, ``*ERROR`` in its log, no result) the folder
is kept (``mppf-ccx-failed-*`` in the temporary directory) and :class:`FESolveError` names it.
"""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from mppf.core.errors import InputError, MppfError

CCX_MISSING = ("CalculiX (ccx) not found: install the Debian package calculix-ccx "
               "(apt-get install calculix-ccx)")
"""The message when ``ccx`` is not on the PATH."""

PROGRESS_S = 2.0
"""Seconds between progress lines while ccx runs."""

TIMEOUT_S = 3600.0
"""Longest a single ccx run may take."""

JOB = "plate"
"""Job name of the deck in the run folder."""


class FESolveError(MppfError, RuntimeError):
    """CalculiX did not finish the FE plate's press step (no convergence, a bad deck)."""


@dataclass(frozen=True)
class CcxRun:
    """The results of one ccx run.

    Attributes
    ----------
    frd : str
        The .frd result file (nodal displacements).
    restart : bytes
        The restart file written (``<job>.rout``; empty without ``*RESTART, WRITE``), for a next run's ``.rin``.
    seconds : float
        Wall time of the run, s.
    log_tail : str
        The end of ccx's log.
    steps : dict
        Per analysis step (1-based): ``(increments, cutbacks, iterations)`` from the status file.
    cpu_s : float
        CPU time of the run (user + system, s; of every child process that ended meanwhile).
    """

    frd: str
    restart: bytes
    seconds: float
    log_tail: str
    steps: dict = field(default_factory=dict)
    cpu_s: float = 0.0


def find_ccx() -> str:
    """Path of the ``ccx`` program (``MPPF_CCX`` overrides the name).

    Raises
    ------
    InputError
        ccx is not installed (exit 2), with the package to install.
    """
    name = os.environ.get("MPPF_CCX", "ccx")
    path = shutil.which(name)
    if path is None:
        raise InputError(CCX_MISSING, hint="or choose the finite-difference plate (--physics fd)")
    return path


def run_ccx(deck: str, *, restart_in: bytes | None = None, progress=None,
            timeout_s: float = TIMEOUT_S) -> CcxRun:
    """Run ccx on a deck in a temporary folder.

    Parameters
    ----------
    deck : str
        The input deck.
    restart_in : bytes, optional
        The restart file of the run before (``*RESTART, READ`` in the deck).
    progress : callable, optional
        Called with a line (str) every :data:`PROGRESS_S` seconds while ccx runs.
    timeout_s : float
        The run is stopped after this long, s.

    Returns
    -------
    CcxRun

    Raises
    ------
    InputError
        ccx is not installed.
    FESolveError
        ccx failed; its folder (deck, log, status) is kept and named in the message.
    """
    ccx = find_ccx()
    folder = Path(tempfile.mkdtemp(prefix="mppf-ccx-"))
    (folder / f"{JOB}.inp").write_text(deck)
    if restart_in is not None:
        (folder / f"{JOB}.rin").write_bytes(restart_in)
    env = {**os.environ, "OMP_NUM_THREADS": "1", "CCX_NPROC_STIFFNESS": "1", "CCX_NPROC_EQUATION_SOLVER": "1"}
    start = time.monotonic()
    cpu_before = _children_cpu_s()
    with open(folder / "ccx.log", "w") as log:
        proc = subprocess.Popen([*_end_with_parent(), ccx, "-i", JOB], cwd=folder, stdout=log,
                                stderr=subprocess.STDOUT, env=env)
        last = start
        while proc.poll() is None:
            time.sleep(0.2)
            now = time.monotonic()
            if now - start > timeout_s:
                proc.kill()
                proc.wait()
                _fail(folder, f"ccx ran longer than {timeout_s:.0f} s and was stopped")
            if progress is not None and now - last >= PROGRESS_S:
                last = now
                progress(f"ccx: {status_line(folder / f'{JOB}.sta')} ({now - start:.0f} s)")
    seconds = time.monotonic() - start
    text = (folder / "ccx.log").read_text(errors="replace")
    frd, rout = folder / f"{JOB}.frd", folder / f"{JOB}.rout"
    if proc.returncode != 0 or "*ERROR" in text or not frd.exists():
        reason = next((line.strip() for line in text.splitlines() if "*ERROR" in line), "")
        _fail(folder, f"ccx failed (exit status {proc.returncode}{': ' + reason if reason else ''})")
    result = CcxRun(frd.read_text(errors="replace"), rout.read_bytes() if rout.exists() else b"", seconds,
                    text[-2000:], sta_summary(folder / f"{JOB}.sta"), _children_cpu_s() - cpu_before)
    shutil.rmtree(folder, ignore_errors=True)
    return result


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def sta_summary(sta_path: Path) -> dict:
    """Per analysis step of a ccx status file: ``{step: (increments, cutbacks, iterations)}``.

    A line of the file is one attempt of an increment (``1U``: the first attempt, not converged, cut
    back); the iterations are those of every attempt, the converged increments are counted once.
    """
    summary: dict = {}
    try:
        lines = sta_path.read_text().splitlines()[2:]
    except OSError:
        return summary
    for row in (line.split() for line in lines):
        if len(row) < 7 or not row[0].isdigit():
            continue
        increments, cutbacks, iterations = summary.get(int(row[0]), (0, 0, 0))
        failed = row[2].endswith("U")
        summary[int(row[0])] = (increments + (not failed), cutbacks + failed, iterations + int(row[3]))
    return summary


def _end_with_parent() -> list[str]:
    """The prefix that ends ccx when the thread that started it ends (``setpriv --pdeathsig``, util-linux): a
    simulator stopped while its station presses a plate leaves no ccx running on a shared machine."""
    setpriv = shutil.which("setpriv")
    return [setpriv, "--pdeathsig", "TERM"] if setpriv else []


def status_line(sta_path: Path) -> str:
    """``step S increment I, step time T`` from a ccx status file (its last line)."""
    try:
        rows = [line.split() for line in sta_path.read_text().splitlines()[2:]]
    except OSError:
        return "starting"
    rows = [r for r in rows if len(r) >= 7]
    if not rows:
        return "starting"
    step, inc, step_time = rows[-1][0], rows[-1][1], rows[-1][5]
    return f"step {step} increment {inc}, step time {float(step_time):.3f}"


def _fail(folder: Path, what: str):
    """Keep the run folder and raise :class:`FESolveError` naming it."""
    kept = Path(tempfile.mkdtemp(prefix="mppf-ccx-failed-"))
    for item in folder.iterdir():
        if item.suffix in (".inp", ".log", ".sta", ".cvg", ".dat"):
            shutil.copy2(item, kept / item.name)
    shutil.rmtree(folder, ignore_errors=True)
    raise FESolveError(f"{what}; deck and log kept in {kept}",
                       hint="run 'ccx -i plate' there by hand to see the increments; smaller press steps help")
