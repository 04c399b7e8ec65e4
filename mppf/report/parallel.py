"""Draw independent pictures on more than one core.

Drawing a picture with matplotlib holds the interpreter lock from start to end, so threads
gain nothing; a report's pictures (one deviation map and one punch map per cycle, the strain
and strokes pictures) are independent of each other, so :func:`draw` hands some of them to a
helper process and draws the others itself meanwhile. The helper is a fresh interpreter
(``python -m mppf.report.parallel TASKS RESULTS``, the tasks and their results pickled in
two temporary files): nothing of this process is copied (no lock another thread holds, no
re-run of the caller's script, as ``multiprocessing``'s start methods can), and it costs
about a second to start (numpy and matplotlib imported), so the helper takes fewer tasks.
The pictures are the same bytes either way (Agg renders the same figure to the same pixels
in any process); only the wall time differs: on a 2-core machine the demo's twelve pictures
take about 60 % of the time. When the helper cannot start or fails, its tasks are drawn here.
"""

from __future__ import annotations

import logging
import pickle
import subprocess
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

from mppf.core.threads import worker_threads

Task = tuple[Callable, tuple]
"""A picture to draw: a module-level function (so the helper can import it) and its arguments."""

MIN_TASKS = 4
"""Fewer pictures than this are all drawn here (the helper's start would not pay)."""

HELPER_SHARE = 0.4
"""The helper's share of the tasks (it starts about a second late)."""

_log = logging.getLogger("mppf")


def draw(tasks: Sequence[Task], helper: bool | None = None) -> list:
    """Run drawing tasks, some in a helper process; return their results in the order given.

    Parameters
    ----------
    tasks : sequence of (function, args)
        Independent tasks; the functions and arguments must pickle (module-level functions,
        dataclasses of arrays) and the results too (paths).
    helper : bool, optional
        Use a helper process. Default: when :func:`mppf.core.threads.worker_threads` is more
        than 1 (``MPPF_THREADS=1`` draws everything here) and there are :data:`MIN_TASKS` tasks.

    Returns
    -------
    list
        What each task returned.
    """
    tasks = list(tasks)
    if helper is None:
        helper = worker_threads() > 1 and len(tasks) >= MIN_TASKS
    theirs = set(range(len(tasks) - 1, -1, -2)[:int(HELPER_SHARE * len(tasks))]) if helper else set()
    if not theirs:
        return [function(*args) for function, args in tasks]
    results: list = [None] * len(tasks)
    with tempfile.TemporaryDirectory(prefix="mppf-draw-") as folder:
        task_file, result_file = Path(folder) / "tasks.pickle", Path(folder) / "results.pickle"
        task_file.write_bytes(pickle.dumps({i: tasks[i] for i in theirs}, protocol=pickle.HIGHEST_PROTOCOL))
        try:
            process = subprocess.Popen([sys.executable, "-m", "mppf.report.parallel", str(task_file), str(result_file)],
                                       stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        except OSError as error:  # no process to spare: draw everything here
            _log.info("pictures drawn in this process only: %s", error)
            theirs, process = set(), None
        for index, (function, args) in enumerate(tasks):
            if index not in theirs:
                results[index] = function(*args)
        if process is not None:
            _, err = process.communicate()
            done = pickle.loads(result_file.read_bytes()) if process.returncode == 0 and result_file.exists() else {}
            if len(done) < len(theirs):
                _log.info("the pictures' helper process failed (exit %s): drawn here; it said: %s",
                          process.returncode, " ".join(err.decode(errors="replace").split())[-500:])
            for index in theirs:
                results[index] = done[index] if index in done else tasks[index][0](*tasks[index][1])
    return results


def _helper(task_file: str, result_file: str) -> int:
    """Run the pickled tasks of ``task_file``; write their results to ``result_file``."""
    tasks = pickle.loads(Path(task_file).read_bytes())
    done = {index: function(*args) for index, (function, args) in tasks.items()}
    Path(result_file).write_bytes(pickle.dumps(done, protocol=pickle.HIGHEST_PROTOCOL))
    return 0


if __name__ == "__main__":
    sys.exit(_helper(*sys.argv[1:3]))
