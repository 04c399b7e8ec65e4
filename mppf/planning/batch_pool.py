"""The process pool a batch plans in (:mod:`mppf.planning.batch`): fresh workers, one BLAS thread each."""

from __future__ import annotations

import contextlib
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor


@contextlib.contextmanager
def _one_blas_thread_each():
    """The workers start with one BLAS thread each (the pool already uses every core); restored after."""
    names = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
    saved = {name: os.environ.get(name) for name in names}
    for name in names:
        os.environ.setdefault(name, "1")
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


@contextlib.contextmanager
def planning_pool(workers: int):
    """A process pool that plans plates: ``workers`` fresh processes ("spawn": nothing of this process's
    threads and locks is inherited), each with one BLAS thread (the pool already uses every core).

    :func:`mppf.planning.batch.run_batch` starts one per batch; a caller planning several batches
    in a row (the benchmark's parts) passes one to each, so the workers start and import once. Each
    worker imports the planning when it starts (:func:`_import_planning`), not in its first plate.

    Parameters
    ----------
    workers : int
        Processes of the pool.

    Yields
    ------
    concurrent.futures.ProcessPoolExecutor
        Stopped (its workers joined) when the ``with`` block ends.
    """
    with _one_blas_thread_each(), ProcessPoolExecutor(max_workers=workers, initializer=_import_planning,
                                                      mp_context=multiprocessing.get_context("spawn")) as pool:
        yield pool


def _import_planning() -> None:
    """What a worker needs to plan a plate, imported as it starts."""
    import mppf.geometry.read
    import mppf.geometry.unfold
    import mppf.geometry.write
    import mppf.planning.job
    import mppf.planning.sectional  # noqa: F401
