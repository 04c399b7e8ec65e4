"""The ICP machinery behind :func:`mppf.registration.register.register_icp`.

One :class:`Problem` holds the fixed target (kd-tree, lazily computed normals, plate
frame, pair weighting); :func:`run` iterates "match closest points, weight the pairs,
solve one step (quaternion or linearised point-to-plane), pin the outline, test the
stop criteria"; :func:`evaluate` and :func:`uncertainty` describe the result. All
lengths in mm, angles in radians unless a name says ``_deg``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from mppf.core.errors import GeometryError
from mppf.core.polygon import area, convex_inset, convex_outline, moments
from mppf.core.rigid import fit_rigid
from mppf.core.progress import NULL_REPORTER, Reporter
from mppf.core.transform import apply_tf, make_tf, quaternion_to_matrix

PARALLEL_QUERY = 20000
"""Closest-point queries of at least this many points run on all cores."""

NORMAL_NEIGHBOURS = 10
"""Target points used for each local PCA normal."""

HUBER_K = 1.345
"""Huber threshold in robust scales (95 % efficiency for Gaussian residuals)."""

TUKEY_C = 4.685
"""Tukey biweight cut-off in robust scales (95 % efficiency for Gaussian residuals)."""

SCORE_KEEP = 0.6
"""Fraction of the best pair distances that scores a principal-axes candidate."""

COVERAGE_TOL = 0.12
"""Outline areas and extents of source and target within this fraction: same plate."""

ELONGATED = 1.3
"""Outline second-moment ratio above which the outline also pins the turn about the normal."""

UNOBSERVABLE = 1e-5
"""Directions of a linearised step whose information is below this fraction of the largest are held."""

MAX_EXTRAPOLATION = 25.0
"""Largest jump of the accelerated ICP, in multiples of the last increment."""

STALL_ITERATIONS = 10
"""A stage stops when its MSE has not reached a new low (by the relative tolerance) for this
many iterations: the closest-point sets cycle (seen with point-to-plane on 4,000 points)."""

PIN_BAND_FRACTION = 0.02
"""Width of the band of outline candidates along the convex outline, in plate sizes (sqrt area)."""

OUTLINE_NEIGHBOURS = 8
"""Neighbour rank whose distance tells isolated points (outliers) from the plate."""

ISOLATED = 4.0
"""Points whose neighbour distance exceeds this many times the median are not outline."""

PIN_TURN_DEG = 0.05
"""Point-to-plane: the outline also pins the turn about the normal when the surface fixes it
worse than this (one sigma, in degrees, for 1 mm noise on the source points). Point-to-point
always has it pinned (it sees the turn only through in-plane closest-point offsets)."""


def query(tree, points: np.ndarray, k: int = 1):
    """``tree.query`` on all cores for large batches (threads cost more than they save on small ones)."""
    return tree.query(points, k=k, workers=-1 if points.shape[0] >= PARALLEL_QUERY else 1)


@dataclass(eq=False)
class Problem:
    """The fixed side of an ICP: target points, kd-tree, frame and pair weighting.

    Attributes
    ----------
    target : (m, 3) float, mm
    tree : scipy.spatial.cKDTree of ``target``
    frame : mppf.geometry.frame.LocalFrame of the target (plate plane, normal n)
    method : {"point", "plane"}
    trim_fraction : float or None
    robust : {"huber", "tukey"} or None
    """

    target: np.ndarray
    tree: object
    frame: object
    method: str
    trim_fraction: float | None = None
    robust: str | None = None
    _normals: np.ndarray | None = field(default=None, repr=False)
    _outline: tuple | None = field(default=None, repr=False)

    def normals(self, idx: np.ndarray) -> np.ndarray:
        """Unit normals (k, 3) of target points ``idx`` by local PCA (computed once each)."""
        if self._normals is None:
            self._normals = np.full(self.target.shape, np.nan)
        missing = np.unique(idx)
        missing = missing[np.isnan(self._normals[missing, 0])]
        if missing.size:
            k = min(NORMAL_NEIGHBOURS, self.target.shape[0])
            _, nb = query(self.tree, self.target[missing], k=k)
            hood = self.target[nb]
            hood = hood - hood.mean(axis=1, keepdims=True)
            cov = np.einsum("mki,mkj->mij", hood, hood)
            _, vec = np.linalg.eigh(cov)
            self._normals[missing] = vec[:, :, 0]
        return self._normals[idx]

    def target_outline(self):
        """Area, centroid (2,) and central second moments (2, 2) of the target's outline."""
        if self._outline is None:
            self._outline = polygon_moments(self.frame.to_local(self.target)[:, :2])
        return self._outline


