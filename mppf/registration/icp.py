"""The ICP loop behind :func:`mppf.registration.register.register_icp`.

:func:`run` iterates "match closest points of the fixed :class:`~mppf.registration.target.RegistrationTarget`,
weight the pairs (:mod:`mppf.registration.pairs`), solve one step (quaternion or linearised point-to-plane), pin the
outline, test the stop criteria"; :func:`evaluate` and
:func:`mppf.registration.uncertainty.uncertainty` describe the result. How pairs are formed and weighted is a :class:`~mppf.registration.settings.Matching`.
All lengths in mm, angles in radians unless a name says ``_deg``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import GeometryError
from mppf.core.kdtree import spatial_order
from mppf.core.progress import NULL_REPORTER, Reporter
from mppf.core.rigid import fit_rigid
from mppf.core.transform import apply_tf, make_tf, matrix_to_rotvec, rotvec_to_matrix
from mppf.registration.pairs import Pairs, pair_weights
from mppf.registration.settings import Matching
from mppf.registration.target import RegistrationTarget

UNOBSERVABLE = 1e-5
"""Directions of a linearised step whose information is below this fraction of the largest are held."""

MAX_EXTRAPOLATION = 25.0
"""Largest jump of the accelerated ICP, in multiples of the last increment."""

STALL_ITERATIONS = 10
"""A stage stops when its MSE has not reached a new low (by the relative tolerance) for this
many iterations: the closest-point sets cycle (seen with point-to-plane on 4,000 points)."""


class Nearest:
    """Closest target points of one source's points, queried again only where they may change.

    A point whose closest target point at its last queried position ``q`` was ``t1`` (at
    ``d1``; the second closest at ``d2``) keeps ``t1`` as long as it stays within
    ``(d2 - d1) / 2`` of ``q``: every other target point is then still farther (triangle
    inequality). So each ICP iteration queries the k-d tree only for the points that
    moved that far (in the late iterations, most points move far less); the others'
    distances are recomputed exactly as the tree computes them. The pairs are the same
    as a query of every point (exact ties are queried as such).

    The points are queried in a spatial order (strips across the source's longest extent,
    along the next in each; taken once, at the first query: a rigid move keeps neighbours
    neighbours), not in the source's order, which is a shuffled subsample: neighbouring
    queries walk the same branches of the tree (the ICP's queries 10-15 % faster), with the
    same answers (each point's query is its own).
    """

    MARGIN_MM = 1e-6
    """Kept off the bound (d2 - d1) / 2, for the round-off of the distances."""

    def __init__(self, target: RegistrationTarget):
        self.target = target
        self.last = None  # (q, d1, d2, i1) of every point at its last query
        self.order = None  # the points' spatial query order

    def __call__(self, moved: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(distance (n,) mm, index (n,)) of the closest target point of each moved point."""
        if self.last is None or self.last[0].shape != moved.shape:
            redo = np.ones(moved.shape[0], dtype=bool)
            self.last = (moved.copy(), np.zeros(moved.shape[0]), np.zeros(moved.shape[0]),
                         np.zeros(moved.shape[0], dtype=np.intp))
            self.order = spatial_order(moved)
        else:
            q, d1, d2, _ = self.last
            shift = np.sqrt(((moved - q) ** 2).sum(axis=1))
            redo = ~(shift < 0.5 * (d2 - d1) - self.MARGIN_MM)
        q, d1, d2, i1 = self.last
        if redo.any():
            rows = self.order[redo[self.order]]  # the points to query, in the spatial order
            dist, idx = self.target.tree.query(moved[rows], k=2)  # targets have at least 3 points
            first, second = dist[:, 0], dist[:, 1]
            tie = first == second
            if tie.any():  # the closest of equals: the one a plain query gives
                idx[tie, 0] = self.target.tree.query(moved[rows][tie])[1]
            q[rows], d1[rows], d2[rows], i1[rows] = moved[rows], first, second, idx[:, 0]
        dist = np.sqrt(((moved - self.target.points[i1]) ** 2).sum(axis=1))
        return dist, i1.copy()


def match(target: RegistrationTarget, source: np.ndarray, tf: np.ndarray, matching: Matching,
          nearest: Nearest | None = None, normals: bool = False) -> Pairs:
    """Closest target points of the moved source, residuals and weights.

    ``nearest`` (one per source, kept across the iterations of a loop) spares the k-d tree
    queries of points that cannot have changed their closest target point. The pairs carry
    the target normals with the plane metric, or when ``normals`` is asked for.
    """
    metric = matching.metric
    moved = apply_tf(tf, source)
    dist, idx = target.tree.query(moved) if nearest is None else nearest(moved)
    matched = target.points[idx]
    normal = target.normals(idx) if metric == "plane" or normals else None
    if metric == "plane":
        residual = np.einsum("ij,ij->i", moved - matched, normal)
    else:
        residual = dist
    weight = pair_weights(residual, matching.trim_fraction, matching.robust)
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
    centre = np.average(pairs.moved, axis=0, weights=pairs.weight)
    scale = _scale(pairs, centre)
    hess, grad = normal_equations(pairs, "plane", np.eye(3), centre, scale)
    return _as_tf(_solve(hess, grad), np.eye(3), centre, scale)


def _scale(pairs: Pairs, centre: np.ndarray) -> float:
    """RMS distance (mm) of the moved pairs from ``centre``: the length that puts turns in mm."""
    arm = pairs.moved - centre
    return max(float(np.sqrt(np.average((arm**2).sum(axis=1), weights=pairs.weight))), 1e-9)


def normal_equations(pairs: Pairs, metric: str, axes: np.ndarray, centre: np.ndarray,
                     scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Newton normal equations (6, 6) and gradient (6,) of one linearised step.

    The unknowns are (turn about u, v, n times ``scale``; shift along u, v, n) in the
    frame whose rows are ``axes``, the turns about ``centre`` (world, mm).
    """
    w = pairs.weight
    arm = (pairs.moved - centre) @ axes.T
    if metric == "plane":
        normal = pairs.normal @ axes.T
        jac = np.hstack([np.cross(arm, normal) / scale, normal])  # (n, 6)
        res = np.einsum("ij,ij->i", pairs.moved - pairs.matched, pairs.normal)  # also for point-metric pairs
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
    weighted = jac * w[:, None]
    return weighted.T @ jac, weighted.T @ res


def _solve(hess: np.ndarray, grad: np.ndarray) -> np.ndarray:
    """The step (6,) of the normal equations; nearly free directions (a cylinder's slide) stay put."""
    eigval, eigvec = np.linalg.eigh(hess)
    keep = eigval > UNOBSERVABLE * eigval[-1]
    return -(eigvec[:, keep] @ ((eigvec[:, keep].T @ grad) / eigval[keep]))


def _as_tf(x: np.ndarray, axes: np.ndarray, centre: np.ndarray, scale: float) -> np.ndarray:
    """The (4, 4) motion of a step ``x`` (see :func:`normal_equations`)."""
    rotation = axes.T @ rotvec_to_matrix(x[:3] / scale) @ axes
    return make_tf(np.eye(3), centre + axes.T @ x[3:]) @ make_tf(rotation) @ make_tf(np.eye(3), -centre)


def _pinned_step(pairs: Pairs, metric: str, pin, tf: np.ndarray) -> np.ndarray:
    """One linearised step with the outline's say in the in-plane pose (:mod:`mppf.registration.pin`).

    The in-plane move (the pin's rows) is the surface's wish mixed with the outline's by the
    pin's share ``S``; the surface's wish comes from the point-to-plane equations (with the
    point metric too: its closest-point offsets in the plane follow the sampling pattern,
    not the shape). The other degrees of freedom then take the metric's best values given
    that move.
    """
    axes, centre = pin.frame.axes, pin.centre
    scale = _scale(pairs, centre)
    hess, grad = normal_equations(pairs, metric, axes, centre, scale)
    x_metric = _solve(hess, grad)
    rows = list(pin.rows)
    units = np.where(np.array(rows) < 3, scale, 1.0)  # turns in rad <-> scaled unknowns
    if pin.hard:
        wanted = pin.wish(tf) * units
    else:
        own = metric == "plane" or pin.tangential
        x_surface = x_metric if own else _solve(*normal_equations(pairs, "plane", axes, centre, scale))
        surface = x_surface[rows] / units
        wanted = (surface + pin.share @ (pin.wish(tf) - surface)) * units
    # the metric's best step with the pinned rows held at their wanted values
    regular = hess + 1e-9 * max(float(np.trace(hess)), 1e-300) * np.eye(6)
    inverse = np.linalg.inv(regular)
    gain = inverse[:, rows] @ np.linalg.inv(inverse[np.ix_(rows, rows)])
    x = x_metric + gain @ (wanted - x_metric[rows])
    return _as_tf(x, axes, centre, scale)


def plane_information(pairs: Pairs, axes: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Point-to-plane information (6, 6) in (turn rad about u, v, n; shift mm) about ``centre``."""
    hess, _ = normal_equations(pairs, "plane", axes, centre, 1.0)
    return hess


def step(pairs: Pairs, metric: str, pin=None, tf=None) -> np.ndarray:
    """Incremental transform of one ICP iteration for the given metric.

    Unpinned point-to-point is the paper's closed-form quaternion step; with an
    outline pin the step is linearised (:func:`_pinned_step`, ``tf`` the current transform).
    """
    if pin is not None:
        return _pinned_step(pairs, metric, pin, tf)
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
    rot = rotvec_to_matrix(factor * rotvec)
    return make_tf(rot, moved_centre + factor * shift - rot @ moved_centre) @ tf


def increment(tf_old: np.ndarray, tf_new: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(turn as a rotation vector in rad, displacement of ``centre`` in mm) from one transform to the next."""
    rotvec = matrix_to_rotvec(tf_new[:3, :3] @ tf_old[:3, :3].T)
    shift = apply_tf(tf_new, centre[None])[0] - apply_tf(tf_old, centre[None])[0]
    return rotvec, shift


@dataclass(frozen=True)
class Stop:
    """When an ICP loop stops (:func:`run`).

    Attributes
    ----------
    max_iterations : int
        Iteration limit.
    translation_mm, rotation_rad : float
        Converged when one iteration moves the source centroid less than this and turns it
        less than this.
    relative_mse : float
        Also converged when the MSE changes by less than this fraction; and when it has not
        fallen below its lowest value by more than this for ``STALL_ITERATIONS`` iterations.
    """

    max_iterations: int
    translation_mm: float
    rotation_rad: float
    relative_mse: float

    def coarse(self, factor: float = 10.0) -> Stop:
        """The same limit with every tolerance ``factor`` times looser (a coarse stage)."""
        return Stop(self.max_iterations, factor * self.translation_mm, factor * self.rotation_rad,
                    factor * self.relative_mse)


def run(target: RegistrationTarget, source: np.ndarray, tf0: np.ndarray, matching: Matching, stop: Stop, *,
        pin=None, nearest: Nearest | None = None, reporter: Reporter = NULL_REPORTER) -> Stage:
    """The ICP loop: match, weight, step, pin, test; from ``tf0``.

    Parameters
    ----------
    target : RegistrationTarget
        The fixed side (k-d tree, normals).
    source : (n, 3) float, mm
        The points that move.
    tf0 : (4, 4) float
        Start, source -> target.
    matching : Matching
        Metric and pair weights.
    stop : Stop
        Iteration limit and tolerances. When the MSE stalls (:class:`Stop`), the lowest-MSE
        transform is returned (with a soft pin: the last one).
    pin : mppf.registration.pin.OutlinePin, optional
        The outline's say in every step; a hard pin is also applied to the start and
        after every step.
    nearest : Nearest, optional
        The closest points of ``source`` kept from an earlier loop on the same points
        (default: a new one).

    When successive increments keep their direction and shrink (slow, linear convergence),
    the loop jumps ahead by the geometric remainder of the series (at most
    ``MAX_EXTRAPOLATION`` steps); the jump is undone if it raises the MSE. Not with a soft
    pin (its steps do not descend the metric's MSE alone; it removes the slow in-plane crawl
    anyway).
    """
    hard = pin is not None and pin.hard
    soft = pin is not None and not pin.hard
    nearest = Nearest(target) if nearest is None else nearest
    normals = pin is not None and not hard and matching.metric == "point" and not pin.tangential  # asks the surface
    pair = lambda tf: match(target, source, tf, matching, nearest, normals)  # noqa: E731
    walk = _Walk(source, pin.apply(tf0) if hard else tf0.copy())
    for it in range(stop.max_iterations):
        pairs = walk.undo_a_worse_jump(pair)  # closest points and weights
        mse = pairs.mse
        walk.history.append(float(np.sqrt(mse)))
        if walk.prev_mse is not None and abs(walk.prev_mse - mse) <= stop.relative_mse * walk.prev_mse:
            return Stage(walk.tf, it, walk.history, True, "relative change of the MSE below tolerance")
        if mse < walk.best_mse * (1.0 - stop.relative_mse):
            walk.best_mse, walk.best_tf, walk.stalled = mse, walk.tf, 0
        else:
            walk.stalled += 1
            if walk.stalled >= STALL_ITERATIONS:
                # a soft pin's steps do not descend the metric's MSE alone: its last transform is the answer
                return Stage(walk.tf if soft else walk.best_tf, it, walk.history, True,
                             f"no lower MSE in {STALL_ITERATIONS} iterations (the closest points cycle)")
        tf_new = step(pairs, matching.metric, pin, walk.tf) @ walk.tf  # quaternion or linearised step
        if hard:
            tf_new = pin.apply(tf_new)  # flat against curved: the outline alone fixes the in-plane pose
        rotvec, shift_vec = increment(walk.tf, tf_new, walk.centre)
        reporter.advance(1)
        if np.linalg.norm(shift_vec) < stop.translation_mm and np.linalg.norm(rotvec) < stop.rotation_rad:
            return Stage(tf_new, it + 1, walk.history, True, "transform increment below tolerance")
        walk.advance(tf_new, rotvec, shift_vec, mse, pin)
    return Stage(walk.tf, stop.max_iterations, walk.history, False, "iteration limit reached")


class _Walk:
    """The state of one ICP loop: transform, MSE history, best so far, the last increment and a pending jump."""

    def __init__(self, source: np.ndarray, tf: np.ndarray):
        self.centre = source.mean(axis=0)
        self.radius = max(float(np.sqrt(((source - self.centre) ** 2).sum(axis=1).mean())), 1e-9)
        self.tf = tf
        self.history: list[float] = []
        self.prev_mse = None
        self.last = None  # previous increment as a scaled 6-vector
        self.fallback = None  # transform before an extrapolation, and the MSE it had to beat
        self.cooldown = 0
        self.best_mse, self.best_tf, self.stalled = np.inf, tf, 0

    def undo_a_worse_jump(self, pair) -> Pairs:
        """The pairs at the current transform; a jump that raised the MSE is undone first (5 quiet iterations)."""
        pairs = pair(self.tf)
        if self.fallback is not None:
            if pairs.mse > self.fallback[1]:  # the jump made it worse: undo it
                self.tf, self.cooldown, self.last = self.fallback[0], 5, None
                pairs = pair(self.tf)
            self.fallback = None
        return pairs

    def advance(self, tf_new: np.ndarray, rotvec: np.ndarray, shift_vec: np.ndarray, mse: float, pin) -> None:
        """Take the step to ``tf_new``; jump ahead when the increments keep their direction and shrink.

        ``pin``: the loop's outline pin or None; no jump under a soft one (see :func:`run`), a hard
        one applied to the jump.
        """
        hard = pin is not None and pin.hard
        jumps = pin is None or hard
        vec = np.concatenate([rotvec * self.radius, shift_vec])
        self.tf = tf_new
        self.cooldown = max(self.cooldown - 1, 0)
        if jumps and self.last is not None and self.cooldown == 0:
            ratio = np.linalg.norm(vec) / max(np.linalg.norm(self.last), 1e-300)
            cos = vec @ self.last / max(np.linalg.norm(vec) * np.linalg.norm(self.last), 1e-300)
            if cos > 0.99 and ratio < 0.999:
                factor = min(ratio / (1.0 - ratio), MAX_EXTRAPOLATION)
                self.fallback = (self.tf, mse)
                self.tf = _extrapolate(self.tf, self.centre, rotvec, shift_vec, factor)
                if hard:
                    self.tf = pin.apply(self.tf)
                vec = None
        self.last = vec
        self.prev_mse = mse


def evaluate(target: RegistrationTarget, source: np.ndarray, tf: np.ndarray, matching: Matching,
             nearest: Nearest | None = None) -> Pairs:
    """Pairs (with target normals) at the final transform (``nearest``: see :func:`match`)."""
    pairs = match(target, source, tf, matching, nearest)
    if pairs.normal is None:
        pairs = Pairs(pairs.moved, pairs.matched, pairs.index, pairs.distance, pairs.residual,
                      pairs.weight, target.normals(pairs.index))
    return pairs
