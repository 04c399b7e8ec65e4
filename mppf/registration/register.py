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
from mppf.registration import icp
from mppf.registration.pin import PIN_TURN_DEG, outline_candidates, outline_pin
from mppf.registration.settings import IcpSettings, Matching, PrincipalStart
from mppf.registration.starts import principal_start
from mppf.registration.target import (
    NORMAL_NEIGHBOURS,
    Cloud,
    RegistrationTarget,
    build_target,
    check_cloud,
    check_min_points,
    prepare,
)


PRINCIPAL = PrincipalStart()
"""Scoring of the principal-axes candidates (defaults of :class:`~mppf.registration.settings.PrincipalStart`)."""


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
        True when a stop test was met (not the iteration limit).
    stop_reason : str
        Why the iterations stopped.
    method : str
        "paired", "point" or "plane" (the metric actually used).
    inlier_fraction : float
        Fraction of the source pairs with a non-zero weight in the last iteration.
    init : dict
        How the start was chosen: ``kind`` ("principal", "identity", "given",
        "closed form"), and for "principal" the candidate sign flips, their scores
        (trimmed RMS, mm) and the chosen one.
    ambiguous_start : bool
        The best two principal-axes candidates scored nearly the same (a symmetric
        plate): the turn of the result should be checked by the operator.
    uncertainty : dict
        One-sigma uncertainty per degree of freedom in the target's plate frame
        (u, v in-plane, n normal): ``t_u_mm``, ``t_v_mm``, ``t_n_mm``, ``r_u_deg``,
        ``r_v_deg``, ``r_n_deg`` from the point-to-plane information matrix (None =
        not observable from the surface shape), and ``observability`` (its
        normalised eigenvalues, ascending). With ``outline_pinned`` the in-plane
        values describe the surface alone; ``in_plane`` says whether the outline pinned them.
    outline_pinned : bool
        The in-plane position (and, for elongated plates, the turn about the normal)
        was pinned by the outline and the centroid of the outline.
    notes : tuple of str
        Decisions the operator should know (metric overridden, pinning skipped, ...).
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
        }


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
        init={"kind": "closed form"},
    )


def _subsample(n: int, count: int, rng: np.random.Generator) -> np.ndarray:
    if count >= n:
        return np.arange(n)
    return np.sort(rng.choice(n, size=count, replace=False))


def _check_init(init) -> None:
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


def _as_target(target, method: str) -> RegistrationTarget:
    """The target as a RegistrationTarget (built here from an array), with enough points for the metric."""
    needed = 3 if method == "point" else NORMAL_NEIGHBOURS
    if isinstance(target, RegistrationTarget):
        check_min_points(target.n_points, target.name, needed)
        return target
    check_min_points(as_points(target, name="target").shape[0], "target", needed)
    return build_target(target, "target")