@dataclass(frozen=True, eq=False)
class Pairs:
    """Matched pairs at one transform."""

    moved: np.ndarray
    matched: np.ndarray
    index: np.ndarray
    distance: np.ndarray
    residual: np.ndarray
    weight: np.ndarray
    normal: np.ndarray | None

    @property
    def mse(self) -> float:
        """Weighted mean squared residual, mm^2."""
        return float(np.average(self.residual**2, weights=self.weight))

    @property
    def rms_mm(self) -> float:
        """Weighted RMS residual, mm."""
        return float(np.sqrt(self.mse))

    @property
    def inlier_fraction(self) -> float:
        """Fraction of pairs with a non-zero weight."""
        return float(np.count_nonzero(self.weight) / self.weight.size)


def pair_weights(residual: np.ndarray, trim_fraction, robust) -> np.ndarray:
    """Weights of pairs: trimmed (worst fraction dropped) and/or robust (Huber, Tukey).

    The robust scale is 1.4826 times the median absolute residual of the kept pairs.
    """
    a = np.abs(residual)
    w = np.ones_like(a)
    if trim_fraction:
        keep = max(3, int(np.ceil((1.0 - trim_fraction) * a.size)))
        if keep < a.size:
            cutoff = np.partition(a, keep - 1)[keep - 1]
            w[a > cutoff] = 0.0
    if robust:
        scale = 1.4826 * float(np.median(a[w > 0]))
        scale = max(scale, 1e-9 * (1.0 + float(a.max())))
        if robust == "huber":
            c = HUBER_K * scale
            w *= np.where(a <= c, 1.0, c / np.maximum(a, c))
        else:
            c = TUKEY_C * scale
            w *= np.where(a < c, (1.0 - (a / c) ** 2) ** 2, 0.0)
    return w


def match(problem: Problem, source: np.ndarray, tf: np.ndarray, metric: str | None = None) -> Pairs:
    """Closest target points of the moved source, residuals and weights."""
    metric = metric or problem.method
    moved = apply_tf(tf, source)
    dist, idx = query(problem.tree, moved)
    matched = problem.target[idx]
    normal = None
    if metric == "plane":
        normal = problem.normals(idx)
        residual = np.einsum("ij,ij->i", moved - matched, normal)
    else:
        residual = dist
    weight = pair_weights(residual, problem.trim_fraction, problem.robust)
    needed = 6 if metric == "plane" else 3
    if np.count_nonzero(weight) < needed:
        raise GeometryError(
            f"only {np.count_nonzero(weight)} of {weight.size} source point pairs keep a weight, "
            f"the {metric} step needs {needed}",
            hint="give more points, a better start, or a milder trim / robust option",
        )
    return Pairs(moved, matched, idx, dist, residual, weight, normal)


def _plane_step(pairs: Pairs) -> np.ndarray:
    """One linearised point-to-plane step (small rotation about the weighted centroid)."""
    return _linear_step(pairs, "plane", np.eye(3), np.ones(6, bool))


