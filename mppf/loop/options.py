"""The loop's option objects: a new plate's inputs, how it runs, and the files the history records.

:func:`mppf.loop.plate.start_plate` and :func:`mppf.loop.plate.record_plate` take the plate as one
:class:`PlateInputs` and how it runs as one :class:`LoopOptions`; :meth:`mppf.loop.history.History.create_plate`
takes the plate's files as one :class:`PlateFiles`. ``mppf loop`` (:mod:`mppf.cli._loop_run`), the demo
(:mod:`mppf.loop.demo`) and the benches build them once.
"""

from __future__ import annotations

from dataclasses import dataclass

from mppf.geometry.read import PointCloud
from mppf.loop.settings import LoopSettings
from mppf.model.material import Material
from mppf.model.press import PressConfig


@dataclass(frozen=True)
class PlateInputs:
    """A new plate as given to the loop.

    Attributes
    ----------
    design, flat : PointCloud
        The design surface and its flat (unfolded) shape, read by :func:`mppf.geometry.read.read_points`
        (their paths and SHA-256 are recorded with the plate).
    press : PressConfig
        The press it is planned for.
    thickness_mm : float
        Plate thickness, mm.
    """

    design: PointCloud
    flat: PointCloud
    press: PressConfig
    thickness_mm: float


@dataclass(frozen=True)
class LoopOptions:
    """How a plate runs in the loop (what is planned and recorded with it); the defaults are ``mppf loop``'s.

    Attributes
    ----------
    settings : LoopSettings
        When the loop stops and how hard it corrects (default: :class:`LoopSettings` ``()``); its
        ``springback``, ``yield_uncertainty_pct`` and ``margin_mm`` plan the first cycle.
    material : Material
        Nominal plate material, for the first cycle's springback pre-compensation (default: mild steel,
        :class:`Material` ``()``).
    setup : dict or None
        More to record with the plate (PLC URL, scanner, seed, physics, ...), JSON-ready; a ``"units"``
        entry (the length unit of the design file) is used to re-read it. Default None: nothing more.
    """

    settings: LoopSettings = LoopSettings()
    material: Material = Material()
    setup: dict | None = None


@dataclass(frozen=True)
class PlateFiles:
    """The files a plate is made from, as the history records them.

    Attributes
    ----------
    design_path, flat_path : path-like
        The design and flat point files.
    design_sha256, flat_sha256 : str
        Their SHA-256 (hex).
    """

    design_path: object
    design_sha256: str
    flat_path: object
    flat_sha256: str
