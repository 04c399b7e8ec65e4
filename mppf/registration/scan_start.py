"""The start of a scan's registration onto its design: converged starts, a tie, a rotation hint, the reference mark.

A few ICP iterations do not tell a nearly symmetric plate from its half turn when the
plate is still some mm off its design; converged fits usually do. So each of the four
principal-axes starts (:func:`mppf.registration.starts.principal_candidates`) is run to
convergence by a trimmed, Huber-weighted point-to-plane ICP on a subsample of the scan and
its normal residuals on one common sample are kept. The best two different poses TIE
(:func:`start_tie`) when the scan cannot tell them apart: their residuals are equal within
the noise, or the design is nearly as symmetric under the turn between them as the scan
is off the design (then the plate's own shape errors could favour either). A tie is
settled by the reference mark, else by a rotation hint; with neither the start is
ambiguous and the caller must not judge (:class:`AmbiguousStart`). See ``docs/compare.md``,
"Which way round". Lengths in mm.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from mppf.core.errors import EXIT_PRESS, InputError, MppfError
from mppf.core.threads import worker_threads
from mppf.core.transform import apply_tf, make_tf, rotation_angle_deg, rotvec_to_matrix
from mppf.registration.register import converge_start, register_icp
from mppf.registration.settings import RegisterOptions, ScanStart
from mppf.registration.starts import evaluate, principal_candidates, rank
from mppf.registration.target import Cloud, RegistrationTarget
from mppf.registration.trust import noise_floor_mm, plane_residuals, robust_scale_mm, sample_index, tie

SYMMETRY_FACTOR = 2.0
"""The scan tells two turns apart only when the design's own misfit under the turn between them
exceeds this many times the scan's residual at the best one (shape errors shift the two alike)."""


class AmbiguousStart(MppfError, ValueError):
    """The scan fits its design equally well two ways round and no mark or hint says which (exit 4).

    Attributes
    ----------
    candidates : list of dict
        The two poses: ``name``, ``residual_mm``, ``turn_deg`` (from the best one).
    """

    exit_code = EXIT_PRESS

    def __init__(self, message: str, *, candidates: list, hint: str | None = None):
        super().__init__(message, hint=hint)
        self.candidates = candidates


@dataclass(frozen=True, eq=False)
class StartChoice:
    """The start of a scan's registration and how it was chosen.

    Attributes
    ----------
    tf : (4, 4) float
        Measured -> design.
    note : str
    ambiguous : bool
        The best two different poses tie (:func:`start_tie`), however it was then settled.
    settled_by : str
        "fit" (the best fit, no tie), "mark", "held mark", "fit (mark not found)", "hint",
        "earlier scan" (:func:`known_start`), or "none" (a tie nothing settled: :meth:`require_settled`
        raises).
    candidates : list of dict
        The four converged starts: ``name``, ``residual_mm`` (robust normal residual of the
        common sample), ``turn_deg`` from the chosen one.
    floor_mm : float
        The scan's noise floor against the design.
    design_asymmetry_mm : float or None
        RMS misfit of the design onto itself under the turn between the best two poses.
    tied_pair : (int, int) or None
        Indices in ``candidates`` of the two tied poses (when nothing settled the tie).
    first_settled_by : str or None
        With "earlier scan": how the turn was settled in the comparison of the first scan.
    """

    tf: np.ndarray
    note: str
    ambiguous: bool
    settled_by: str
    candidates: list = field(default_factory=list)
    floor_mm: float = float("nan")
    design_asymmetry_mm: float | None = None
    tied_pair: tuple | None = None
    first_settled_by: str | None = None

    @property
    def settled(self) -> bool:
        """Whether the turn is known: no tie, or a tie settled by the mark or the hint."""
        return self.settled_by != "none"

    def require_settled(self) -> None:
        """Raise :class:`AmbiguousStart` (exit 4, both candidates shown) when the turn is not known."""
        if self.settled:
            return
        pair = [self.candidates[i] for i in self.tied_pair]
        raise AmbiguousStart(
            f"ambiguous: give the reference mark. The scan fits its design equally well two ways round: start "
            f"{pair[0]['name']} (residual {pair[0]['residual_mm']:.2f} mm) and start {pair[1]['name']} (residual "
            f"{pair[1]['residual_mm']:.2f} mm), turned {pair[1]['turn_deg']:.0f} deg from each other (noise floor "
            f"{self.floor_mm:.2f} mm, design asymmetry under that turn {self.design_asymmetry_mm:.2f} mm)",
            candidates=pair,
            hint="pick the reference-corner mark in the scan and give it (compare --mark X,Y,Z, or a "
                 "<scan>.mark.json file beside the scan), or give a rotation hint")

    def info(self) -> dict:
        """JSON-able summary (``Registration.init`` of a comparison)."""
        return {"kind": "scan start", "settled_by": self.settled_by, "ambiguous": self.ambiguous,
                "candidates": self.candidates, "floor_mm": self.floor_mm if np.isfinite(self.floor_mm) else None,
                "design_asymmetry_mm": self.design_asymmetry_mm,
                **({"first_settled_by": self.first_settled_by} if self.first_settled_by else {})}