def _linear_step(pairs: Pairs, metric: str, axes: np.ndarray, free: np.ndarray) -> np.ndarray:
    """One linearised step (point or plane metric) with some degrees of freedom held.

    Parameters
    ----------
    axes : (3, 3) float
        Rows are the axes in which ``free`` is expressed (the target's u, v, n).
    free : (6,) bool
        Which of (turn about u, v, n; shift along u, v, n) may change.
    """
    w = pairs.weight
    centre = np.average(pairs.moved, axis=0, weights=w)
    arm = (pairs.moved - centre) @ axes.T
    scale = max(float(np.sqrt(np.average((arm**2).sum(axis=1), weights=w))), 1e-9)
    if metric == "plane":
        normal = pairs.normal @ axes.T
        jac = np.hstack([np.cross(arm, normal) / scale, normal])  # (n, 6)
        res = pairs.residual
    else:
        # d(omega x arm)/d omega = -[arm]x ; three rows per pair
        jac = np.zeros((arm.shape[0], 3, 6))
        jac[:, 0, 1], jac[:, 0, 2] = arm[:, 2], -arm[:, 1]
        jac[:, 1, 0], jac[:, 1, 2] = -arm[:, 2], arm[:, 0]
        jac[:, 2, 0], jac[:, 2, 1] = arm[:, 1], -arm[:, 0]
        jac[:, :, :3] /= scale
        jac[:, :, 3:] = np.eye(3)
        res = ((pairs.moved - pairs.matched) @ axes.T).reshape(-1)
        jac = jac.reshape(-1, 6)
        w = np.repeat(w, 3)
    jac = jac[:, free]
    hess = (jac * w[:, None]).T @ jac
    grad = (jac * w[:, None]).T @ res
    eigval, eigvec = np.linalg.eigh(hess)
    keep = eigval > UNOBSERVABLE * eigval[-1]  # nearly free directions (a cylinder's slide) stay put
    x = np.zeros(6)
    x[free] = -(eigvec[:, keep] @ ((eigvec[:, keep].T @ grad) / eigval[keep]))
    rotation = axes.T @ Rotation.from_rotvec(x[:3] / scale).as_matrix() @ axes
    return make_tf(np.eye(3), centre + axes.T @ x[3:]) @ make_tf(rotation) @ make_tf(np.eye(3), -centre)


def step(pairs: Pairs, metric: str, pin=None) -> np.ndarray:
    """Incremental transform of one ICP iteration for the given metric.

    Unpinned point-to-point is the paper's closed-form quaternion step; with an
    outline pin the held in-plane degrees of freedom need the linearised step.
    """
    if pin is not None:
        return _linear_step(pairs, metric, pin.frame.axes, pin.free)
    if metric == "plane":
        return _plane_step(pairs)
    keep = pairs.weight > 0
    return fit_rigid(pairs.moved[keep], pairs.matched[keep], pairs.weight[keep])


@dataclass(frozen=True, eq=False)
class Stage:
    """Result of one run of the ICP loop."""

    tf: np.ndarray
    iterations: int
    rms_history: list
    converged: bool
    stop_reason: str


def _extrapolate(tf: np.ndarray, centre: np.ndarray, rotvec: np.ndarray, shift: np.ndarray,
                 factor: float) -> np.ndarray:
    """``tf`` followed by ``factor`` times the last increment (turn about the moved centre)."""
    moved_centre = apply_tf(tf, centre[None])[0]
    rot = Rotation.from_rotvec(factor * rotvec).as_matrix()
    return make_tf(rot, moved_centre + factor * shift - rot @ moved_centre) @ tf


