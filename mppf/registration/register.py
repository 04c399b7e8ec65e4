"""Rigid registration of plates: paired closed form and ICP.

Two entry points, both returning a :class:`Registration` whose ``tf`` maps SOURCE
coordinates into TARGET coordinates (``target ~ tf @ source``):

- :func:`register_paired` - known correspondences (e.g. the point pairs of an
  unfolding): the closed-form unit-quaternion solution of the paper, eq. (2.3)-(2.10),
  with its errata fixed (:func:`mppf.core.rigid.fit_rigid`).
- :func:`register_icp` - no correspondences: iterative closest points, point-to-point
  (the paper: one quaternion step per iteration) or point-to-plane (linearised, normals
  of the target), a principal-axes start that tries the sign-flip candidates
  (:mod:`mppf.registration.starts`), trimmed or robust (Huber/Tukey) weights,
  coarse-to-fine subsampling, and outline pinning of the in-plane position of shallow
  plates (:mod:`mppf.registration.pin`). The ICP loop itself lives in
  :mod:`mppf.registration.icp`, the fixed side in :mod:`mppf.registration.target`.

The math, the defaults and the measured figures are in ``docs/math-registration.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mppf.core.errors import InputError
from mppf.core.progress import NULL_REPORTER, Reporter
from mppf.core.rigid import fit_rigid
from mppf.core.transform import apply_tf, as_points, tf_to_list
from mppf.registration import icp, stages
from mppf.registration.settings import RegisterOptions, PrincipalStart
from mppf.registration.target import (
    NORMAL_NEIGHBOURS,
    Cloud,
    RegistrationTarget,
    build_target,
    check_cloud,
    check_min_points,
    prepare,
)
from mppf.registration.uncertainty import uncertainty as dof_uncertainty
from mppf.registration.trust import judge, plane_residuals, robust_scale_mm


PRINCIPAL = PrincipalStart()
"""The principal-axes candidates (defaults of :class:`~mppf.registration.settings.PrincipalStart`)."""


@dataclass(frozen=True, eq=False)
class Registration:
    """Result of a rigid registration.

    Attributes
    ----------
    tf : (4, 4) float
        Maps source coordinates into target coordinates (mm).
    rms_mm : float
        RMS of the final matched residuals used for the fit (inlier pairs; point
        distances for "paired"/"point", normal distances for "plane").
    iterations : int
        Solver iterations run (1 for the closed form; all ICP stages together).
    rms_history : list of float
        RMS (mm) at the start of each iteration, then at the final transform.
    converged : bool
        The judgement is "converged": a stop test was met (not the iteration limit) AND the
        residual is near the noise floor AND no other start fits clearly better (see
        ``judgement``). A pose that merely stopped moving is not converged.
    stop_reason : str
        Why the iterations stopped.
    method : str
        "paired", "point" or "plane" (the metric actually used).
    inlier_fraction : float
        Fraction of the source pairs with a non-zero weight in the last iteration.
    init : dict
        How the start was chosen: ``kind`` ("principal", "identity", "given", "closed
        form"), and the starts tried (``candidates``: their names, ``scores_mm``: RMS of
        their clipped normal residuals on one common sample once converged, ``chosen``,
        ``runner_up``: the best start that reached another pose).
    ambiguous_start : bool
        The best start and the best one that reached a different pose fit equally well
        within the noise (:func:`mppf.registration.trust.tie`; a symmetric plate): the
        turn of the result should be checked by the operator.
    uncertainty : dict
        One-sigma uncertainty per degree of freedom in the target's plate frame
        (u, v in-plane, n normal): ``t_u_mm``, ``t_v_mm``, ``t_n_mm``, ``r_u_deg``,
        ``r_v_deg``, ``r_n_deg`` from the point-to-plane information matrix (None =
        not observable from the surface shape), and ``observability`` (its
        normalised eigenvalues, ascending). These describe the surface alone;
        ``in_plane`` says what fixed the in-plane pose, ``outline_share`` how much the
        outline decided of each in-plane degree of freedom (0: the surface, 1: the outline).
    outline_pinned : bool
        The outline had its say in the in-plane pose (each direction weighted by how weakly
        the surface fixes it: ``uncertainty["outline_share"]``).
    notes : tuple of str
        Decisions the operator should know (metric overridden, pinning skipped, ...).
    judgement : str
        "converged", or "failed: ..." with the figures (iteration limit, or a residual far
        above the noise floor at the best start tried).
    residual_mm : float
        Robust scale (1.4826 x median) of the normal residuals of a sample of the source at
        the result.
    noise_mm : float
        The noise floor: the residual the right pose leaves
        (:func:`mppf.registration.trust.noise_floor_mm`).
    """

    tf: np.ndarray
    rms_mm: float
    iterations: int
    rms_history: list
    converged: bool
    stop_reason: str
    method: str
    inlier_fraction: float = 1.0
    init: dict = field(default_factory=dict)
    ambiguous_start: bool = False
    uncertainty: dict = field(default_factory=dict)
    outline_pinned: bool = False
    notes: tuple = ()
    judgement: str = ""
    residual_mm: float = float("nan")
    noise_mm: float = float("nan")

    def to_dict(self) -> dict:
        """A JSON-able dict: rms_mm, iterations, transform (4x4 row-major lists), method, ..."""
        return {
            "rms_mm": float(self.rms_mm),
            "iterations": int(self.iterations),
            "transform": tf_to_list(self.tf),
            "method": self.method,
            "converged": bool(self.converged),
            "stop_reason": self.stop_reason,
            "inlier_fraction": float(self.inlier_fraction),
            "rms_history": [float(v) for v in self.rms_history],
            "init": self.init,
            "ambiguous_start": bool(self.ambiguous_start),
            "uncertainty": self.uncertainty,
            "outline_pinned": bool(self.outline_pinned),
            "notes": list(self.notes),
            "judgement": self.judgement or ("converged" if self.converged else f"failed: {self.stop_reason}"),
            "residual_mm": _finite_or_none(self.residual_mm),
            "noise_mm": _finite_or_none(self.noise_mm),
        }


def _finite_or_none(value: float):
    return float(value) if np.isfinite(value) else None


# ------------------------------------------------------------------ paired closed form


def register_paired(source, target, weights=None) -> Registration:
    """Rigid transform of paired points by the closed-form unit quaternion.

    Parameters
    ----------
    source, target : (n, 3) float, mm
        Corresponding points, ``source[i] <-> target[i]``; n >= 3, not collinear.
    weights : (n,) float >= 0, optional
        Weight of each pair (default equal).

    Returns
    -------
    Registration
        ``tf`` maps source into target; ``rms_mm`` the RMS pair distance after it.

    Raises
    ------
    InputError
        Different point counts, NaN/inf, bad weights.
    GeometryError
        Fewer than 3 pairs, or the points are coincident or collinear.
    """
    src, tgt = as_points(source, name="source"), as_points(target, name="target")
    if src.shape[0] != tgt.shape[0]:
        raise InputError(
            f"paired registration needs the same number of points: source has {src.shape[0]}, "
            f"target {tgt.shape[0]}",
            hint="give point pairs in the same order, or use ICP (method point or plane)",
        )
    src, tgt = check_cloud(src, "source"), check_cloud(tgt, "target")
    w = None
    if weights is not None:
        w = np.asarray(weights, dtype=float).reshape(-1)
        if w.shape[0] != src.shape[0] or not np.all(np.isfinite(w)) or (w < 0).any() or w.sum() <= 0:
            raise InputError(
                f"weights must be {src.shape[0]} finite non-negative numbers with a positive sum",
                hint="give one weight per pair",
            )
    tf = fit_rigid(src, tgt, w)
    dist = np.linalg.norm(apply_tf(tf, src) - tgt, axis=1)
    rms = float(np.sqrt(np.average(dist**2, weights=w)))
    return Registration(
        tf=tf, rms_mm=rms, iterations=1, rms_history=[rms], converged=True,
        stop_reason="closed form (paired points)", method="paired",
        inlier_fraction=1.0 if w is None else float(np.count_nonzero(w) / w.size),
        init={"kind": "closed form"}, judgement="converged", residual_mm=rms,
    )


MIN_ICP_POINTS = 10
"""Fewest points of either cloud an ICP registration is run on (three points fit any surface: no judgement)."""


def check_icp_points(n_points: int, what: str) -> None:
    """Refuse a cloud too small for an ICP registration to say anything (``what``: the file, for the message).

    Raises
    ------
    GeometryError
        Fewer than :data:`MIN_ICP_POINTS` points.
    """
    from mppf.core.errors import GeometryError

    if n_points < MIN_ICP_POINTS:
        raise GeometryError(f"{what} has {n_points} point(s); a registration by ICP needs at least {MIN_ICP_POINTS} "
                            "(a few points fit any surface, so no judgement could be given)",
                            hint="give the whole scan or design; for a handful of matched points use --method paired")


def _as_target(target, method: str) -> RegistrationTarget:
    """The target as a RegistrationTarget (built here from an array), with enough points for the metric."""
    needed = 3 if method == "point" else NORMAL_NEIGHBOURS
    if isinstance(target, RegistrationTarget):
        check_min_points(target.n_points, target.name, needed)
        return target
    check_min_points(as_points(target, name="target").shape[0], "target", needed)
    return build_target(target, "target")


DEFAULT = RegisterOptions()
"""The default options of :func:`register_icp`."""


def register_icp(source, target, options: RegisterOptions = DEFAULT, reporter: Reporter = NULL_REPORTER
                 ) -> Registration:
    """Register a source cloud onto a target cloud by iterative closest points.

    Parameters
    ----------
    source : (n, 3) float, mm, or Cloud
        The cloud that moves (a scan, or a flat unfolded plate); a
        :class:`~mppf.registration.target.Cloud` prepared once
        (:func:`~mppf.registration.target.prepare`) spares its checks and frame to repeated
        registrations of the same cloud.
    target : (m, 3) float, mm, or RegistrationTarget
        The fixed cloud (the design); the closest points and normals come from it. A
        :class:`~mppf.registration.target.RegistrationTarget` built once
        (:func:`~mppf.registration.target.build_target`) spares its k-d tree, frame and
        normals to repeated registrations onto the same target.
    options : RegisterOptions
        Metric, start, iterations, trimming and robust weights, subsampling, outline pin,
        tolerances (:class:`mppf.registration.settings.RegisterOptions`, checked when built).
        A plane metric is never used between a flat and a curved plate: it is overridden by
        "point" (noted).
    reporter : Reporter
        Progress (iterations). Decisions are returned in ``Registration.notes``.

    Returns
    -------
    Registration
        With its ``judgement``: "converged" only when the residual is near the noise floor and
        no start tried fits clearly better.

    Raises
    ------
    InputError
        NaN/inf in the points, options not given as RegisterOptions.
    GeometryError
        Fewer than 3 points or points that do not span a plane (either cloud).
    """
    from threadpoolctl import threadpool_limits

    if not isinstance(options, RegisterOptions):
        raise InputError(f"register_icp takes its options as a RegisterOptions, got {type(options).__name__}",
                         hint="build them with mppf.registration.settings.RegisterOptions(...)")
    # many (n, 3) @ (3, 3) products, and the frames' small least squares: one BLAS thread is faster than a pool
    # that spins (the bulge fit of a 20,000-point frame: 1.2 ms of CPU against 8 ms on the 2 shared cores)
    with threadpool_limits(limits=1, user_api="blas"):
        cloud = source if isinstance(source, Cloud) else prepare(source, "source")
        tgt = _as_target(target, options.method)
        return _register(cloud, tgt, options, reporter)


def converge_start(cloud: Cloud, target: RegistrationTarget, start_tf, settings: RegisterOptions) -> np.ndarray:
    """A start converged (4, 4): ``register_icp(cloud, target, replace(settings, init=start_tf)).tf``
    (``pin_outline=False, check_starts=False``) without the noise floor, judgement and uncertainty a start
    fit does not use (about half of a fit on 2,000 points). ``cloud`` prepared, ``target`` built.
    """
    from threadpoolctl import threadpool_limits

    if settings.pin_outline is not False:
        raise ValueError("converge_start fits without the outline pin: give pin_outline=False")
    notes: list[str] = []
    matching, flat_vs_curved = stages.matching(cloud, target, settings, notes)
    problem = stages.Problem(target, cloud, stages.subsamples(cloud, settings), matching, settings, flat_vs_curved,
                             0.0, notes)
    with threadpool_limits(limits=1, user_api="blas"):
        fit = stages.fit(problem, np.asarray(start_tf, dtype=float).copy(), NULL_REPORTER)
    return fit.fine.tf


def _register(cloud: Cloud, target: RegistrationTarget, settings: RegisterOptions, reporter: Reporter):
    """The steps of :func:`register_icp` on checked inputs."""
    notes: list[str] = []
    # 1. never a plane metric between a flat and a curved plate
    matching, flat_vs_curved = stages.matching(cloud, target, settings, notes)
    # 2. the source points of the fine and coarse stages, and the sample every pose is judged on
    points = stages.subsamples(cloud, settings)
    # 3. the noise floor: the residual the right pose leaves
    floor = stages.floor(cloud, target, points)
    problem = stages.Problem(target, cloud, points, matching, settings, flat_vs_curved, floor, notes)
    # 4. the start: the best converged principal-axes candidate, the identity or the given transform
    tf0, init_info = stages.start(problem, PRINCIPAL)
    # 5. coarse stage, then the fine stage with the outline's say where the surface leaves the pose free
    fit = stages.fit(problem, tf0, reporter)
    # 6. from a given start that settled: converge the principal-axes starts too, go on from a clearly better one
    if not settings.principal_start and settings.check_starts and fit.fine.converged:
        fit, init_info = stages.check_starts(problem, fit, init_info, PRINCIPAL)
    # 7. the judgement, final residuals and uncertainty
    return _result(problem, fit, init_info)


def _result(problem: stages.Problem, fit: stages.Fit, init_info: dict) -> Registration:
    """The Registration of the fine stage's transform: residuals, judgement, uncertainty, notes."""
    target, points, matching, floor = problem.target, problem.points, problem.matching, problem.floor_mm
    flat_vs_curved, notes = problem.flat_vs_curved, problem.notes
    final = icp.evaluate(target, points.fine, fit.fine.tf, matching, fit.nearest)
    uncertainty = dof_uncertainty(target, final)
    uncertainty["in_plane"] = stages.in_plane(fit.pin)
    if fit.pin is not None:
        uncertainty["outline_share"] = fit.pin.weights
    free = [axis for axis in ("u", "v") if uncertainty.get(f"t_{axis}_mm") is None]
    if fit.pin is None and free:
        notes.append(f"the in-plane shift along {' and '.join(free)} is not fixed by the surface shape "
                     "(too shallow) and the outline was not used: it stays where the start put it; "
                     "scan the whole plate so the outline pins it, or check it against marks")
    residual = robust_scale_mm(plane_residuals(target, points.judge, fit.fine.tf))
    judgement = judge(fit.fine.converged, fit.fine.stop_reason, residual, floor, len(init_info.get("scores_mm", [0])),
                    compared=not flat_vs_curved)
    if flat_vs_curved:
        notes.append("flat against curved: the residual measures their difference in shape, not the fit")
    return Registration(
        tf=fit.fine.tf, rms_mm=final.rms_mm, iterations=fit.coarse.iterations + fit.fine.iterations,
        rms_history=[*fit.coarse.rms_history, *fit.fine.rms_history, final.rms_mm],
        converged=judgement == "converged", stop_reason=fit.fine.stop_reason, method=matching.metric,
        inlier_fraction=final.inlier_fraction, init=init_info, ambiguous_start=bool(init_info.get("ambiguous", False)),
        uncertainty=uncertainty, outline_pinned=fit.pin is not None, notes=tuple(notes), judgement=judgement,
        residual_mm=residual, noise_mm=floor,
    )