def choose_start(scan: Cloud, target: RegistrationTarget, rotation_hint, reference_mark,
                 length_mm: float, settings: ScanStart = ScanStart()) -> StartChoice:
    """The start of the registration (measured -> design) and how it was chosen.

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
    StartChoice

    Raises
    ------
    InputError
        A malformed hint or mark.

    A tie with neither a mark nor a hint is returned unsettled (``settled_by="none"``, the
    best fit as ``tf``): the caller checks that the scan is of this plate at all, then calls
    :meth:`StartChoice.require_settled` (:class:`AmbiguousStart`).
    """
    hint = None if rotation_hint is None else as_rotation(rotation_hint)
    mark = None if reference_mark is None else as_mark(reference_mark)
    # 1-2. the four principal-axes starts converged and ranked; whether the scan tells the best two apart
    floor = noise_floor_mm(scan, target)
    converged = _converged(scan, target, floor, length_mm, settings)
    fits, candidates, order, second = converged.fits, converged.candidates, converged.order, converged.second
    tied, asymmetry = start_tie(target, candidates[order[0]], None if second is None else candidates[second], floor)
    best = order[0]
    summary = lambda chosen: _summary(candidates, chosen)  # noqa: E731
    scored = ", ".join(f"{robust_scale_mm(c.normal):.2f}" for c in candidates)
    # 3. the mark settles the turn; a hint breaks a tie; a tie without either is not judged
    if mark is not None:
        tf, note, how = _mark_start(scan, target, converged, mark, length_mm, settings)
        chosen = min(range(4), key=lambda i: rotation_angle_deg(fits[i][:3, :3] @ tf[:3, :3].T))
        return StartChoice(tf, note, tied, how, summary(chosen), floor, asymmetry)
    if tied and hint is not None:
        turns = {i: rotation_angle_deg(fits[i][:3, :3] @ hint.T) for i in (best, second)}
        chosen = min(turns, key=turns.get)
        return StartChoice(fits[chosen], f"start: tie of the best two starts broken by the rotation hint; converged "
                                         f"residual {scored} mm", True, "hint", summary(chosen), floor, asymmetry)
    if tied:  # not judged: the caller raises AmbiguousStart once the scan is known to be of this plate
        return StartChoice(fits[best], f"start: a tie of the best two poses, settled neither by a mark nor by a "
                                       f"hint; converged residual {scored} mm", True, "none", summary(best), floor,
                           asymmetry, (best, second))
    return StartChoice(fits[best], f"start: best converged fit; converged residual {scored} mm", False, "fit",
                       summary(best), floor, asymmetry)


SETTLED = {"fit": "the best fit", "mark": "the reference mark", "held mark": "the reference mark held in place",
           "fit (mark not found)": "the best fit (the mark not found)", "hint": "the rotation hint"}
"""How a start was settled (``StartChoice.settled_by``), in words."""


