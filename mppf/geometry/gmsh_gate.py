"""The one gate to gmsh: a process-wide lock, start and stop by use count, and silence.

gmsh is a global singleton and not thread safe. Every call into it in mppf goes through
:class:`GmshModel`: each open CAD file is one named gmsh model; a call takes the lock,
makes its model current, and gives the lock back, so two threads may hold CAD files
open and query them in turn. gmsh is initialised when the first model opens and
finalised when the last closes (and at exit). It is initialised without touching the
SIGINT handler (Ctrl-C stays mppf's), with ``General.Terminal`` 0, and its log is kept
for error messages. What OpenCASCADE prints straight to the terminal (it does, on
import and export) is caught at the file-descriptor level by
:func:`mppf.geometry.files.quiet`.
"""

from __future__ import annotations

import atexit
import itertools
import threading
from contextlib import contextmanager

from mppf.geometry.files import quiet

_LOCK = threading.RLock()
_USERS = 0
_NAMES = itertools.count(1)


def _gmsh():
    import gmsh

    return gmsh


def _start() -> None:
    """Initialise gmsh for the first user (under the lock)."""
    global _USERS
    if _USERS == 0:
        gmsh = _gmsh()
        with quiet():
            gmsh.initialize(readConfigFiles=False, interruptible=False)
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.option.setNumber("General.Verbosity", 2)  # errors and warnings only, into the log
            gmsh.logger.start()
    _USERS += 1


def _stop() -> None:
    """Finalise gmsh after the last user (under the lock)."""
    global _USERS
    _USERS -= 1
    if _USERS == 0:
        gmsh = _gmsh()
        with quiet():
            gmsh.logger.stop()
            gmsh.finalize()


@atexit.register
def _finalise_at_exit() -> None:
    global _USERS
    with _LOCK:
        if _USERS > 0:
            _USERS = 1
            _stop()


def last_error() -> str:
    """The last error (else warning) gmsh logged, "" if none; call it inside :meth:`GmshModel.use`."""
    gmsh = _gmsh()
    messages = [m for m in gmsh.logger.get() if m.startswith(("Error", "Warning"))]
    gmsh.logger.stop()
    gmsh.logger.start()
    errors = [m for m in messages if m.startswith("Error")]
    return (errors or messages or [""])[-1]


class GmshModel:
    """One named gmsh model, used under the process-wide lock.

    Use :meth:`use` for every call into gmsh; :meth:`close` (or ``with``) removes the model
    and stops gmsh after the last one.
    """

    def __init__(self):
        with _LOCK:
            _start()
            self.name = f"mppf-{next(_NAMES)}"
            self.closed = False
            _gmsh().model.add(self.name)

    @contextmanager
    def use(self):
        """Hold the lock with this model current; yields the ``gmsh`` module."""
        with _LOCK:
            if self.closed:
                raise RuntimeError(f"gmsh model {self.name} is closed")
            gmsh = _gmsh()
            gmsh.model.setCurrent(self.name)
            yield gmsh

    def close(self) -> None:
        """Remove the model; finalise gmsh if it was the last one. Safe to call twice."""
        with _LOCK:
            if self.closed:
                return
            gmsh = _gmsh()
            gmsh.model.setCurrent(self.name)
            gmsh.model.remove()
            self.closed = True
            _stop()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()
