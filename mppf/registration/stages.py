"""The stages of :func:`mppf.registration.register.register_icp`, one function each.

``matching`` (the metric, never a plane between flat and curved), ``subsamples`` (the
points of the fine and coarse stages and of the judging sample), ``floor`` (the noise
floor, :mod:`mppf.registration.trust`), ``start`` (principal-axes candidates converged,
:mod:`mppf.registration.starts`), ``fit`` (coarse stage, outline pin, fine stage) and
``check_starts`` (from a given start: would a principal-axes start fit clearly better?).
Lengths in mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.progress import NULL_REPORTER, Reporter
from mppf.registration import icp
from mppf.registration.pairs import Pairs
from mppf.registration.pin import outline_candidates, outline_pin, surface_covariance
from mppf.registration.settings import RegisterOptions, Matching, PrincipalStart
from mppf.registration.starts import (
    Candidate,
    compared,
    converge_candidates,
    evaluate,
    level_mm,
    principal_candidates,
    principal_start,
    rank,
    same_pose,
    sampled_alike,
)
from mppf.registration.target import Cloud, RegistrationTarget, spreads
from mppf.registration.trust import noise_floor_mm, robust_scale_mm, sample_index, tie


@dataclass(frozen=True, eq=False)
class Points:
    """The source points each stage works on (all subsamples of the source, seeded).

    Attributes
    ----------
    fine : (k, 3) float
        At most ``RegisterOptions.max_points``: the fine stage.
    coarse : (j, 3) float
        The coarse stage (``fine`` itself for small clouds).
    fit : (i, 3) float
        The principal-axes candidates are converged on these.
    judge : (h, 3) float
        Every pose is judged on these (noise floor, residuals, ties).
    """

    fine: np.ndarray
    coarse: np.ndarray
    fit: np.ndarray
    judge: np.ndarray

    @property
    def has_coarse(self) -> bool:
        """Whether the coarse stage runs on fewer points than the fine one."""
        return self.coarse is not self.fine


@dataclass(frozen=True, eq=False)
class Fit:
    """The coarse and fine stages of one registration, the pin used and the fine points' closest-point cache."""

    coarse: icp.Stage
    fine: icp.Stage
    pin: object
    nearest: icp.Nearest


@dataclass(frozen=True, eq=False)
class Problem:
    """One registration's fixed inputs, shared by its stages.

    Attributes
    ----------
    target : RegistrationTarget
        The fixed side.
    cloud : Cloud
        The source, prepared.
    points : Points
        The source's subsamples.
    matching : Matching
        The pairing (the metric possibly overridden: :func:`matching`).
    settings : RegisterOptions
        The options of the registration.
    flat_vs_curved : bool
        A flat plate faces a curved one.
    floor_mm : float
        The noise floor (mm; 0 where none is measured).
    notes : list of str
        Decisions, appended to as the stages run.
    """

    target: RegistrationTarget
    cloud: Cloud
    points: Points
    matching: Matching
    settings: RegisterOptions
    flat_vs_curved: bool
    floor_mm: float
    notes: list


def matching(cloud: Cloud, target: RegistrationTarget, settings: RegisterOptions, notes: list) -> tuple[Matching, bool]:
    """The pairing of the registration and whether a flat plate faces a curved one (notes: an overridden metric)."""
    flat_vs_curved = cloud.flat != target.flat
    method = settings.method
    if flat_vs_curved and method == "plane":
        method = "point"
        notes.append("point-to-plane overridden by point-to-point: one plate is flat and the other "
                     "curved, and a plane metric slides the flat plate off the curved one")
    return Matching(method, settings.trim_fraction, settings.robust), flat_vs_curved


def _subsample(n: int, count: int, rng: np.random.Generator) -> np.ndarray:
    if count >= n:
        return np.arange(n)
    return np.sort(rng.choice(n, size=count, replace=False))


def subsamples(cloud: Cloud, settings: RegisterOptions, principal: PrincipalStart = PrincipalStart()) -> Points:
    """The seeded subsamples of the source (see :class:`Points`)."""
    rng = np.random.default_rng(settings.seed)
    src = cloud.points
    fine_idx = _subsample(src.shape[0], settings.max_points, rng)
    fine = src[fine_idx]
    coarse = fine
    if fine_idx.size > 2 * settings.coarse_points:
        coarse = src[fine_idx[_subsample(fine_idx.size, settings.coarse_points, rng)]]
    fit = fine[_subsample(fine.shape[0], principal.points, rng)]
    return Points(fine=fine, coarse=coarse, fit=fit, judge=fine[sample_index(fine.shape[0], seed=settings.seed)])


def floor(cloud: Cloud, target: RegistrationTarget, points: Points) -> float:
    """The noise floor (mm) of this source against this target (:func:`noise_floor_mm`), on the fine points."""
    return noise_floor_mm(Cloud(points=points.fine, frame=cloud.frame, flat=cloud.flat, name=cloud.name), target)


def _size_mm(target: RegistrationTarget) -> float:
    """Twice the target's in-plane RMS radius: the plate size that poses are compared at."""
    return 2.0 * spreads(target.frame, target.points)[0]


def start(problem: Problem, principal: PrincipalStart) -> tuple[np.ndarray, dict]:
    """The start transform (``settings.init``) and how it was chosen (``Registration.init``)."""
    init, target, points, matching = problem.settings.init, problem.target, problem.points, problem.matching
    if problem.settings.principal_start:
        return principal_start(target, points.fit, points.judge, problem.cloud.frame, matching, problem.floor_mm,
                               _size_mm(target), principal)
    if isinstance(init, str):
        return np.eye(4), {"kind": "identity"}
    return np.asarray(init, dtype=float).copy(), {"kind": "given"}


