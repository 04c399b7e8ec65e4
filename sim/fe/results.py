"""Reading CalculiX results: nodal blocks of the .frd file, printed node sets of the .dat file.

The .frd file (ASCII) holds, per output increment, a ``1PSTEP`` line (increment, step), a
``100CL`` header (time) and blocks ``-4 NAME`` of ``-1`` lines: the node id (10 characters)
then values of 12 characters each, ended by ``-3``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import FileFormatError


@dataclass(frozen=True)
class NodalBlock:
    """One result block of a .frd file.

    Attributes
    ----------
    name : str
        e.g. ``DISP``.
    step : int
        The analysis step (1-based, counted over restarts).
    time : float
        Total time of the increment.
    nodes : (n,) int
    values : (n, k) float
    """

    name: str
    step: int
    time: float
    nodes: np.ndarray
    values: np.ndarray


def read_frd(text: str, name: str = "DISP") -> list[NodalBlock]:
    """The blocks of one result (e.g. ``DISP``) in a .frd file, in the order written.

    Raises
    ------
    FileFormatError
        A block without its node lines or a line that is not numbers.
    """
    blocks, step, when = [], 0, 0.0
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("    1PSTEP"):
            parts = line.split()
            step = int(parts[3]) if len(parts) > 3 else step
        elif line.startswith("  100CL"):
            when = float(line[12:24])
        elif line.startswith(" -4") and line.split()[1] == name:
            i, block = _read_block(lines, i + 1, name, step, when)
            blocks.append(block)
            continue
        i += 1
    return blocks


def _read_block(lines: list[str], i: int, name: str, step: int, when: float) -> tuple[int, NodalBlock]:
    """The ``-1`` lines of a block from line ``i``; returns the line after its ``-3``."""
    nodes, values = [], []
    while i < len(lines) and not lines[i].startswith(" -3"):
        line = lines[i]
        if line.startswith(" -1"):
            try:
                nodes.append(int(line[3:13]))
                values.append([float(line[13 + 12 * k:25 + 12 * k]) for k in range((len(line) - 13) // 12)])
            except ValueError as exc:
                raise FileFormatError("the .frd file", f"bad result line {line!r}", hint="was the run complete?") from exc
        i += 1
    if not nodes:
        raise FileFormatError("the .frd file", f"a {name} block without node lines", hint="was the run complete?")
    return i + 1, NodalBlock(name, step, when, np.array(nodes), np.array(values, dtype=float))


def last_of_steps(blocks: list[NodalBlock]) -> dict[int, NodalBlock]:
    """The last block of each step: step -> block."""
    return {b.step: b for b in blocks}


def read_dat_forces(text: str, node_set: str) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """``*NODE PRINT`` reaction forces of a node set in a .dat file.

    Returns
    -------
    list of (time, nodes (n,) int, forces (n, 3) float N)
    """
    out = []
    key = f"forces (fx,fy,fz) for set {node_set.upper()} and time"
    for chunk in text.split(key)[1:]:
        head, *rows = chunk.splitlines()
        parsed = [r.split() for r in rows if r.strip()]
        parsed = [p for p in parsed[:_first_break(parsed)] if len(p) == 4]
        out.append((float(head.split()[0]), np.array([int(p[0]) for p in parsed]),
                    np.array([[float(v) for v in p[1:]] for p in parsed]).reshape(-1, 3)))
    return out


def _first_break(rows: list[list[str]]) -> int:
    """Index of the first row that is not a node line."""
    for k, row in enumerate(rows):
        if len(row) != 4 or not row[0].isdigit():
            return k
    return len(rows)
