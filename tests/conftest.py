"""Shared, generic pytest fixtures: the bundled hull plates, and one plate planned once for the loop tests."""

from __future__ import annotations

import gc
import os
import sys
from pathlib import Path

# Every test worker and every subprocess of the tests (the real `mppf` processes) imports the whole
# package; where the environment forbids bytecode caches (PYTHONDONTWRITEBYTECODE, set on some CI
# machines) each compiled every module and re-wrote every test's assertions from source again, a
# tenth of the suite's time. The tests write the caches (__pycache__/, ignored by git) and read them.
sys.dont_write_bytecode = False
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)

# The tests solve many small problems: one BLAS thread is faster than a pool that spins (and the test
# workers share the machine's cores). Set before any BLAS is loaded: scipy's wheels bring their own
# OpenBLAS, loaded only when scipy.linalg first is, which a limit set at start-up would not reach (the
# plate simulator's banded Cholesky ran 14 times slower on a busy machine). The same for OpenMP (pykdtree's
# queries; mppf.core.kdtree's own thread rules are tested in tests/core/test_kdtree.py): the workers fill the
# cores, and OpenMP threads spin while they wait, so a second thread per worker only burned CPU (the suite's CPU
# time was 14 % lower on one thread). Subprocesses of the tests inherit them.
# mppf's own threads (a comparison's start fits, local fits and foot points: mppf.core.threads) likewise: on
# cores the workers already fill, a comparison on two threads took 15 % more CPU than on one, for the same results
# (tests/core/test_threads.py checks that they do not depend on the count).
for _name in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS", "MPPF_THREADS"):
    os.environ.setdefault(_name, "1")

# The tests never use the user's data folder (audit log, history, the installed press, the seal key): one
# for the run unless a test sets its own. Job files are sealed with the installation's key (mppf.core.seal);
# the tests share one key for the run between every test process and every `mppf` subprocess (the tests give
# subprocesses data folders of their own).
if "MPPF_SEAL_KEY" not in os.environ or "MPPF_HOME" not in os.environ:
    import tempfile

    _run_home = tempfile.mkdtemp(prefix="mppf-test-home-")
    os.environ.setdefault("MPPF_HOME", _run_home)
    os.environ.setdefault("MPPF_SEAL_KEY", os.path.join(_run_home, "seal.key"))

import numpy  # noqa: F401 - loaded before the BLAS limit below, so that it applies
import pytest
from threadpoolctl import threadpool_limits

import mppf

_BLAS_LIMIT = threadpool_limits(limits=1, user_api="blas")  # a BLAS loaded before this file (a plugin's)


def pytest_xdist_auto_num_workers(config) -> int:
    """``-n auto`` (the default run): half as many test workers again as cores, at least one more.

    A fifth of the tests' time is spent waiting (watchdogs, timeouts, a scan station's polls, real
    processes starting), one worker per core then leaves a core idle; the extra worker fills it.
    """
    from mppf.core.threads import cores

    count = cores()
    return count + max(1, count // 2)


@pytest.fixture
def steady_gc():
    """No full garbage collection during the test (collected before it, enabled again after).

    For the tests that time a driver's heartbeat against a PLC's watchdog: a test worker's heap (every
    test's objects before, matplotlib's figures) makes a full collection hold the interpreter 0.1-0.5 s
    (measured in the default run, idle), long enough to stretch a heartbeat gap past a quarter of a 1 s
    watchdog; the driver's own process never sees that (a full collection in a process that has imported
    the loop, the driver, the simulator and the reports: 53 ms).
    """
    gc.collect()
    gc.disable()
    try:
        yield
    finally:
        gc.enable()


LOOP_PLATE = "K2_fwd_bilge_convex"
"""The plate of the loop's tests: a weakly doubly curved KCS bilge plate, plans fast."""


@pytest.fixture(scope="session")
def hull_dir() -> Path:
    """Folder of the bundled real hull plates (61 x 41 grids, mm, hull coordinates)."""
    return Path(mppf.__file__).parent / "examples" / "hull"


@pytest.fixture(scope="session")
def plate_files(tmp_path_factory, hull_dir) -> tuple[Path, Path]:
    """The design of :data:`LOOP_PLATE` and its unfolded flat, as files (made once per session)."""
    from mppf.geometry.read import read_points
    from mppf.geometry.unfold import unfold
    from mppf.geometry.write import write_points

    design = hull_dir / f"{LOOP_PLATE}.csv"
    flat = tmp_path_factory.mktemp("plate") / f"{LOOP_PLATE}.flat.csv"
    return design, write_points(flat, unfold(read_points(design).points).flat)


@pytest.fixture(scope="session")
def planned_plate(plate_files):
    """(design, flat, press, job): :data:`LOOP_PLATE` planned once for the example press, 20 mm thick.

    The job is the first cycle's of :func:`mppf.loop.plate.start_plate` with the default loop
    settings; tests record it as a new plate with :func:`mppf.loop.plate.record_plate`.
    """
    from mppf.geometry.read import read_points
    from mppf.loop.plate import plan_first_cycle
    from mppf.model.press import example_press_path, load_press

    design, flat = (read_points(path) for path in plate_files)
    press = load_press(example_press_path())
    return design, flat, press, plan_first_cycle(design, flat, press, 20.0)