def fit(problem: Problem, tf0: np.ndarray, reporter: Reporter) -> Fit:
    """Coarse stage (unpinned) from ``tf0`` (4, 4), the outline pin at its result, the fine stage."""
    target, points, matching, settings = problem.target, problem.points, problem.matching, problem.settings
    stop = icp.Stop(settings.max_iterations, *settings.tolerances)
    nearest = icp.Nearest(target)  # the fine points' closest target points, kept from loop to loop
    reporter.start("registering", total=None)
    coarse = icp.run(target, points.coarse, tf0, matching, stop.coarse(),
                     nearest=None if points.has_coarse else nearest, reporter=reporter)
    pin = _outline_pin(problem, coarse.tf, nearest)
    fine = icp.run(target, points.fine, coarse.tf, matching, stop, pin=pin, nearest=nearest, reporter=reporter)
    reporter.finish()
    return Fit(coarse, fine, pin, nearest)


def _outline_pin(problem: Problem, tf: np.ndarray, nearest: icp.Nearest):
    """The outline pin at ``tf``, or None (the reason added to the problem's ``notes``).

    Flat against curved the outline decides the in-plane pose alone. Otherwise its share in
    each direction follows from the information of the pairs at ``tf`` and their normal
    residual scale (at least the noise floor): point-to-plane information, or with the
    point metric on clouds sampled alike (:func:`same_sampling`) the point-to-point one,
    whose in-plane offsets are then noise, not the sampling pattern.
    """
    target, points, matching, floor_mm = problem.target, problem.points, problem.matching, problem.floor_mm
    pin_outline, flat_vs_curved = problem.settings.pin_outline, problem.flat_vs_curved
    if pin_outline is False:
        return None
    pairs = None if flat_vs_curved else icp.evaluate(target, points.fine, tf, matching, nearest)
    tangential = pairs is not None and matching.metric == "point" and same_sampling(pairs)

    def covariance(centre):
        normal = np.einsum("ij,ij->i", pairs.moved - pairs.matched, pairs.normal)
        sigma = max(robust_scale_mm(normal), floor_mm, 1e-9)
        if tangential:
            information, _ = icp.normal_equations(pairs, "point", target.frame.axes, centre, 1.0)
        else:
            information = icp.plane_information(pairs, target.frame.axes, centre)
        return surface_covariance(information, sigma)

    cloud = problem.cloud
    candidates = outline_candidates(cloud.frame, cloud.points, points.fine)
    pin, coverage = outline_pin(target, candidates, cloud.n_points, tf, require_coverage=pin_outline == "auto",
                                covariance=covariance, hard=flat_vs_curved, tangential=tangential)
    if pin is None:
        problem.notes.append(f"outline not pinned: {coverage}")
    return pin


def same_sampling(pairs: Pairs) -> bool:
    """Whether the pairs' in-plane offsets are noise (clouds sampled alike: a moved copy), not the sampling
    (:func:`mppf.registration.starts.sampled_alike`)."""
    normal = np.einsum("ij,ij->i", pairs.moved - pairs.matched, pairs.normal)
    return sampled_alike(Candidate("pairs", np.eye(4), normal, pairs.distance))


def check_starts(problem: Problem, result: Fit, info: dict, principal: PrincipalStart) -> tuple[Fit, dict]:
    """From a given (or identity) start: converge the principal-axes starts too, go on from a clearly better one.

    The given start's result and the four converged candidates are scored on the same
    sample; when the best is a principal-axes candidate in another pose that does not tie
    with the given start's result, the registration is run again from it (noted).
    """
    target, points, matching, floor_mm = problem.target, problem.points, problem.matching, problem.floor_mm
    metric = matching.metric
    names = ["+++", "--+", "-+-", "+--"]
    starts = dict(zip(names, principal_candidates(problem.cloud.frame, target.frame)))
    candidates = compared([evaluate(info["kind"], target, points.judge, result.fine.tf),
                           *converge_candidates(target, points.fit, points.judge, starts, metric, matching, principal)],
                          metric)
    given = candidates[0]
    order, second, tied = rank(candidates, floor_mm, points.judge.mean(axis=0), _size_mm(target))
    level = level_mm(candidates, floor_mm)
    info = {**info, "candidates": [c.name for c in candidates], "scores_mm": [c.score_mm(level) for c in candidates],
            "chosen": 0, "runner_up": second, "ambiguous": bool(tied)}
    best = order[0]
    if (best == 0 or same_pose(given.tf, candidates[best].tf, points.judge.mean(axis=0), _size_mm(target))
            or tie(candidates[best].residual, given.residual, floor_mm, level)):
        return result, info  # the given start's pose is (as good as) the best one
    problem.notes.append(f"the {info['kind']} start settled at a residual of {given.score_mm(level):.3g} mm; the "
                 f"principal-axes start {candidates[best].name} fits better ({candidates[best].score_mm(level):.3g} "
                 "mm): registered again from it")
    again = fit(problem, candidates[best].tf, NULL_REPORTER)
    info["chosen"] = best
    info["runner_up"] = 0
    return again, info


def in_plane(pin) -> str:
    """What fixed the in-plane shift: "pinned by the outline", "from the surface shape", or the outline
    along one axis only (its share at least a half there)."""
    if pin is None:
        return "from the surface shape"
    by_outline = [axis for axis in ("u", "v") if pin.weights[f"t_{axis}"] >= 0.5]
    if len(by_outline) == 2:
        return "pinned by the outline"
    if not by_outline:
        return "from the surface shape"
    return f"pinned by the outline along {by_outline[0]}, from the surface shape across"
