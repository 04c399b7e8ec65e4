"""Typed settings of the registration stages: one frozen dataclass per stage, defaults commented.

- :class:`Matching`: how the ICP pairs are formed and weighted (one ICP loop).
- :class:`RegisterOptions`: the options of one :func:`mppf.registration.register.register_icp` call.
- :class:`PrincipalStart`: the scoring of the four principal-axes starts of ``register_icp``.
- :class:`ScanStart`: the start of a scan's registration onto its design
  (:mod:`mppf.registration.scan_start`: converged starts, rotation hint, reference mark).
- :class:`ScanStages`: the two ICP stages that register a scan onto its design skin
  (:func:`mppf.measure.compare.compare`).
- :class:`OutlineFit`: the re-placement of a registered scan by its outline
  (:mod:`mppf.registration.outline_fit`).

Every value is checked once, in the dataclass (:func:`mppf.core.validate.check_number`);
lengths in mm, angles in degrees unless a name says ``_rad``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import InputError
from mppf.core.validate import check_number

METHODS = ("point", "plane")
"""ICP error metrics: point-to-point (the paper) and point-to-plane."""

ROBUST_KERNELS = ("huber", "tukey")
"""Robust weight functions for ICP pairs (scale from the median absolute residual)."""


@dataclass(frozen=True)
class Matching:
    """How the pairs of one ICP loop are formed and weighted."""

    metric: str = "point"               # "point": closest-point distance; "plane": along the target normal
    trim_fraction: float | None = None  # drop this fraction of the worst pairs each iteration, in [0, 0.9)
    robust: str | None = None           # "huber" or "tukey" weights, scale 1.4826 x the median residual

    def __post_init__(self):
        if self.metric not in METHODS:
            raise InputError(f"unknown ICP method {self.metric!r}", hint=f"use one of {', '.join(METHODS)}")
        if self.trim_fraction is not None:
            check_number("trim_fraction", self.trim_fraction, low=0.0, high=0.9, high_open=True,
                         hint="the fraction of the worst pairs dropped each iteration, e.g. 0.1")
        if self.robust is not None and self.robust not in ROBUST_KERNELS:
            raise InputError(f"unknown robust kernel {self.robust!r}", hint=f"use one of {', '.join(ROBUST_KERNELS)}")


@dataclass(frozen=True, eq=False)
class RegisterOptions:
    """The options of one ICP registration (:func:`mppf.registration.register.register_icp`), checked once.

    Attributes
    ----------
    method : {"point", "plane"}
        Error metric, see :attr:`Matching.metric`. Default "point".
    init : {"principal", "identity"} or (4, 4) float
        Start: principal axes and centroids (the four sign flips converged, the best kept),
        the identity, or a given rigid source-to-target transform. Default "principal".
    max_iterations : int
        Iteration limit of each stage (coarse and fine), >= 1. Default 100.
    trim_fraction, robust
        See :class:`Matching`. Default None (no trim, plain least squares).
    max_points : int
        The source is registered on at most this many points (a seeded subsample), >= 100.
        Default 30000.
    coarse_points : int
        Points of the coarse stage of sources above twice this many. Default 4000.
    pin_outline : {"auto", True, False}
        Let the outline have its say in the in-plane pose where the surface leaves it free
        (:mod:`mppf.registration.pin`); "auto": when both clouds cover the same plate.
    tol_translation_mm, tol_rotation_rad : float
        Converged when an iteration moves the source centroid less than this (mm) and turns
        it less than this (rad). Defaults 1e-3 mm, 1e-5 rad.
    tol_relative_mse : float
        Also converged when the MSE changes by less than this fraction. Default 1e-9.
    seed : int
        Seed of the subsampling (results are reproducible). Default 0.
    check_starts : bool
        From a given or identity start, also converge the principal-axes starts and keep
        the best (a wrong start settles as readily). Default True.
    """

    method: str = "point"
    init: str | np.ndarray = "principal"
    max_iterations: int = 100
    trim_fraction: float | None = None
    robust: str | None = None
    max_points: int = 30000
    coarse_points: int = 4000
    pin_outline: bool | str = "auto"
    tol_translation_mm: float = 1e-3
    tol_rotation_rad: float = 1e-5
    tol_relative_mse: float = 1e-9
    seed: int = 0
    check_starts: bool = True

    def __post_init__(self):
        Matching(self.method, self.trim_fraction, self.robust)  # checks those three
        check_init(self.init)
        check_number("max_iterations", self.max_iterations, low=1, integer=True,
                     hint="give the iteration limit per stage, e.g. 100")
        check_number("max_points", self.max_points, low=100, integer=True)
        if self.pin_outline not in ("auto", True, False):
            raise InputError(f"pin_outline must be 'auto', True or False, got {self.pin_outline!r}")
        for name in ("tol_translation_mm", "tol_rotation_rad", "tol_relative_mse"):
            check_number(name, getattr(self, name), low=0.0)

    @property
    def principal_start(self) -> bool:
        """Whether the start is the principal axes' (not the identity or a given transform)."""
        return isinstance(self.init, str) and self.init == "principal"

    @property
    def matching(self) -> Matching:
        """The pairing of the fine stage."""
        return Matching(self.method, self.trim_fraction, self.robust)

    @property
    def tolerances(self) -> tuple[float, float, float]:
        """(translation mm, rotation rad, relative MSE change) of the fine stage."""
        return self.tol_translation_mm, self.tol_rotation_rad, self.tol_relative_mse


