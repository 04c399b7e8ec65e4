"""The start of a scan's registration onto its design: converged starts, a rotation hint, the reference mark.

A few ICP iterations do not tell a nearly symmetric plate from its half turn when the
plate is still some mm off its design; converged fits usually do. So each of the four
principal-axes starts (:func:`mppf.registration.starts.principal_candidates`) is run to
convergence by a trimmed, Huber-weighted point-to-plane ICP on a subsample of the scan
and scored by its RMS; a rotation hint breaks a tie, a reference mark picks among them
(or, when all of them slid off it, starts held at the mark are fitted). See
``docs/compare.md``, "Which way round". Lengths in mm.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy.spatial.transform import Rotation

from mppf.core.errors import InputError
from mppf.core.transform import apply_tf, make_tf, rotation_angle_deg
from mppf.registration.register import register_icp
from mppf.registration.settings import ScanStart
from mppf.registration.starts import principal_candidates
from mppf.registration.target import Cloud, RegistrationTarget


def choose_start(scan: Cloud, target: RegistrationTarget, rotation_hint, reference_mark,
                 length_mm: float, settings: ScanStart = ScanStart()) -> tuple[np.ndarray, str]:
    """The start of the registration (measured -> design) and a note saying how it was chosen.

    Parameters
    ----------
    scan : Cloud
        The scan, prepared (:func:`mppf.registration.target.prepare`).
    target : RegistrationTarget
        The design skin.
    rotation_hint : (3, 3) or (4, 4) float or None
        Rough rotation measured -> design, used to break a tie of the best two starts.
    reference_mark : pair of (3,) float or None
        ``(measured_xyz, design_xyz)`` of the plate's reference-corner mark.
    length_mm : float
        The design's length (largest in-plane extent).
    settings : ScanStart

    Returns
    -------
    tf : (4, 4) float
    note : str

    Raises
    ------
    InputError
        A malformed hint or mark.
    """
    hint = None if rotation_hint is None else _as_rotation(rotation_hint)
    mark = None if reference_mark is None else _as_mark(reference_mark)
    candidates = principal_candidates(scan.frame, target.frame)
    fits, scores = zip(*_map(lambda start: _start_fit(scan, target, start, settings), candidates, settings))
    order = [int(i) for i in np.argsort(scores)]
    best, second = order[0], order[1]
    scored = ", ".join(f"{s:.2f}" for s in scores)
    if mark is not None:
        return _mark_start(scan, target, candidates, fits, scores, order, mark, length_mm, settings)
    if hint is not None and scores[second] <= settings.tie_ratio * scores[best] + 1e-9:
        turns = {i: rotation_angle_deg(fits[i][:3, :3] @ hint.T) for i in (best, second)}
        chosen = min(turns, key=turns.get)
        return fits[chosen], f"start: tie of the best two starts broken by the rotation hint; converged RMS {scored} mm"
    tie = (" (a tie of the best two: nearly symmetric plate, no hint)"
           if scores[second] <= settings.tie_ratio * scores[best] else "")
    return fits[best], f"start: best converged fit{tie}; converged RMS {scored} mm"


def _mark_start(scan, target, candidates, fits, scores, order, mark, length_mm, settings):
    """The start settled by the reference mark: the best start that agrees with it, else a start held at it."""
    scored = ", ".join(f"{s:.2f}" for s in scores)
    miss = [float(np.linalg.norm(apply_tf(tf, mark[0][None])[0] - mark[1])) for tf in fits]
    agree = [i for i in order if miss[i] <= settings.mark_radius_fraction * length_mm]
    if agree:
        chosen = agree[0]
        how = "the reference mark" + (" (it overruled the best fit)" if chosen != order[0] else "")
        return fits[chosen], (f"start: {how}; converged RMS of the four principal-axes starts {scored} mm, "
                              f"mark {miss[chosen]:.0f} mm from its place")
    # the free fits slid away (a plate still far off its design fits a shifted, turned
    # design about as well): fit again from each start with the mark held at its place
    n = scan.n_points
    sample = scan.points[np.random.default_rng(0).choice(n, size=min(n, settings.points), replace=False)]
    held = _map(lambda start: _held_fit(scan, target, start, mark, sample, settings),
                _held_starts(target, candidates, mark, sample, settings), settings)
    held_scores = [rms for _, rms in held]
    chosen = int(np.argmin(held_scores))
    # a mark picked in the wrong place holds the scan off the design: not taken
    if held_scores[chosen] <= settings.held_max_rms_fraction * length_mm:
        return held[chosen][0], (
            f"start: the reference mark held in place (the free fits slid {min(miss):.0f} mm or more off it); "
            f"RMS of the {len(held)} best turns so held {', '.join(f'{v:.1f}' for v in held_scores)} mm")
    note = (f"start: no start puts the reference mark near its place (nearest {min(miss):.0f} mm): "
            "the best fit is used; check the mark")
    return fits[order[0]], f"{note}; converged RMS {scored} mm"


def _map(fit, starts, settings: ScanStart) -> list:
    """``[fit(start) for start in starts]``, on ``settings.workers`` threads (the fits are independent)."""
    if settings.workers <= 1:
        return [fit(start) for start in starts]
    with ThreadPoolExecutor(max_workers=settings.workers) as pool:
        return list(pool.map(fit, starts))


def _start_fit(scan, target, start, settings: ScanStart) -> tuple[np.ndarray, float]:
    """A start converged by trimmed, Huber-weighted point-to-plane ICP on a subsample: (tf, RMS)."""
    reg = register_icp(scan, target, method="plane", init=start, trim_fraction=settings.trim_fraction,
                       robust="huber", pin_outline=False, max_points=settings.points,
                       max_iterations=settings.iterations)
    return reg.tf, reg.rms_mm


def _held_starts(target, candidates, mark, sample, settings: ScanStart) -> list[np.ndarray]:
    """Starts with the reference mark on its place: the ``held_keep`` best of a sweep of turns.

    The principal axes of a scan with hidden parts may be tens of degrees off the design's;
    so both ways up (the candidates' normal flipped or not), the scan is turned about the
    design's normal through the mark in steps of ``held_turn_step_deg`` and each pose is
    scored, without iterating, by :func:`_nearest_rms` of the scan's ``sample`` (clipped at
    a tenth of the design's size, so that a far corner does not rule).
    """
    normal = target.frame.axes[2]
    clip = 0.1 * float(np.ptp(target.points, axis=0).max())
    poses, scores = [], []
    for base in (candidates[0], candidates[2]):  # the two ways up
        for turn in np.arange(0.0, 360.0, settings.held_turn_step_deg):
            tf = make_tf(Rotation.from_rotvec(np.radians(turn) * normal).as_matrix() @ base[:3, :3], np.zeros(3))
            tf[:3, 3] = mark[1] - apply_tf(tf, mark[0][None])[0]
            poses.append(tf)
            scores.append(_nearest_rms(target, sample, tf, clip))
    return [poses[i] for i in np.argsort(scores)[:settings.held_keep]]


def _held_fit(scan, target, start, mark, sample, settings: ScanStart) -> tuple[np.ndarray, float]:
    """A start fitted with the reference mark held at its place: (tf, RMS distance of ``sample``).

    Point-to-point ICP on a subsample in ``hold_rounds`` rounds, each followed by the shift
    that puts the mark (measured, design) back on its place: the best fit with the mark
    held (to within the few mm it was picked to). Scored by :func:`_nearest_rms`: a pose
    held off the design by the mark leaves points beyond the design's edge, whose
    point-to-plane distances can still be small.
    """
    tf = np.array(start, dtype=float)
    for _ in range(settings.hold_rounds):
        tf[:3, 3] += mark[1] - apply_tf(tf, mark[0][None])[0]
        reg = register_icp(scan, target, method="point", init=tf, trim_fraction=settings.trim_fraction,
                           pin_outline=False, max_points=settings.points,
                           max_iterations=max(settings.iterations // settings.hold_rounds, 1))
        tf = np.array(reg.tf, dtype=float)
    tf[:3, 3] += mark[1] - apply_tf(tf, mark[0][None])[0]
    return tf, _nearest_rms(target, sample, tf)


def _nearest_rms(target: RegistrationTarget, points, tf, clip: float = np.inf) -> float:
    """RMS distance (mm) of ``points`` moved by ``tf`` to their nearest target points, each clipped."""
    near, _ = target.tree.query(apply_tf(tf, points))
    return float(np.sqrt(np.mean(np.minimum(near, clip) ** 2)))


def _as_rotation(rotation_hint) -> np.ndarray:
    hint = np.asarray(rotation_hint, dtype=float)
    if hint.shape not in ((3, 3), (4, 4)) or not np.all(np.isfinite(hint)):
        raise InputError(f"rotation_hint must be a (3, 3) rotation or a (4, 4) transform, got shape {hint.shape}")
    return hint[:3, :3]


def _as_mark(reference_mark) -> tuple[np.ndarray, np.ndarray]:
    try:
        measured, design = (np.asarray(p, dtype=float).reshape(3) for p in reference_mark)
    except (TypeError, ValueError):
        raise InputError("reference_mark must be a pair (measured_xyz, design_xyz) of 3 coordinates each",
                         hint="give the mark's position in the scan and the corner's on the design, mm") from None
    if not (np.all(np.isfinite(measured)) and np.all(np.isfinite(design))):
        raise InputError(f"reference_mark has NaN or infinite coordinates: {measured}, {design}")
    return measured, design
