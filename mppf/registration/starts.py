"""Principal-axes starts of a registration: the four candidates, converged, scored and compared.

Aligning the principal axes (and centroids) of source and target leaves the signs of the
axes open: the four proper sign flips are the candidates. :func:`converge_candidates` runs
each to convergence on a subsample (a few iterations do not tell a plate from its half
turn while it is still millimetres off) and keeps the residuals of one common sample at
the result; :func:`rank` orders them, merges candidates that reached the same pose, and
says whether the best two different poses tie within the noise
(:func:`mppf.registration.trust.tie`): a (nearly) symmetric plate. Lengths in mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.transform import make_tf, rotation_angle_deg
from mppf.registration import icp
from mppf.registration.settings import Matching, PrincipalStart
from mppf.registration.target import RegistrationTarget
from mppf.registration.trust import CLIP_FLOORS, point_residuals, robust_scale_mm, tie

SIGN_FLIPS = ((1, 1, 1), (-1, -1, 1), (-1, 1, -1), (1, -1, -1))
"""Proper sign flips of the (u, v, n) principal axes tried by the principal-axes start."""

SAME_POSE_DEG = 5.0
"""Converged candidates whose rotations differ by less than this ..."""

SAME_POSE_FRACTION = 0.05
"""... and whose centroids land within this fraction of the plate size reached the same pose."""

SAMPLED_ALIKE = 4.0
"""Median in-plane over median normal offset of the pairs below which two clouds count as sampled alike."""


def _proper_axes(axes: np.ndarray) -> np.ndarray:
    return axes if np.linalg.det(axes) > 0 else axes * np.array([[1.0], [1.0], [-1.0]])


def principal_candidates(source_frame, target_frame) -> list[np.ndarray]:
    """The four proper rotations that align the source's principal axes with the target's.

    Parameters
    ----------
    source_frame, target_frame : mppf.geometry.frame.LocalFrame

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


@dataclass(frozen=True, eq=False)
class Candidate:
    """One start, converged: its name, transform, and the common sample's residuals (k,) there.

    ``normal`` are the sample's distances to the target's local planes, ``distance`` to
    the closest target points. Candidates are compared on the residuals of the
    registration's metric: the normal ones for point-to-plane, the distances for
    point-to-point (whose point correspondences also tell a symmetric moved copy from its
    half turn).
    """

    name: str
    tf: np.ndarray
    normal: np.ndarray
    distance: np.ndarray
    by_distance: bool = False

    @property
    def residual(self) -> np.ndarray:
        """The residuals the candidate is compared on."""
        return self.distance if self.by_distance else self.normal

    def score_mm(self, level_mm: float) -> float:
        """RMS of the residuals, each squared residual clipped at ``CLIP_FLOORS`` levels as in the tie test (mm)."""
        clip = (CLIP_FLOORS * max(level_mm, 1e-9)) ** 2
        return float(np.sqrt(np.mean(np.minimum(self.residual**2, clip))))


def level_mm(candidates: list[Candidate], floor_mm: float) -> float:
    """The residual level the candidates' squared residuals are clipped at (in ``CLIP_FLOORS``): the
    noise floor, or the best candidate's robust residual scale when larger (shapes that differ)."""
    return max(floor_mm, min(robust_scale_mm(c.residual) for c in candidates))


def evaluate(name: str, target: RegistrationTarget, points: np.ndarray, tf: np.ndarray) -> Candidate:
    """The candidate ``tf`` with the normal residuals and closest-point distances of ``points``."""
    normal, distance = point_residuals(target, points, tf)
    return Candidate(name, tf, normal, distance)


def sampled_alike(candidate: Candidate) -> bool:
    """Whether the clouds are sampled alike at this pose: in-plane offsets about the normal ones (noise).

    Isotropic noise puts the median in-plane offset at about 1.75 times the median normal
    offset; a different sampling puts it at about the point spacing.
    """
    along = np.sqrt(np.maximum(candidate.distance**2 - candidate.normal**2, 0.0))
    return bool(np.median(along) <= SAMPLED_ALIKE * max(float(np.median(np.abs(candidate.normal))), 1e-12))