def known_start(start_from) -> StartChoice:
    """The start of a scan in the frame of one already compared: its Comparison, or its (4, 4) transform.

    For a union of scans taken in one frame (the loop's rescans): the first scan's registration
    settled the turn; it is refined, not chosen again, and the note says how it was settled there
    (``first_settled_by`` in :meth:`StartChoice.info`). InputError for a malformed transform.
    """
    init = getattr(getattr(start_from, "registration", None), "init", None) or {}
    first = init.get("first_settled_by") or init.get("settled_by")
    start = np.asarray(getattr(start_from, "transform", start_from), dtype=float)
    if start.shape != (4, 4) or not np.all(np.isfinite(start)):
        raise InputError(f"start_from must be a comparison or a finite (4, 4) transform, got shape {start.shape}",
                         hint="give the comparison (or transform) of the scan these share their frame with")
    how = f" (its turn settled there by {SETTLED.get(first, first)})" if first else ""
    return StartChoice(start, f"start: the registration of the scan this one shares its frame with{how}", False,
                       "earlier scan", first_settled_by=first)


def start_tie(target: RegistrationTarget, best, other, floor_mm: float) -> tuple[bool, float | None]:
    """Whether the scan cannot tell ``best`` from ``other`` (Candidates), and the design's asymmetry (mm).

    A tie: their residuals are equal within the noise (:func:`mppf.registration.trust.tie`),
    or the design, moved by the turn between them and fitted onto itself, misfits itself by
    less than :data:`SYMMETRY_FACTOR` times the scan's residual at ``best``.
    """
    if other is None:
        return False, None
    relative = other.tf @ np.linalg.inv(best.tf)  # design -> design: one pose onto the other
    sample = target.points[sample_index(target.n_points, 1500, seed=2)]
    fit = register_icp(sample, target, RegisterOptions(method="plane", init=relative, pin_outline=False,
                                                       max_points=1500, max_iterations=30, check_starts=False))
    asymmetry = float(np.sqrt(np.mean(plane_residuals(target, sample, fit.tf) ** 2)))
    residual = robust_scale_mm(best.normal)
    return bool(tie(best.normal, other.normal, floor_mm) or asymmetry < SYMMETRY_FACTOR * residual), asymmetry


def _summary(candidates, chosen: int) -> list[dict]:
    """The converged starts as dicts: name, robust residual, turn from the chosen one."""
    ref = candidates[chosen].tf[:3, :3]
    return [{"name": c.name, "residual_mm": robust_scale_mm(c.normal),
             "turn_deg": rotation_angle_deg(c.tf[:3, :3] @ ref.T)} for c in candidates]


@dataclass(frozen=True, eq=False)
class _Converged:
    """The four principal-axes starts (4, 4) each, converged (``fits``), their evaluations on one sample,
    the ranking (best first) and the best different pose (or None)."""

    starts: list
    fits: list
    candidates: list
    order: list
    second: int | None


def _converged(scan: Cloud, target: RegistrationTarget, floor_mm: float, length_mm: float,
               settings: ScanStart) -> _Converged:
    """The four principal-axes starts, converged; their residuals on one common sample; ranked."""
    judge = scan.points[sample_index(scan.n_points, settings.points, seed=1)]
    starts = principal_candidates(scan.frame, target.frame)
    fits = _map(lambda start: _start_fit(scan, target, start, settings), starts, settings)
    candidates = [evaluate(name, target, judge, tf) for name, tf in zip(("+++", "--+", "-+-", "+--"), fits)]
    order, second, _ = rank(candidates, floor_mm, judge.mean(axis=0), length_mm)
    return _Converged(starts, fits, candidates, order, second)


