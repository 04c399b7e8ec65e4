"""Rigid registration of plates: paired closed form and ICP.

Two entry points, both returning a :class:`Registration` whose ``tf`` maps SOURCE
coordinates into TARGET coordinates (``target ~ tf @ source``):

- :func:`register_paired` - known correspondences (e.g. the point pairs of an
  unfolding): the closed-form unit-quaternion solution of the paper, eq. (2.3)-(2.10),
  with its errata fixed (``Q(Sigma)`` is a symmetric 4 x 4 matrix; the rotation is the
  standard quaternion matrix of :func:`mppf.core.transform.quaternion_to_matrix`;
  ``t = mu_target - R mu_source``).
- :func:`register_icp` - no correspondences: iterative closest points with
  ``scipy.spatial.cKDTree``, point-to-point (the paper: one quaternion step per
  iteration) or point-to-plane (linearised, normals of the target), a principal-axes
  start that tries the sign-flip candidates, trimmed or robust (Huber/Tukey) weights,
  coarse-to-fine subsampling, and outline pinning of the in-plane position of shallow
  plates. The ICP loop itself lives in :mod:`mppf.registration.icp`.

The math, the defaults and the measured figures are in ``docs/math-registration.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from mppf.registration import icp
from mppf.core.errors import GeometryError, InputError
from mppf.core.rigid import fit_rigid
from mppf.geometry.frame import fit_frame
from mppf.geometry.io import check_plate
from mppf.core.progress import NULL_REPORTER, Reporter
from mppf.core.transform import apply_tf, as_points, make_tf, tf_to_list

METHODS = ("point", "plane")
"""ICP error metrics: point-to-point (the paper) and point-to-plane."""

ROBUST_KERNELS = ("huber", "tukey")
"""Robust weight functions for ICP pairs (scale from the median absolute residual)."""

FLAT_RATIO = 3e-3
"""A cloud is flat when its spread along its normal is below this fraction of its in-plane spread."""

AMBIGUOUS_RATIO = 1.25
"""The principal-axes start is ambiguous when the second best candidate scores within this factor."""

COARSE_POINTS = 4000
"""Source points of the coarse stage (clouds larger than twice this are registered coarse-to-fine)."""

SCORE_POINTS = 1000
"""Source points used to score the principal-axes candidates."""

SCORE_ITERATIONS = 8
"""ICP iterations run from each principal-axes candidate before scoring it."""


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


def _check_finite(points: np.ndarray, name: str) -> None:
    bad = ~np.all(np.isfinite(points), axis=1)
    if bad.any():
        first = int(np.argmax(bad))
        raise InputError(
            f"{name}: point {first} has a NaN or infinite coordinate {points[first].tolist()}",
            hint="remove or repair invalid points before registering",
        )


def _check_cloud(points, name: str, min_points: int = 3) -> np.ndarray:
    """Shape, finiteness, count and spread checks of one point set."""
    pts = as_points(points, name=name)
    _check_finite(pts, name)
    if pts.shape[0] < min_points:
        raise GeometryError(
            f"{name}: {pts.shape[0]} point(s), registration needs at least {min_points} "
            "non-collinear points",
            hint="give more points",
        )
    return check_plate(pts, min_points=min_points, source=name)


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
    src, tgt = _check_cloud(src, "source"), _check_cloud(tgt, "target")
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


# ------------------------------------------------------------------ ICP front end


def _proper_axes(axes: np.ndarray) -> np.ndarray:
    return axes if np.linalg.det(axes) > 0 else axes * np.array([[1.0], [1.0], [-1.0]])


SIGN_FLIPS = ((1, 1, 1), (-1, -1, 1), (-1, 1, -1), (1, -1, -1))
"""Proper sign flips of the (u, v, n) principal axes tried by the principal-axes start."""


def principal_candidates(source_frame, target_frame) -> list[np.ndarray]:
    """The four proper rotations that align the source's principal axes with the target's.

    Returns
    -------
    list of (4, 4) float
        ``tf`` candidates mapping source into target, centroid onto centroid.
    """
    a_s = _proper_axes(source_frame.axes)
    a_t = _proper_axes(target_frame.axes)
    out = []
    for flip in SIGN_FLIPS:
        rotation = a_t.T @ np.diag(flip) @ a_s
        out.append(make_tf(rotation, target_frame.origin - rotation @ source_frame.origin))
    return out


def _spreads(frame, points: np.ndarray) -> tuple[float, float]:
    """(in-plane RMS radius, RMS along the normal) of points in their frame, mm."""
    local = frame.to_local(points)
    return float(np.sqrt((local[:, :2] ** 2).sum(axis=1).mean())), float(local[:, 2].std())


def _subsample(n: int, count: int, rng: np.random.Generator) -> np.ndarray:
    if count >= n:
        return np.arange(n)
    return np.sort(rng.choice(n, size=count, replace=False))


def _check_options(method, init, max_iterations, trim_fraction, robust, max_points, pin_outline):
    if method not in METHODS:
        raise InputError(f"unknown ICP method {method!r}", hint=f"use one of {', '.join(METHODS)}")
    if isinstance(init, str):
        if init not in ("principal", "identity"):
            raise InputError(f"unknown init {init!r}", hint="use principal, identity or a 4x4 transform")
    else:
        tf0 = np.asarray(init, dtype=float)
        if tf0.shape != (4, 4) or not np.all(np.isfinite(tf0)):
            raise InputError(f"init must be a finite 4x4 transform, got shape {tf0.shape}")
        rot = tf0[:3, :3]
        if not np.allclose(rot @ rot.T, np.eye(3), atol=1e-6) or np.linalg.det(rot) < 0:
            raise InputError("init is not a rigid transform (its 3x3 part is not a rotation)",
                             hint="give a proper rotation and a translation")
    if int(max_iterations) < 1:
        raise InputError(f"max_iterations must be at least 1, got {max_iterations}",
                         hint="give the iteration limit per stage, e.g. 100")
    if trim_fraction is not None and not 0.0 <= float(trim_fraction) < 0.9:
        raise InputError(f"trim_fraction must be in [0, 0.9), got {trim_fraction}",
                         hint="the fraction of the worst pairs dropped each iteration, e.g. 0.1")
    if robust is not None and robust not in ROBUST_KERNELS:
        raise InputError(f"unknown robust kernel {robust!r}", hint=f"use one of {', '.join(ROBUST_KERNELS)}")
    if int(max_points) < 100:
        raise InputError(f"max_points must be at least 100, got {max_points}")
    if pin_outline not in ("auto", True, False):
        raise InputError(f"pin_outline must be 'auto', True or False, got {pin_outline!r}")


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
    source : (n, 3) float, mm
        The cloud that moves (a scan, or a flat unfolded plate).
    target : (m, 3) float, mm
        The fixed cloud (the design); the closest points and normals come from it.
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
        ``COARSE_POINTS`` of clouds above twice that. The target is always used whole.
    pin_outline : {"auto", True, False}
        Pin the in-plane position (and the turn about the normal for elongated
        plates: always with ``method="point"``, with "plane" where the surface fixes
        it worse than ``mppf.registration.icp.PIN_TURN_DEG``) with the outline: the area centroid
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
    _check_options(method, init, max_iterations, trim_fraction, robust, max_points, pin_outline)
    src = _check_cloud(source, "source")
    tgt = _check_cloud(target, "target", min_points=3 if method == "point" else icp.NORMAL_NEIGHBOURS)
    rng = np.random.default_rng(seed)
    notes: list[str] = []

    # 1. frames of both clouds; detect flat against curved
    frame_s, frame_t = fit_frame(src), fit_frame(tgt)
    radius_s, thick_s = _spreads(frame_s, src)
    radius_t, thick_t = _spreads(frame_t, tgt)
    flat_s, flat_t = thick_s < FLAT_RATIO * radius_s, thick_t < FLAT_RATIO * radius_t
    flat_vs_curved = flat_s != flat_t
    if flat_vs_curved and method == "plane":
        method = "point"
        notes.append("point-to-plane overridden by point-to-point: one plate is flat and the other "
                     "curved, and a plane metric slides the flat plate off the curved one")

    # 2. the fixed target: kd-tree, lazily computed normals, outline
    tree = cKDTree(tgt)
    problem = icp.Problem(target=tgt, tree=tree, frame=frame_t, method=method,
                          trim_fraction=trim_fraction, robust=robust)
    fine_idx = _subsample(src.shape[0], int(max_points), rng)
    coarse_idx = fine_idx[_subsample(fine_idx.size, COARSE_POINTS, rng)] if fine_idx.size > 2 * COARSE_POINTS else None

    # 3. start
    init_info: dict
    ambiguous = False
    if isinstance(init, str) and init == "principal":
        score_idx = fine_idx[_subsample(fine_idx.size, SCORE_POINTS, rng)]
        tf0, init_info = _principal_start(problem, src[score_idx], frame_s, frame_t)
        ambiguous = init_info["ambiguous"]
    elif isinstance(init, str):
        tf0, init_info = np.eye(4), {"kind": "identity"}
    else:
        tf0, init_info = np.asarray(init, dtype=float).copy(), {"kind": "given"}

    # 4. coarse stage, unpinned (on a subsample of large clouds)
    tol = (tol_translation_mm, tol_rotation_rad, tol_relative_mse)
    fine_src = src[fine_idx]
    coarse_src = fine_src if coarse_idx is None else src[coarse_idx]
    reporter.start("registering", total=None)
    stage = icp.run(problem, coarse_src, tf0, max_iterations=max_iterations,
                    tol=(10 * tol[0], 10 * tol[1], 10 * tol[2]), reporter=reporter)
    tf, total_iter, history = stage.tf, stage.iterations, list(stage.rms_history)

    # 5. outline pin: when both clouds cover the same plate, the outline fixes the in-plane
    #    position (and the turn about the normal where the metric leaves it loose)
    pin = None
    if pin_outline is not False:
        # point-to-point sees the turn about the normal only through the in-plane offsets to the
        # closest target points: on a differently sampled target these follow the sampling
        # pattern (about the point spacing) rather than the shape, so the outline fixes the turn
        # better; point-to-plane fixes it from the normals where the surface is curved enough
        pin_turn = flat_vs_curved or method == "point"
        if not pin_turn:
            turn_sigma = icp.uncertainty(problem, icp.evaluate(problem, fine_src, tf), sigma_mm=1.0)["r_n_deg"]
            pin_turn = turn_sigma is None or turn_sigma > icp.PIN_TURN_DEG
        candidates = icp.outline_candidates(frame_s, src, fine_src)
        pin, coverage = icp.outline_pin(problem, candidates, tf, require_coverage=pin_outline == "auto",
                                        pin_turn=pin_turn)
        if pin is None:
            notes.append(f"outline not pinned: {coverage}")

    # 6. fine stage, pinned when the outline allows
    stage = icp.run(problem, fine_src, tf, max_iterations=max_iterations, tol=tol, pin=pin,
                    reporter=reporter)
    reporter.finish()
    total_iter += stage.iterations
    history += list(stage.rms_history)

    # 7. final residuals and uncertainty at the result
    final = icp.evaluate(problem, fine_src, stage.tf)
    history.append(final.rms_mm)
    uncertainty = icp.uncertainty(problem, final)
    uncertainty["in_plane"] = "pinned by the outline" if pin is not None else "from the surface shape"
    free = [axis for axis in ("u", "v") if uncertainty.get(f"t_{axis}_mm") is None]
    if pin is None and free:
        notes.append(f"the in-plane shift along {' and '.join(free)} is not fixed by the surface shape "
                     "(too shallow) and the outline was not used: it stays where the start put it; "
                     "scan the whole plate so the outline pins it, or check it against marks")
    return Registration(
        tf=stage.tf, rms_mm=final.rms_mm, iterations=total_iter, rms_history=history,
        converged=stage.converged, stop_reason=stage.stop_reason, method=method,
        inlier_fraction=final.inlier_fraction, init=init_info, ambiguous_start=ambiguous,
        uncertainty=uncertainty, outline_pinned=pin is not None, notes=tuple(notes),
    )


def _principal_start(problem, score_src: np.ndarray, frame_s, frame_t) -> tuple[np.ndarray, dict]:
    """Run each principal-axes candidate a few iterations; keep the best by trimmed RMS."""
    candidates = principal_candidates(frame_s, frame_t)
    scores, refined = [], []
    for tf in candidates:
        stage = icp.run(problem, score_src, tf, max_iterations=SCORE_ITERATIONS, tol=(0.0, 0.0, 0.0),
                        metric="point")
        refined.append(stage.tf)
        scores.append(icp.trimmed_rms(problem, score_src, stage.tf))
    order = np.argsort(scores)
    best, second = int(order[0]), int(order[1])
    ambiguous = bool(scores[second] <= AMBIGUOUS_RATIO * scores[best] + 1e-9)
    info = {
        "kind": "principal",
        "candidates": ["".join("+" if s > 0 else "-" for s in flip) for flip in SIGN_FLIPS],
        "scores_mm": [float(s) for s in scores],
        "chosen": best,
        "ambiguous": ambiguous,
    }
    return refined[best], info

