"""Where a job came from and how it is split: the sectional summary, a section's transition zone,
the batch and loop provenance, the piece of a plate a single-section job is, and the seal.

Frozen :class:`~mppf.model.job_record.DocRecord` blocks of the job file, each under its own key
(``"sectional"``, ``"transition"`` in a section, ``"batch"``, ``"loop"``, ``"section"``,
``"seal"``); see ``docs/file-formats.md`` and ``docs/sections.md``. Lengths in mm.
"""

# ruff: noqa: RUF009 - the field helpers of mppf.model.job_record return dataclasses.field(default=None, ...)
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.model.job_record import (
    DocRecord,
    array,
    free,
    grid,
    integer,
    integers,
    number,
    numbers,
    text,
    texts,
)


@dataclass(frozen=True, eq=False)
class SectionalSummary(DocRecord):
    """How a plate larger than the bed is split into sections (the job's ``"sectional"`` block).

    Attributes
    ----------
    n_sections : int
    counts : (2,) int
        Sections along x and across.
    spacing_mm : (2,) float
        Distance between neighbouring sections' placements, mm.
    shared_mm : (2,) float
        Width shared by neighbouring sections, mm.
    transition_zone_mm : float
        Width of the zone where a section's correction blends with the earlier ones', mm.
    order : str
        The pressing order in words.
    plate_size_mm : (2,) float
        The x, y extent of the flat plate, mm.
    n_steps_total : int
        Press steps of all sections.
    max_travel_mm : float
        Largest travel of any section, mm.
    max_border_step_mm : float
        Largest step of the design recovered from the strokes where sections meet, mm.
    warnings : tuple of str
        The plan's warnings (a section stepping at its border), printed before pressing.
    """

    n_sections: int | None = integer()
    counts: tuple | None = integers()
    spacing_mm: tuple | None = numbers()
    shared_mm: tuple | None = numbers()
    transition_zone_mm: float | None = number()
    order: str | None = text()
    plate_size_mm: np.ndarray | None = array((2,))
    n_steps_total: int | None = integer()
    max_travel_mm: float | None = number()
    max_border_step_mm: float | None = number()
    warnings: tuple | None = texts()


@dataclass(frozen=True)
class TransitionReport(DocRecord):
    """A section's transition zone (its ``"transition"`` block).

    Attributes
    ----------
    zone_mm : float
        Width of the transition zone, mm.
    blended_punches : int
        Active punches whose correction blends with the earlier sections'.
    border_step_mm : float or None
        Largest step of the recovered design where this section meets the earlier ones, mm.
    start_share : float or None
        Where the section's steps start: this share of the way from the flat plate's tips to the tips
        touching the plate the earlier sections formed (1: where it lies;
        :func:`mppf.planning.section_start.section_start`); None: from the flat plate.
    """

    zone_mm: float | None = number()
    blended_punches: int | None = integer()
    border_step_mm: float | None = number()
    start_share: float | None = number()


@dataclass(frozen=True)
class BatchRecord(DocRecord):
    """What ``mppf batch`` stores in a job it planned, so a resumed batch can skip it.

    Attributes
    ----------
    key : str
        Hash of the plate's inputs and options (:func:`mppf.planning.batch.input_key`).
    row : dict
        The plate's summary row (column: value), shown again as it was; free-form.
    """

    key: str | None = text()
    row: dict | None = free()


@dataclass(frozen=True)
class LoopProvenance(DocRecord):
    """What the forming loop records in a job it corrected (its ``"loop"`` block).

    A job the loop corrected keeps the planner's reports of the first cycle, whose step counts are
    not its own (the job checks skip them).

    Attributes
    ----------
    plate_id : str
    cycle : int
        The cycle the job is pressed in.
    corrects_job_sha256 : str
        SHA-256 of the job of the cycle it corrects.
    """

    plate_id: str | None = text()
    cycle: int | None = integer()
    corrects_job_sha256: str | None = text()


@dataclass(frozen=True, eq=False)
class SectionPiece(DocRecord):
    """Which section of a plate a single-section job is (:func:`mppf.planning.sections.section_job`).

    Attributes
    ----------
    index : int
        1-based section number.
    of : int
        Sections of the plate.
    plate_centre_mm : (2,) float
        Press x, y of the plate centre for this section, mm.
    own_weight : (rows, cols) float, NaN where parked
        Weight of the section's own stroke correction at each punch.
    """

    index: int | None = integer()
    of: int | None = integer()
    plate_centre_mm: np.ndarray | None = array((2,))
    own_weight: np.ndarray | None = grid()


@dataclass(frozen=True)
class Seal(DocRecord):
    """The seal block of a job file (:mod:`mppf.core.seal`, which makes and checks it on the document).

    Attributes
    ----------
    algorithm : str
        ``HMAC-SHA256``.
    key_id : str
        16 hex digits naming the installation's key.
    sealed_by : str
        What sealed it (``mppf plan``, ``mppf loop``, ``mppf reseal by NAME``).
    parts : dict
        HMAC of each part of the job (part name: hex); free-form for every stage but the seal's.
    reason : str or None
        Why it was resealed (``mppf reseal --reason``).
    content_mac, mac : str
        HMAC of the content, and of the whole job.
    """

    algorithm: str | None = text()
    key_id: str | None = text()
    sealed_by: str | None = text()
    parts: dict | None = free()
    reason: str | None = text()
    content_mac: str | None = text()
    mac: str | None = text()
