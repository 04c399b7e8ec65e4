"""Principal-axes starts of a registration: the four candidates and how they are scored.

Aligning the principal axes (and centroids) of source and target leaves the signs of the
axes open: the four proper sign flips are the candidates. ``register_icp`` runs each a
few point-to-point iterations and keeps the one whose closest-point distances are
smallest (:func:`principal_start`); a nearly symmetric plate (a saddle, half a turn)
scores two of them alike, which is flagged. Lengths in mm.
"""

from __future__ import annotations

import numpy as np

from mppf.core.transform import apply_tf, make_tf
from mppf.registration import icp
from mppf.registration.settings import Matching, PrincipalStart
from mppf.registration.target import RegistrationTarget, query

SIGN_FLIPS = ((1, 1, 1), (-1, -1, 1), (-1, 1, -1), (1, -1, -1))
"""Proper sign flips of the (u, v, n) principal axes tried by the principal-axes start."""


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


def trimmed_rms(target: RegistrationTarget, source: np.ndarray, tf: np.ndarray, keep_fraction: float) -> float:
    """RMS of the best ``keep_fraction`` of the closest-point distances of the moved source, mm."""
    dist, _ = query(target.tree, apply_tf(tf, source))
    keep = max(3, int(keep_fraction * dist.size))
    return float(np.sqrt(np.mean(np.partition(dist, keep - 1)[:keep] ** 2)))


def principal_start(target: RegistrationTarget, score_src: np.ndarray, source_frame, matching: Matching,
                    settings: PrincipalStart = PrincipalStart()) -> tuple[np.ndarray, dict]:
    """The best principal-axes start: each candidate run a few iterations, scored by :func:`trimmed_rms`.

    Parameters
    ----------
    target : RegistrationTarget
    score_src : (k, 3) float, mm
        The source points the candidates are scored on (a subsample).
    source_frame : LocalFrame
        The whole source's frame.
    matching : Matching
        Pair weights of the registration (the candidates are run point-to-point).
    settings : PrincipalStart

    Returns
    -------
    tf : (4, 4) float
        The refined best candidate.
    info : dict
        ``kind`` "principal", the candidates' sign flips, their scores (mm), the chosen
        one and whether the start is ambiguous.
    """
    point = Matching("point", matching.trim_fraction, matching.robust)
    scores, refined = [], []
    for tf in principal_candidates(source_frame, target.frame):
        stage = icp.run(target, score_src, tf, point, max_iterations=settings.iterations, tol=(0.0, 0.0, 0.0))
        refined.append(stage.tf)
        scores.append(trimmed_rms(target, score_src, stage.tf, settings.keep_fraction))
    order = np.argsort(scores)
    best, second = int(order[0]), int(order[1])
    ambiguous = bool(scores[second] <= settings.ambiguous_ratio * scores[best] + 1e-9)
    info = {
        "kind": "principal",
        "candidates": ["".join("+" if s > 0 else "-" for s in flip) for flip in SIGN_FLIPS],
        "scores_mm": [float(s) for s in scores],
        "chosen": best,
        "ambiguous": ambiguous,
    }
    return refined[best], info
