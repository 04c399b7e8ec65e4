"""How many threads mppf's own parallel parts run on: ``MPPF_THREADS``, else up to two cores.

A comparison runs three kinds of independent work on Python threads (numpy and the k-d trees
let go of the interpreter lock): the four principal-axes start fits
(:func:`mppf.registration.scan_start.choose_start`), the chunks of local fits
(:mod:`mppf.measure.localfit`) and the foot points of a large scan (:mod:`mppf.measure.deviations`).
On an idle machine two threads finish a comparison sooner; on a machine whose cores are already
busy (a batch of plates, other programs, a test run with a worker per core) they finish no sooner
and cost more CPU: measured on a 2-core machine whose cores were busy, a 12,000-point
comparison took 1.32 s of CPU on two threads and 1.15 s on one, with the same results
(the results never depend on the thread count).

``MPPF_THREADS`` (an integer from 1 to 64) sets the count for the whole process, as
``OMP_NUM_THREADS`` does for OpenMP; it is read when asked, so a process may set it before its
first comparison. A value that is not such an integer is ignored with one warning on the
``mppf`` logger, and the default is used.
"""

from __future__ import annotations

import logging
import os

ENV = "MPPF_THREADS"
"""The environment variable that sets the thread count."""

MAX_THREADS = 64
"""The largest thread count taken from :data:`ENV`."""

DEFAULT_MAX = 2
"""Without :data:`ENV`: this many threads at most (the parts split in two; more threads gain nothing)."""

_warned: set[str] = set()


def cores() -> int:
    """Cores this process may run on (its CPU affinity where the system tells it, else the CPU count)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


def worker_threads() -> int:
    """Threads for mppf's independent parts: ``$MPPF_THREADS`` if valid, else ``min(2, cores())``.

    Returns
    -------
    int
        At least 1.
    """
    raw = os.environ.get(ENV)
    if raw is not None and raw.strip():
        text = raw.strip()
        if text.isdigit() and 1 <= int(text) <= MAX_THREADS:
            return int(text)
        if text not in _warned:
            _warned.add(text)
            logging.getLogger("mppf").warning(
                "%s=%r is not a thread count from 1 to %d: ignored, %d thread(s) used; set it to e.g. 1 or unset it",
                ENV, raw, MAX_THREADS, min(DEFAULT_MAX, cores()))
    return min(DEFAULT_MAX, cores())