def compared(candidates: list[Candidate], metric: str) -> list[Candidate]:
    """The candidates set to be compared on the residuals of ``metric`` ("point": distances)."""
    return [Candidate(c.name, c.tf, c.normal, c.distance, metric == "point") for c in candidates]


def converge_candidates(target: RegistrationTarget, fit_src: np.ndarray, score_src: np.ndarray, starts: dict,
                        metric: str, matching: Matching, settings: PrincipalStart) -> list[Candidate]:
    """Each start ``{name: tf}`` run to convergence (ICP on ``fit_src``), with the residuals of ``score_src``.

    With the registration's trimming and robust weights.
    """
    fit = Matching(metric, matching.trim_fraction, matching.robust)
    out = []
    for name, tf in starts.items():
        stage = icp.run(target, fit_src, tf, fit, icp.Stop(settings.iterations, *settings.tolerances))
        out.append(evaluate(name, target, score_src, stage.tf))
    return out


def same_pose(a: np.ndarray, b: np.ndarray, centre: np.ndarray, size_mm: float) -> bool:
    """Whether two transforms put the source (centre ``centre``) in the same pose."""
    moved = [a[:3, :3] @ centre + a[:3, 3], b[:3, :3] @ centre + b[:3, 3]]
    return (rotation_angle_deg(a[:3, :3] @ b[:3, :3].T) < SAME_POSE_DEG
            and float(np.linalg.norm(moved[0] - moved[1])) < SAME_POSE_FRACTION * size_mm)


def rank(candidates: list[Candidate], floor_mm: float, centre: np.ndarray,
         size_mm: float) -> tuple[list[int], int | None, bool]:
    """(order best first, index of the best different pose or None, whether those two tie).

    ``candidates`` are compared as :func:`compared` sets them.
    """
    level = level_mm(candidates, floor_mm)
    order = sorted(range(len(candidates)), key=lambda i: candidates[i].score_mm(level))
    best = candidates[order[0]]
    for i in order[1:]:
        if not same_pose(best.tf, candidates[i].tf, centre, size_mm):
            return order, i, tie(best.residual, candidates[i].residual, floor_mm, level)
    return order, None, False


def principal_start(target: RegistrationTarget, fit_src: np.ndarray, score_src: np.ndarray, source_frame,
                    matching: Matching, floor_mm: float, size_mm: float,
                    settings: PrincipalStart = PrincipalStart()) -> tuple[np.ndarray, dict]:
    """The best principal-axes start, converged, and how it was chosen (``Registration.init``).

    The candidates converge and are compared with ``matching`` (its metric: distances for
    "point", normal residuals for "plane").

    Returns
    -------
    tf : (4, 4) float
        The best candidate, converged on ``fit_src``.
    info : dict
        ``kind`` "principal", the candidates' sign flips, their scores (mm, RMS of the
        clipped residuals of ``score_src``), the chosen one, the runner-up (the best
        different pose) and whether they tie (``ambiguous``).
    """
    metric = matching.metric
    names = ["".join("+" if s > 0 else "-" for s in flip) for flip in SIGN_FLIPS]
    starts = dict(zip(names, principal_candidates(source_frame, target.frame)))
    candidates = compared(converge_candidates(target, fit_src, score_src, starts, metric, matching, settings),
                          metric)
    order, second, tied = rank(candidates, floor_mm, score_src.mean(axis=0), size_mm)
    if tied and rotation_angle_deg(candidates[second].tf[:3, :3]) < rotation_angle_deg(candidates[order[0]].tf[:3, :3]):
        # a tie the points cannot settle goes to the least turn of the given coordinates (a design and
        # its unfolded flat, or a scan taken as the plate lies, share their axes): the same data gives
        # the same pose whichever way its point sampling tips the residuals
        order = [second] + [i for i in order if i != second]
        second = next((i for i in order[1:] if not same_pose(candidates[order[0]].tf, candidates[i].tf,
                                                             score_src.mean(axis=0), size_mm)), None)
    info = {
        "kind": "principal",
        "candidates": names,
        "scores_mm": [c.score_mm(level_mm(candidates, floor_mm)) for c in candidates],
        "chosen": order[0],
        "runner_up": second,
        "ambiguous": bool(tied),
        "compared_on": "closest-point distances" if candidates[0].by_distance else "normal residuals",
    }
    return candidates[order[0]].tf, info