@dataclass(frozen=True)
class PrincipalStart:
    """The four principal-axes starts (proper sign flips of the axes) of ``register_icp``, converged and scored."""

    points: int = 1000                  # source points (a seeded subsample) each candidate is fitted on
    iterations: int = 30                # ICP iterations (point-to-plane; point-to-point flat against curved)
    tol_translation_mm: float = 0.01    # a candidate has converged when an iteration moves it less than this ...
    tol_rotation_rad: float = 1e-4      # ... and turns it less than this
    tol_relative_mse: float = 1e-6      # (or its MSE changes by less than this fraction)

    @property
    def tolerances(self) -> tuple[float, float, float]:
        """(translation mm, rotation rad, relative MSE change) of a candidate's fit."""
        return self.tol_translation_mm, self.tol_rotation_rad, self.tol_relative_mse


@dataclass(frozen=True)
class ScanStart:
    """The start of a scan's registration onto its design (:func:`mppf.registration.scan_start.choose_start`)."""

    points: int = 2000                   # scan points (a seeded subsample) each start is fitted and scored on
    iterations: int = 40                 # ICP iterations (per stage) run from each principal-axes start
    trim_fraction: float = 0.05          # worst pairs dropped in each iteration of a start fit
    tie_ratio: float = 1.25              # the best two converged starts within this factor of RMS: a tie
    mark_radius_fraction: float = 0.1    # a start agrees with the reference mark within this fraction of the length
    held_turn_step_deg: float = 15.0     # step of the turns about the normal tried with the mark held in place
    held_keep: int = 3                   # best of those turns that are fitted with the mark held
    hold_rounds: int = 5                 # rounds of a held fit: ICP, then the mark shifted back on its place
    held_max_rms_fraction: float = 0.05  # a held fit is taken within this RMS (fraction of the length) of the design
    workers: int | None = None           # threads the independent start fits run on (the results do not depend on
    #                                      it); None: mppf.core.threads.worker_threads() ($MPPF_THREADS, else <= 2)


@dataclass(frozen=True)
class ScanStages:
    """The two ICP stages that register a scan onto its dense design skin (``compare``)."""

    point_points: int = 3000          # scan points of the point-to-point stage (a seeded subsample)
    point_iterations: int = 40        # its iteration limit per stage
    plane_points: int = 30000         # scan points of the point-to-plane stage
    plane_iterations: int = 100       # its iteration limit per stage
    trim_fraction: float = 0.05       # worst pairs dropped in each point-to-plane iteration
    robust: str = "huber"             # point-to-plane pair weights
    overhang_fraction: float = 0.02   # point-to-plane is rejected when it leaves this much more of the scan
    #                                   beyond the design's edge than point-to-point


@dataclass(frozen=True)
class OutlineFit:
    """Re-placing a registered scan by its outline in the plane and its deviations out of it."""

    rounds: int = 2                   # rounds of outline fit and plane removal (a tilt moves a curved plate's edge)
    lift_passes: int = 3              # removals of the deviations' best plane in each round
    iterations: int = 60              # iterations of the 2-D edge fit
    min_turn_deg: float = 0.5         # a smaller outline turn is not applied (the edge gives it to tenths of a
    #                                   degree only, the surface fit of a curved plate far better): shift only
    max_turn_deg: float = 15.0        # a larger turn is an implausible fit: rejected
    max_shift_fraction: float = 0.1   # largest in-plane shift, as a fraction of the plate length
    edge_spacings: float = 3.0        # scan points within this many point spacings of its convex outline: the edge
    min_edge_points: int = 20         # fewer edge points: the outline fit is skipped
    piece_spacings: float = 8.0       # length of the pieces an outline edge is cut into, in point spacings
    edge_quantile: float = 0.1        # the scan's edge along a piece: this low quantile of its points' insets
    band_spacings: tuple[float, float] = (4.0, 0.6)  # band (point spacings) around the outer pieces' edge in which
    #                                   a piece is used: it narrows from the first to the second value
    slope_floor: float = 0.2          # the normal's z component is held at least this when a deviation along the
    #                                   normal is turned into a height along z


def check_init(init) -> None:
    """Refuse a start that is neither "principal", "identity" nor a finite rigid (4, 4) transform (InputError)."""
    if isinstance(init, str):
        if init not in ("principal", "identity"):
            raise InputError(f"unknown init {init!r}", hint="use principal, identity or a 4x4 transform")
        return
    tf0 = np.asarray(init, dtype=float)
    if tf0.shape != (4, 4) or not np.all(np.isfinite(tf0)):
        raise InputError(f"init must be a finite 4x4 transform, got shape {tf0.shape}")
    rot = tf0[:3, :3]
    if not np.allclose(rot @ rot.T, np.eye(3), atol=1e-6) or np.linalg.det(rot) < 0:
        raise InputError("init is not a rigid transform (its 3x3 part is not a rotation)",
                         hint="give a proper rotation and a translation")