def increment(tf_old: np.ndarray, tf_new: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(turn as a rotation vector in rad, displacement of ``centre`` in mm) from one transform to the next."""
    rotvec = Rotation.from_matrix(tf_new[:3, :3] @ tf_old[:3, :3].T).as_rotvec()
    shift = apply_tf(tf_new, centre[None])[0] - apply_tf(tf_old, centre[None])[0]
    return rotvec, shift


def run(problem: Problem, source: np.ndarray, tf0: np.ndarray, *, max_iterations: int,
        tol: tuple[float, float, float], pin=None, metric: str | None = None,
        accelerate: bool = True, reporter: Reporter = NULL_REPORTER) -> Stage:
    """The ICP loop: match, weight, step, pin, test; from ``tf0``.

    Parameters
    ----------
    tol : (translation mm, rotation rad, relative MSE change)
        Also: when the MSE has not fallen below its lowest value by more than the relative
        tolerance for ``STALL_ITERATIONS`` iterations, the lowest-MSE transform is returned.
    pin : OutlinePin, optional
        Applied after every step (and to the start).
    metric : {"point", "plane"}, optional
        Overrides ``problem.method`` (the principal-axes scoring uses "point").
    accelerate : bool
        When successive increments keep their direction and shrink (slow, linear
        convergence), jump ahead by the geometric remainder of the series (at most
        ``MAX_EXTRAPOLATION`` steps); the jump is undone if it raises the MSE.
    """
    metric = metric or problem.method
    tol_t, tol_r, tol_mse = tol
    centre = source.mean(axis=0)
    radius = max(float(np.sqrt(((source - centre) ** 2).sum(axis=1).mean())), 1e-9)
    tf = pin.apply(tf0) if pin is not None else tf0.copy()
    history: list[float] = []
    prev_mse = None
    last = None  # previous increment as a scaled 6-vector
    fallback = None  # transform before an extrapolation, and the MSE it had to beat
    cooldown = 0
    best_mse, best_tf, stalled = np.inf, tf, 0
    for it in range(max_iterations):
        pairs = match(problem, source, tf, metric)  # closest points and weights
        mse = pairs.mse
        if fallback is not None:
            if mse > fallback[1]:  # the jump made it worse: undo it
                tf, cooldown, last = fallback[0], 5, None
                pairs = match(problem, source, tf, metric)
                mse = pairs.mse
            fallback = None
        history.append(float(np.sqrt(mse)))
        if prev_mse is not None and abs(prev_mse - mse) <= tol_mse * prev_mse:
            return Stage(tf, it, history, True, "relative change of the MSE below tolerance")
        if mse < best_mse * (1.0 - tol_mse):
            best_mse, best_tf, stalled = mse, tf, 0
        else:
            stalled += 1
            if stalled >= STALL_ITERATIONS:
                return Stage(best_tf, it, history, True,
                             f"no lower MSE in {STALL_ITERATIONS} iterations (the closest points cycle)")
        tf_new = step(pairs, metric, pin) @ tf  # quaternion or linearised step
        if pin is not None:
            tf_new = pin.apply(tf_new)  # outline and centroid fix the in-plane position
        rotvec, shift_vec = increment(tf, tf_new, centre)
        reporter.advance(1)
        if np.linalg.norm(shift_vec) < tol_t and np.linalg.norm(rotvec) < tol_r:
            return Stage(tf_new, it + 1, history, True, "transform increment below tolerance")
        vec = np.concatenate([rotvec * radius, shift_vec])
        tf = tf_new
        cooldown = max(cooldown - 1, 0)
        if accelerate and last is not None and cooldown == 0:
            ratio = np.linalg.norm(vec) / max(np.linalg.norm(last), 1e-300)
            cos = vec @ last / max(np.linalg.norm(vec) * np.linalg.norm(last), 1e-300)
            if cos > 0.99 and ratio < 0.999:
                factor = min(ratio / (1.0 - ratio), MAX_EXTRAPOLATION)
                fallback = (tf, mse)
                tf = _extrapolate(tf, centre, rotvec, shift_vec, factor)
                if pin is not None:
                    tf = pin.apply(tf)
                vec = None
        last = vec
        prev_mse = mse
    return Stage(tf, max_iterations, history, False, "iteration limit reached")


def evaluate(problem: Problem, source: np.ndarray, tf: np.ndarray) -> Pairs:
    """Pairs (with target normals) at the final transform."""
    pairs = match(problem, source, tf)
    if pairs.normal is None:
        pairs = Pairs(pairs.moved, pairs.matched, pairs.index, pairs.distance, pairs.residual,
                      pairs.weight, problem.normals(pairs.index))
    return pairs


def trimmed_rms(problem: Problem, source: np.ndarray, tf: np.ndarray) -> float:
    """RMS of the best ``SCORE_KEEP`` fraction of closest-point distances, mm."""
    dist, _ = query(problem.tree, apply_tf(tf, source))
    keep = max(3, int(SCORE_KEEP * dist.size))
    return float(np.sqrt(np.mean(np.partition(dist, keep - 1)[:keep] ** 2)))


def uncertainty(problem: Problem, pairs: Pairs, sigma_mm: float | None = None) -> dict:
    """One-sigma uncertainty per degree of freedom from the point-to-plane information.

    In the target's plate frame (u, v in-plane, n normal): translations in mm, turns
    about the axes in degrees; None where the surface shape does not fix the
    degree of freedom (e.g. sliding along a cylinder). ``observability`` lists the
    normalised eigenvalues of the information matrix (turns scaled by the plate's
    RMS radius), ascending: values near 0 are nearly free directions. Directions below
    ``UNOBSERVABLE`` are held at their start by the ICP step: a degree of freedom lying
    mostly in them is reported as None, the others conditional on them. The noise is
    estimated from the normal residuals unless ``sigma_mm`` is given.
    """
    axes = problem.frame.axes
    w = pairs.weight
    local = (pairs.moved - problem.frame.origin) @ axes.T
    normal = pairs.normal @ axes.T
    centre = np.average(local, axis=0, weights=w)
    arm = local - centre
    radius = max(float(np.sqrt(np.average((arm[:, :2] ** 2).sum(axis=1), weights=w))), 1e-9)
    jac = np.hstack([normal, np.cross(arm, normal) / radius])
    hess = (jac * w[:, None]).T @ jac
    residual = np.einsum("ij,ij->i", pairs.moved - pairs.matched, pairs.normal)
    dof = max(float(w.sum()) - 6.0, 1.0)
    sigma2 = float((w * residual**2).sum() / dof) if sigma_mm is None else sigma_mm**2
    eigval, eigvec = np.linalg.eigh(hess)
    held = eigval <= UNOBSERVABLE * eigval[-1]  # directions the ICP step holds at their start
    # covariance of what is estimated (conditional on the held directions); a degree of
    # freedom that lies mostly in the held directions is not estimated at all
    inv_diag = (eigvec[:, ~held] ** 2 / eigval[~held]) @ np.ones((~held).sum())
    fixed = (eigvec[:, held] ** 2).sum(axis=1) < 0.5
    std = np.sqrt(sigma2 * inv_diag)
    std[3:] = np.degrees(std[3:] / radius)
    names = ("t_u_mm", "t_v_mm", "t_n_mm", "r_u_deg", "r_v_deg", "r_n_deg")
    out = {name: (float(s) if ok else None) for name, s, ok in zip(names, std, fixed)}
    out["noise_sigma_mm"] = float(np.sqrt(sigma2))
    out["observability"] = [float(v) for v in np.clip(eigval / eigval[-1], 0.0, None)]
    return out


# ------------------------------------------------------------------ outline pinning


def polygon_moments(points_2d: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Area (mm^2), area centroid (2,) and central second moments (2, 2) of the convex outline.

    Raises
    ------
    GeometryError
        The points do not span an area in the plane.
    """
    return moments(convex_outline(points_2d, "the points of the plate"))


def _major_axis_angle(moments: np.ndarray) -> tuple[float, float]:
    """(angle of the major axis in rad, ratio of the second moments major/minor)."""
    eigval, eigvec = np.linalg.eigh(moments)
    major = eigvec[:, 1]
    return float(np.arctan2(major[1], major[0])), float(eigval[1] / max(eigval[0], 1e-300))


@dataclass(frozen=True, eq=False)
class OutlinePin:
    """Fixes the in-plane position of the source by the outline in the target's plane.

    After each ICP step the moved source's convex outline (in the target's plate
    plane) is brought onto the target's: area centroid onto area centroid, and for
    elongated plates the major axis onto the major axis (a turn about the normal).
    The normal offset and the tilts stay as the surface fit gives them.
    """

    frame: object
    points: np.ndarray
    centroid_t: np.ndarray
    angle_t: float
    pin_turn: bool

    @property
    def free(self) -> np.ndarray:
        """(6,) bool: degrees of freedom (turns about u, v, n; shifts along u, v, n) left to ICP."""
        return np.array([True, True, not self.pin_turn, False, False, True])

    def apply(self, tf: np.ndarray) -> np.ndarray:
        """``tf`` corrected in-plane, (4, 4)."""
        local = self.frame.to_local(apply_tf(tf, self.points))[:, :2]
        _, centroid_s, moments_s = polygon_moments(local)
        turn = 0.0
        if self.pin_turn:
            angle_s, _ = _major_axis_angle(moments_s)
            turn = (self.angle_t - angle_s + np.pi / 2) % np.pi - np.pi / 2
        rot = Rotation.from_rotvec([0.0, 0.0, turn]).as_matrix()
        c_s = np.array([centroid_s[0], centroid_s[1], 0.0])
        c_t = np.array([self.centroid_t[0], self.centroid_t[1], 0.0])
        correction = make_tf(rot, c_t - rot @ c_s)
        return self.frame.tf_world_local @ correction @ self.frame.tf_local_world @ tf


def outline_candidates(frame, points: np.ndarray, sample: np.ndarray) -> np.ndarray:
    """Points of a cloud that may form its outline: a band along its convex outline.

    The convex outline is first taken from ``sample`` (a subsample of ``points``)
    without its isolated points (stray returns, outliers: their
    ``OUTLINE_NEIGHBOURS``-th neighbour farther than ``ISOLATED`` times the median
    such distance). The points of the whole cloud within ``PIN_BAND_FRACTION`` of the
    plate size of that outline, and not isolated themselves, are returned; they lie in
    the cloud's own plate plane (``frame``), so the outline can be recomputed cheaply in
    any pose.
    """

    def not_isolated(tree, pts):
        spacing = query(tree, pts, k=min(OUTLINE_NEIGHBOURS + 1, tree.n))[0][:, -1]
        return spacing <= ISOLATED * np.median(spacing)

    sample = sample[not_isolated(cKDTree(sample), sample)]
    try:
        outline = convex_outline(frame.to_local(sample)[:, :2])
    except GeometryError:
        return sample
    depth = convex_inset(outline, frame.to_local(points)[:, :2])
    band = points[np.abs(depth) <= PIN_BAND_FRACTION * np.sqrt(area(outline))]
    if band.shape[0] < 3:
        return band
    tree = cKDTree(points) if points.shape[0] > sample.shape[0] else cKDTree(sample)
    return band[not_isolated(tree, band)]


def outline_pin(problem: Problem, candidates: np.ndarray, tf: np.ndarray, *,
                require_coverage: bool, pin_turn: bool) -> tuple[OutlinePin | None, str]:
    """Build the outline pin at ``tf``, or say why not.

    Parameters
    ----------
    candidates : (k, 3) float, mm
        Source points along its outline (:func:`outline_candidates`).
    require_coverage : bool
        Only pin when both outlines have areas and extents within ``COVERAGE_TOL``.
    pin_turn : bool
        Also pin the turn about the normal (for elongated outlines).

    Returns
    -------
    (OutlinePin or None, str)
        The pin, and a description of the coverage test.
    """
    area_t, centroid_t, moments_t = problem.target_outline()
    near = candidates
    if near.shape[0] < 10:
        return None, "too few source points on the outline"
    local = problem.frame.to_local(apply_tf(tf, near))[:, :2]
    try:
        area_s, _, moments_s = polygon_moments(local)
    except GeometryError:
        return None, "the source has no outline in the target's plane"
    ext_s, ext_t = np.sqrt(np.linalg.eigvalsh(moments_s)), np.sqrt(np.linalg.eigvalsh(moments_t))
    ratios = np.concatenate([[area_s / area_t], ext_s / ext_t])
    coverage = (f"outline area ratio {ratios[0]:.3f}, extent ratios {ratios[1]:.3f} / {ratios[2]:.3f} "
                f"(source / target)")
    if require_coverage and np.any(np.abs(np.log(ratios)) > np.log1p(COVERAGE_TOL)):
        return None, coverage + ": the clouds do not cover the same plate"
    angle_t, elongation = _major_axis_angle(moments_t)
    pin = OutlinePin(frame=problem.frame, points=near, centroid_t=centroid_t, angle_t=angle_t,
                     pin_turn=pin_turn and elongation > ELONGATED)
    return pin, coverage
