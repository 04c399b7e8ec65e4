"""Helpers shared by the driver and press-CLI tests: a small press, jobs, a hook reporter."""

from __future__ import annotations

import numpy as np

from mppf.planning.job import Job, StepStrokes
from mppf.planning.press import example_press_path, load_press, press_from_dict


def small_press(rows: int = 4, cols: int = 6, **forming):
    """The example press cut down to ``rows x cols`` punches (fast to upload and simulate)."""
    doc = load_press(example_press_path()).to_dict()
    doc["matrix"]["rows"], doc["matrix"]["cols"] = rows, cols
    doc["forming"].update(forming)
    return press_from_dict(doc)


def step_setpoints(press, upper_mm: float = 30.0, lower_mm: float = 10.0, seed: int = 0):
    """(upper, lower) setpoints with a little variation per punch, within the limits."""
    rng = np.random.default_rng(seed)
    upper = upper_mm + np.round(rng.uniform(0, 20, press.shape), 2)
    lower = lower_mm + np.round(rng.uniform(0, 20, press.shape), 2)
    return upper, lower


def small_job(press, n_steps: int = 2, *, beyond_limit: bool = False) -> Job:
    """A job with ``n_steps`` steps; punch (0, 0) inactive (parked)."""
    active = np.ones(press.shape, dtype=bool)
    active[0, 0] = False
    steps = []
    for k in range(n_steps):
        upper, lower = step_setpoints(press, 30.0 + 5 * k, 10.0 + 5 * k, seed=k)
        if beyond_limit and k == n_steps - 1:
            upper[1, 2] = press.upper.max_mm + 50.0
        steps.append(StepStrokes(np.where(active, upper, np.nan), np.where(active, lower, np.nan), active))
    return Job(press=press, thickness_mm=20.0, steps=steps)


class HookReporter:
    """A Reporter that records what it is told and runs test actions at chosen moments.

    ``on_start(task)``, ``on_info(message)`` and ``on_update(completed)`` are called
    with the reporter's arguments; they play the part of things happening in the shop
    (a foreign master, an e-stop, the operator's Ctrl-C) at a precise point of a step.
    """

    def __init__(self, on_start=None, on_info=None, on_update=None):
        self.tasks: list[str] = []
        self.messages: list[str] = []
        self.updates = 0
        self._on_start, self._on_info, self._on_update = on_start, on_info, on_update

    def start(self, task, total=None):
        self.tasks.append(task)
        if self._on_start:
            self._on_start(task)

    def advance(self, amount=1.0):
        pass

    def update(self, completed):
        self.updates += 1
        if self._on_update:
            self._on_update(completed)

    def finish(self):
        pass

    def info(self, message):
        self.messages.append(message)
        if self._on_info:
            self._on_info(message)