def _mark_start(scan, target, converged: _Converged, mark, length_mm: float, settings: ScanStart):
    """The start settled by the reference mark: the best start that agrees with it, else a start held at it."""
    candidates, fits, order = converged.starts, converged.fits, converged.order
    scored = ", ".join(f"{robust_scale_mm(c.normal):.2f}" for c in converged.candidates)
    miss = [float(np.linalg.norm(apply_tf(tf, mark[0][None])[0] - mark[1])) for tf in fits]
    agree = [i for i in order if miss[i] <= settings.mark_radius_fraction * length_mm]
    if agree:
        chosen = agree[0]
        how = "the reference mark" + (" (it overruled the best fit)" if chosen != order[0] else "")
        return fits[chosen], (f"start: {how}; converged residual of the four principal-axes starts {scored} mm, "
                              f"mark {miss[chosen]:.0f} mm from its place"), "mark"
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
            f"RMS of the {len(held)} best turns so held {', '.join(f'{v:.1f}' for v in held_scores)} mm"), "held mark"
    note = (f"start: no start puts the reference mark near its place (nearest {min(miss):.0f} mm): "
            "the best fit is used; check the mark")
    return fits[order[0]], f"{note}; converged residual {scored} mm", "fit (mark not found)"


def _map(fit, starts, settings: ScanStart) -> list:
    """``[fit(start) for start in starts]``, on ``settings.workers`` threads (the fits are independent)."""
    threads = worker_threads() if settings.workers is None else settings.workers
    if threads <= 1:
        return [fit(start) for start in starts]
    from threadpoolctl import threadpool_limits

    # one BLAS thread set once here, for both threads: each fit's own limit then sets and restores the same
    # value (BLAS's thread count is process-wide; restored by one thread while the other computes, it would not be)
    with threadpool_limits(limits=1, user_api="blas"), ThreadPoolExecutor(max_workers=threads) as pool:
        return list(pool.map(fit, starts))


def _start_fit(scan, target, start, settings: ScanStart) -> np.ndarray:
    """A start converged by trimmed, Huber-weighted point-to-plane ICP on a subsample (measured -> design)."""
    return converge_start(scan, target, start, RegisterOptions(method="plane", trim_fraction=settings.trim_fraction,
                                                           robust="huber", pin_outline=False, max_points=settings.points,
                                                           max_iterations=settings.iterations, check_starts=False))


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
            tf = make_tf(rotvec_to_matrix(np.radians(turn) * normal) @ base[:3, :3], np.zeros(3))
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
        tf = np.array(converge_start(scan, target, tf, RegisterOptions(
            method="point", trim_fraction=settings.trim_fraction, pin_outline=False, max_points=settings.points,
            max_iterations=max(settings.iterations // settings.hold_rounds, 1), check_starts=False)), dtype=float)
    tf[:3, 3] += mark[1] - apply_tf(tf, mark[0][None])[0]
    return tf, _nearest_rms(target, sample, tf)


def _nearest_rms(target: RegistrationTarget, points, tf, clip: float = np.inf) -> float:
    """RMS distance (mm) of ``points`` moved by ``tf`` to their nearest target points, each clipped."""
    near, _ = target.tree.query(apply_tf(tf, points))
    return float(np.sqrt(np.mean(np.minimum(near, clip) ** 2)))


def as_rotation(rotation_hint) -> np.ndarray:
    """The (3, 3) rotation of a hint given as (3, 3) or (4, 4); InputError for another shape or NaN."""
    hint = np.asarray(rotation_hint, dtype=float)
    if hint.shape not in ((3, 3), (4, 4)) or not np.all(np.isfinite(hint)):
        raise InputError(f"rotation_hint must be a finite (3, 3) rotation or (4, 4) transform, got shape {hint.shape}",
                         hint="give the rough rotation measured -> design, e.g. the inverse of the job's press pose")
    return hint[:3, :3]


def as_mark(reference_mark) -> tuple[np.ndarray, np.ndarray]:
    """``(measured_xyz, design_xyz)`` of a reference mark as two (3,) float arrays, mm; InputError if malformed."""
    try:
        measured, design = (np.asarray(p, dtype=float).reshape(3) for p in reference_mark)
    except (TypeError, ValueError):
        raise InputError("reference_mark must be a pair (measured_xyz, design_xyz) of 3 coordinates each",
                         hint="give the mark's position in the scan and the corner's on the design, mm") from None
    if not (np.all(np.isfinite(measured)) and np.all(np.isfinite(design))):
        raise InputError(f"reference_mark has NaN or infinite coordinates: {measured}, {design}",
                         hint="give the mark's position in the scan and the corner's on the design, mm")
    return measured, design