def register_icp(
    source,
    target,
    *,
    method: str = "point",
    init="principal",
    max_iterations: int = 100,
    trim_fraction: float | None = None,
    robust: str | None = None,
    max_points: int = 30000,
    pin_outline="auto",
    tol_translation_mm: float = 1e-3,
    tol_rotation_rad: float = 1e-5,
    tol_relative_mse: float = 1e-9,
    seed: int = 0,
    reporter: Reporter = NULL_REPORTER,
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
    method : {"point", "plane"}
        Point-to-point (the paper) or point-to-plane. A plane metric is never used
        between a flat and a curved plate: it is overridden by "point" (noted).
    init : {"principal", "identity"} or (4, 4) float
        Start: principal axes and centroids (the four proper sign flips are each
        run a few iterations and scored, the best is kept), the identity, or a given
        source-to-target transform.
    max_iterations : int
        Iteration limit of each stage (coarse and fine).
    trim_fraction : float, optional
        Drop this fraction of the worst pairs each iteration (e.g. 0.1).
    robust : {"huber", "tukey"}, optional
        Robust pair weights, scale from the median absolute residual.
    max_points : int
        The source is registered on at most this many points (a seeded random
        subsample); a coarse stage (unpinned, tolerances x 10) runs first, on
        ``IcpSettings.coarse_points`` of clouds above twice that. The target is always used whole.
    pin_outline : {"auto", True, False}
        Pin the in-plane position (and the turn about the normal for elongated
        plates: always with ``method="point"``, with "plane" where the surface fixes
        it worse than ``mppf.registration.pin.PIN_TURN_DEG``) with the outline: the area centroid
        and principal axes of the convex outline in the target's plate plane. "auto"
        pins when both clouds cover the same plate (outline areas and extents within 12 %).
    tol_translation_mm, tol_rotation_rad : float
        Converged when one iteration moves the source centroid less than this and
        turns it less than this.
    tol_relative_mse : float
        Also converged when the mean squared residual changes by less than this
        fraction between iterations.
    seed : int
        Seed of the subsampling (results are reproducible).
    reporter : Reporter
        Progress (iterations). Decisions are returned in ``Registration.notes``.

    Returns
    -------
    Registration

    Raises
    ------
    InputError
        Bad options, NaN/inf in the points.
    GeometryError
        Fewer than 3 points or points that do not span a plane (either cloud).
    """
    settings = IcpSettings(method=method, max_iterations=max_iterations, trim_fraction=trim_fraction, robust=robust,
                           max_points=max_points, pin_outline=pin_outline, tol_translation_mm=tol_translation_mm,
                           tol_rotation_rad=tol_rotation_rad, tol_relative_mse=tol_relative_mse, seed=seed)
    _check_init(init)
    cloud = source if isinstance(source, Cloud) else prepare(source, "source")
    tgt = _as_target(target, method)
    src, frame_s = cloud.points, cloud.frame
    rng = np.random.default_rng(seed)
    notes: list[str] = []

    # 1. never a plane metric between a flat and a curved plate
    flat_vs_curved = cloud.flat != tgt.flat
    if flat_vs_curved and method == "plane":
        method = "point"
        notes.append("point-to-plane overridden by point-to-point: one plate is flat and the other "
                     "curved, and a plane metric slides the flat plate off the curved one")
    matching = Matching(method, trim_fraction, robust)

    # 2. the source points of the fine stage, and of the coarse stage of large clouds
    fine_idx = _subsample(src.shape[0], settings.max_points, rng)
    coarse_idx = (fine_idx[_subsample(fine_idx.size, settings.coarse_points, rng)]
                  if fine_idx.size > 2 * settings.coarse_points else None)
    fine_src = src[fine_idx]
    coarse_src = fine_src if coarse_idx is None else src[coarse_idx]

    # 3. start: the best principal-axes candidate, the identity or the given transform
    tf0, init_info = _start(init, tgt, src, fine_idx, frame_s, matching, rng)

    # 4. coarse stage, unpinned (on a subsample of large clouds)
    tol = settings.tolerances
    nearest = icp.Nearest(tgt)  # the fine points' closest target points, kept from loop to loop
    reporter.start("registering", total=None)
    coarse = icp.run(tgt, coarse_src, tf0, matching, max_iterations=settings.max_iterations,
                     tol=(10 * tol[0], 10 * tol[1], 10 * tol[2]), nearest=nearest if coarse_idx is None else None,
                     reporter=reporter)

    # 5. outline pin: when both clouds cover the same plate, the outline fixes the in-plane
    #    position (and the turn about the normal where the metric leaves it loose)
    pin = _outline_pin(tgt, src, fine_src, frame_s, coarse.tf, matching, settings.pin_outline, flat_vs_curved, notes,
                       nearest)

    # 6. fine stage, pinned when the outline allows
    fine = icp.run(tgt, fine_src, coarse.tf, matching, max_iterations=settings.max_iterations, tol=tol, pin=pin,
                   nearest=nearest, reporter=reporter)
    reporter.finish()

    # 7. final residuals and uncertainty at the result
    return _result(tgt, fine_src, coarse, fine, matching, pin, init_info, notes, nearest)


def _start(init, target, src, fine_idx, frame_s, matching, rng) -> tuple[np.ndarray, dict]:
    """The start transform and how it was chosen (``Registration.init``)."""
    if isinstance(init, str) and init == "principal":
        score_idx = fine_idx[_subsample(fine_idx.size, PRINCIPAL.points, rng)]
        return principal_start(target, src[score_idx], frame_s, matching, PRINCIPAL)
    if isinstance(init, str):
        return np.eye(4), {"kind": "identity"}
    return np.asarray(init, dtype=float).copy(), {"kind": "given"}


def _outline_pin(target, src, fine_src, frame_s, tf, matching, pin_outline, flat_vs_curved, notes, nearest):
    """The outline pin at ``tf``, or None (the reason added to ``notes``)."""
    if pin_outline is False:
        return None
    # point-to-point sees the turn about the normal only through the in-plane offsets to the
    # closest target points: on a differently sampled target these follow the sampling
    # pattern (about the point spacing) rather than the shape, so the outline fixes the turn
    # better; point-to-plane fixes it from the normals where the surface is curved enough
    pin_turn = flat_vs_curved or matching.metric == "point"
    if not pin_turn:
        pairs = icp.evaluate(target, fine_src, tf, matching, nearest)
        turn_sigma = icp.uncertainty(target, pairs, sigma_mm=1.0)["r_n_deg"]
        pin_turn = turn_sigma is None or turn_sigma > PIN_TURN_DEG
    candidates = outline_candidates(frame_s, src, fine_src)
    pin, coverage = outline_pin(target, candidates, tf, require_coverage=pin_outline == "auto", pin_turn=pin_turn)
    if pin is None:
        notes.append(f"outline not pinned: {coverage}")
    return pin


def _result(target, fine_src, coarse, fine, matching, pin, init_info, notes, nearest) -> Registration:
    """The Registration of the fine stage's transform: residuals, uncertainty, notes."""
    final = icp.evaluate(target, fine_src, fine.tf, matching, nearest)
    uncertainty = icp.uncertainty(target, final)
    uncertainty["in_plane"] = "pinned by the outline" if pin is not None else "from the surface shape"
    free = [axis for axis in ("u", "v") if uncertainty.get(f"t_{axis}_mm") is None]
    if pin is None and free:
        notes.append(f"the in-plane shift along {' and '.join(free)} is not fixed by the surface shape "
                     "(too shallow) and the outline was not used: it stays where the start put it; "
                     "scan the whole plate so the outline pins it, or check it against marks")
    return Registration(
        tf=fine.tf, rms_mm=final.rms_mm, iterations=coarse.iterations + fine.iterations,
        rms_history=[*coarse.rms_history, *fine.rms_history, final.rms_mm], converged=fine.converged,
        stop_reason=fine.stop_reason, method=matching.metric, inlier_fraction=final.inlier_fraction,
        init=init_info, ambiguous_start=bool(init_info.get("ambiguous", False)), uncertainty=uncertainty,
        outline_pinned=pin is not None, notes=tuple(notes),
    )
