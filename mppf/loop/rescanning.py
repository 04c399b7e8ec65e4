"""Rescans: areas not measured and spots of set-aside points are scanned again, the union of the scans compared.

A compared cycle whose verdict needs review only because areas of the net plate were not
measured and / or points set aside as scanner artefacts lie beyond the tolerance
(:attr:`mppf.measure.decision.Verdict.only_rescannable`: the limits met, not badly formed) is not
stopped at once: the loop asks the station for a rescan of
those areas and spots (a scan request with ``rescan`` K and the ``regions``, ``kind``
"uncovered" or "artefacts": :func:`artefact_spots`; :mod:`mppf.loop.scan_request`;
``--on-pressed`` runs for it too), up to ``LoopSettings.rescans`` times per cycle, and compares
the union of the scans. A rescan is taken in the frame of the cycle's first scan (a fixed
station: the plate and the scanner have not moved), so its points are simply added; the union is
compared knowing the scan of each point, so a set-aside point another scan measured within the
tolerance is cleared (:func:`mppf.measure.outliers.clear_by_rescans`).

**The guard** (:func:`overlap_agreement`): where the rescan overlaps the earlier scans, the
union's normal deviations of its points must agree with those of the nearest earlier point
(within one point spacing in u, v): the median absolute difference must be at most
:data:`AGREE_NOISE` x the same median of the earlier scans' points against their own nearest
neighbour (their noise level) + :data:`AGREE_FLOOR_MM`, over at least :data:`MIN_OVERLAP`
points. A rescan that disagrees (the plate or the scanner moved), does not overlap, cannot be
read or makes a union that does not register is not merged: the loop stops with needs_review
and says why. A rescan is waited for at most ``LoopSettings.rescan_timeout_s``; when none came, the
cycle is decided on the scans taken and the run asks for no more rescans (a station that does not
rescan costs one wait per run, not one per cycle). See ``docs/scanner-station.md``, "Rescans".
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mppf.core.errors import GeometryError, InputError
from mppf.core.transform import apply_tf
from mppf.geometry.read import read_points
from mppf.loop.measuring import compare_union, rescan_paths
from mppf.loop.pressing import scan_context
from mppf.loop.records import load_cycle_job
from mppf.loop.scan_request import RescanAsk, post_request
from mppf.measure.decision import OUT_OF_TOLERANCE
from mppf.registration.scan_start import AmbiguousStart

AGREE_NOISE = 3.0
"""A rescan agrees when its median difference is within this many times the earlier scans' own (their noise)."""

AGREE_FLOOR_MM = 0.1
"""... plus this (mm): a noise-free scan still has its sampling and smoothing differences."""

MIN_OVERLAP = 30
"""Fewest rescan points beside earlier ones for the agreement to be judged (fewer: not merged)."""

SPOT_SPACINGS = 2.0
"""An artefact spot of a rescan request: a disc of this many point spacings about each point (merged when touching)."""

SPOT_MIN_RADIUS_MM = 10.0
"""... at least this radius (mm)."""

UNANSWERED = "rescan_unanswered"
"""Key of ``_Run.known``: which rescan request of the run went unanswered (then no more are asked in the run)."""

SPOTS_LISTED = 200
"""Most artefact spots a rescan request lists (the largest |deviation| first; the total is given)."""


@dataclass(frozen=True)
class Agreement:
    """How a rescan agrees with the earlier scans where they overlap (mm).

    Attributes
    ----------
    overlap : int
        Rescan points with an earlier point within one point spacing (u, v).
    difference_mm : float
        Median |deviation - the nearest earlier point's deviation| over them (NaN: no overlap).
    noise_mm : float
        The same median of the earlier scans' points against their own nearest neighbour.
    limit_mm : float
        ``AGREE_NOISE * noise_mm + AGREE_FLOOR_MM``.
    """

    overlap: int
    difference_mm: float
    noise_mm: float
    limit_mm: float

    @property
    def agrees(self) -> bool:
        return self.overlap >= MIN_OVERLAP and bool(self.difference_mm <= self.limit_mm)

    def describe(self) -> str:
        """One line, e.g. "median difference 0.28 mm <= 0.96 mm over 5210 overlapping points"."""
        if self.overlap < MIN_OVERLAP:
            return (f"it overlaps the earlier scans at {self.overlap} point(s) only (at least {MIN_OVERLAP}): "
                    "it cannot be checked to be in their frame")
        sign = "<=" if self.agrees else ">"
        return (f"median difference {self.difference_mm:.2f} mm {sign} {self.limit_mm:.2f} mm "
                f"({AGREE_NOISE:g} x the scans' own {self.noise_mm:.2f} mm + {AGREE_FLOOR_MM:g} mm) over "
                f"{self.overlap} overlapping points")

    def to_dict(self) -> dict:
        return {"overlap": self.overlap, "difference_mm": _finite(self.difference_mm), "noise_mm": self.noise_mm,
                "limit_mm": self.limit_mm, "agrees": self.agrees}


@dataclass(frozen=True)
class Measured:
    """What a cycle measured: the comparison decided on, every scan taken, why a rescan was not merged."""

    comparison: object
    scans: list
    stopped: str | None = None


def overlap_agreement(comparison, n_before: int) -> Agreement:
    """Whether the points after the first ``n_before`` of a union's comparison agree with those before.

    Parameters
    ----------
    comparison : Comparison
        Of the union (the earlier scans' points first).
    n_before : int
        How many points the earlier scans have.
    """
    from scipy.spatial import cKDTree

    dev = np.asarray(comparison.deviation_mm, dtype=float)
    usable = np.isfinite(dev) & ~np.asarray(comparison.is_outlier) & ~np.asarray(comparison.is_outside)
    index = np.arange(dev.shape[0])
    before, after = usable & (index < n_before), usable & (index >= n_before)
    uv = np.asarray(comparison.measured_uv_mm, dtype=float)
    if before.sum() < 2 or not after.any():
        return Agreement(0, float("nan"), float("nan"), float("nan"))
    tree = cKDTree(uv[before])
    # 1. the earlier scans' own spacing and noise: each point against its nearest other point
    dist, own = tree.query(uv[before], k=2)
    spacing = float(np.median(dist[:, 1]))
    noise = float(np.median(np.abs(dev[before] - dev[before][own[:, 1]])))
    # 2. the rescan's points against the nearest earlier point within one spacing
    dist, near = tree.query(uv[after], k=1, distance_upper_bound=spacing)
    hit = np.isfinite(dist)
    difference = float(np.median(np.abs(dev[after][hit] - dev[before][near[hit]]))) if hit.any() else float("nan")
    return Agreement(int(hit.sum()), difference, noise, AGREE_NOISE * noise + AGREE_FLOOR_MM)


def region_doc(gap, comparison, tf_press_design) -> dict:
    """An area not measured, for the rescan request: design (u, v) and, with the press pose, press (x, y).

    ``corners_press_mm``: the (u, v) box's corners on the press (the design frame's plane placed by
    ``tf_press_design``: about where the area lies, for the station to aim at).
    """
    doc = {"kind": "uncovered", **gap.to_dict()}
    doc["corners_press_mm"] = _corners_press(gap.box_uv_mm, comparison, tf_press_design)
    return doc


def artefact_spots(comparison, tf_press_design) -> list[dict]:
    """The spots of the set-aside points beyond the tolerance not cleared by a rescan (in the net plate and its trim
    margin), for the rescan request.

    Each point's disc (:data:`SPOT_SPACINGS` point spacings, at least :data:`SPOT_MIN_RADIUS_MM`), merged where
    discs overlap; each spot: ``kind`` "artefacts", ``centroid_uv_mm``, ``box_uv_mm`` (the discs' box),
    ``radius_mm``, ``count``, ``max_abs_mm``, ``press_xy_mm`` and ``corners_press_mm`` (None without the press
    pose); the largest |deviation| first (all of them: the request lists :data:`SPOTS_LISTED`).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    dev = np.asarray(comparison.deviation_mm, dtype=float)
    # the trim margin's too: a point at the net plate's edge falls in or out of the net as the union's
    # registration settles (a fraction of a mm), and may decide the next union
    on_plate = ~np.asarray(comparison.is_outside)
    beyond = np.asarray(comparison.is_outlier) & ~np.asarray(comparison.is_cleared) & on_plate
    beyond &= np.abs(np.nan_to_num(dev)) > comparison.tolerance_mm
    rows = np.flatnonzero(beyond)
    if not rows.size:
        return []
    spacing = comparison.set_aside.spacing_mm if comparison.set_aside is not None else float("nan")
    radius = max(SPOT_SPACINGS * spacing, SPOT_MIN_RADIUS_MM) if np.isfinite(spacing) else SPOT_MIN_RADIUS_MM
    uv = np.asarray(comparison.measured_uv_mm, dtype=float)[rows]
    # 1. discs that overlap belong to one spot
    pairs = cKDTree(uv).query_pairs(2.0 * radius, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(rows.size, rows.size))
    _, label = connected_components(graph, directed=False)
    spots = []
    for spot in range(label.max() + 1):
        member = label == spot
        low, high = uv[member].min(axis=0) - radius, uv[member].max(axis=0) + radius
        box = [float(low[0]), float(low[1]), float(high[0]), float(high[1])]
        centre = uv[member].mean(axis=0)
        press = None
        if tf_press_design is not None:
            press = apply_tf(tf_press_design, comparison.design_frame.to_world(np.r_[centre, 0.0][None]))[0, :2]
        spots.append({"kind": "artefacts", "centroid_uv_mm": [float(v) for v in centre], "box_uv_mm": box,
                      "radius_mm": float(radius), "count": int(member.sum()),
                      "max_abs_mm": float(np.abs(dev[rows[member]]).max()),
                      "press_xy_mm": None if press is None else [round(float(v), 1) for v in press],
                      "corners_press_mm": _corners_press(box, comparison, tf_press_design)})
    return sorted(spots, key=lambda s: -s["max_abs_mm"])


def _corners_press(box_uv_mm, comparison, tf_press_design):
    """The (u, v) box's four corners on the press, ``[x, y]`` rounded to 0.1 mm (None without the press pose)."""
    if tf_press_design is None:
        return None
    u0, v0, u1, v1 = box_uv_mm
    corners = np.array([[u0, v0, 0.0], [u1, v0, 0.0], [u1, v1, 0.0], [u0, v1, 0.0]])
    xy = apply_tf(tf_press_design, comparison.design_frame.to_world(corners))[:, :2]
    return [[round(float(x), 1), round(float(y), 1)] for x, y in xy]


def _rescannable(verdict) -> bool:
    """A rescan can decide the cycle or mend what it measured: it needs review only for areas not measured and / or
    set-aside points beyond the tolerance, or it is out of tolerance with areas not measured (the correction would
    otherwise guess the plate there); never for a badly formed plate. A point confirmed by two scans gets another
    look too: it clears the point only where the new scan measures a plain surface beside it nearer than any plate's
    flank allows (two artefacts at one spot by chance; :func:`mppf.measure.outliers.clear_by_rescans`), which no scan
    of a real dent can."""
    if verdict is None or verdict.figures.badly_formed:
        return False
    return verdict.only_rescannable or (verdict.kind == OUT_OF_TOLERANCE and verdict.figures.n_gaps > 0)


def _spots(comparison, tf_press_design) -> list:
    """The artefact spots worth a rescan: the set-aside points beyond the tolerance not yet re-measured within it.

    Asked for whenever a rescan is taken, also when it is taken for areas not measured while the cycle is out of
    tolerance: once those areas are measured the union may be within the limits, and then its artefacts decide (a
    rescan of the gaps alone would leave every artefact for the next rescan, and the rescans of a cycle are few).
    """
    if comparison.verdict is None or not comparison.verdict.figures.set_aside_beyond:
        return []
    return artefact_spots(comparison, tf_press_design)


def _asking(comparison, spots: list) -> str:
    """What the rescan is for, in words: the artefact spots, the areas not measured."""
    parts = []
    if spots:
        points = sum(s["count"] for s in spots)
        parts.append(f"{points} set-aside point(s) beyond the tolerance at {len(spots)} spot(s) not re-measured "
                     f"within it (largest |deviation| {spots[0]['max_abs_mm']:.2f} mm)")
    if comparison.coverage is not None and comparison.coverage.regions:
        parts.append(f"{len(comparison.coverage.regions)} area(s) not measured "
                     f"({'; '.join(comparison.coverage.names())})")
    return "; ".join(parts)


def rescan_uncovered(cycle_run, record, comparison) -> Measured:
    """Rescan the areas not measured and the artefact spots while they alone make the cycle need review; the
    comparison to decide on.

    Parameters
    ----------
    cycle_run : mppf.loop.cycle._Run
        The loop's run (history, plate, press, settings, design, scanner, reporter, scan folder).
    record : CycleRecord
        The scanned cycle.
    comparison : Comparison
        Of its first scan.
    """
    run, settings, reporter = cycle_run, cycle_run.settings, cycle_run.reporter
    scans = [{"path": str(record.scan_path), "sha256": record.scan_sha256, "rescan": 0,
              "n_points": int(comparison.n_points), "merged": True}]
    job = load_cycle_job(record)
    for number in range(1, settings.rescans + 1):
        if not _rescannable(comparison.verdict):
            return Measured(comparison, scans)
        if run.known.get(UNANSWERED):
            reporter.info(f"cycle {record.cycle}: no rescan asked: the station did not answer a rescan request "
                          f"earlier in this run ({run.known[UNANSWERED]}); the cycle is decided on the scan taken")
            return Measured(comparison, scans)
        # 1. say what happens; ask the station for the areas and spots (request file, --on-pressed), take the rescan
        spots = _spots(comparison, job.tf_press_design)
        regions = [region_doc(g, comparison, job.tf_press_design) for g in comparison.coverage.regions]
        reporter.info(f"cycle {record.cycle}: {_asking(comparison, spots)}: asking for rescan {number} of "
                      f"{settings.rescans}")
        try:
            path = _take_rescan(run, record, job, number, regions + spots[:SPOTS_LISTED], scans, len(spots))
        except InputError as exc:  # no rescan came in the wait: decided on the scans taken, no more asked this run
            run.known[UNANSWERED] = f"cycle {record.cycle}, rescan {number}"
            reporter.info(f"cycle {record.cycle}: no rescan came ({exc.message}); the cycle is decided on the "
                          f"{len(scans)} scan(s) taken, and no further rescan is asked in this run (a station "
                          "that does not rescan: --rescans 0)")
            return Measured(comparison, scans)
        scan = {"path": str(path), "sha256": "", "rescan": number, "n_points": 0, "merged": False}
        scans.append(scan)
        # 2. the union of the scans so far, compared; merged only when the rescan agrees where they overlap
        union, reason = _union(run, record, scans, scan, path, comparison)
        if reason is None:
            agreement = overlap_agreement(union, sum(s["n_points"] for s in scans[:-1]))
            scan["agreement"] = agreement.to_dict()
            if not agreement.agrees:
                reason = (f"it disagrees with the earlier scans where they overlap ({agreement.describe()}): "
                          "the plate or the scanner moved between the scans")
        if reason is not None:
            stopped = f"rescan {number} ({Path(path).name}) not merged: {reason}; the cycle needs review"
            reporter.info(f"cycle {record.cycle}: {stopped}")
            return Measured(comparison, scans, stopped)
        scan["merged"] = True
        comparison = union
        merged = sum(1 for s in scans if s["merged"])
        reporter.info(f"cycle {record.cycle}: rescan {number} merged ({agreement.describe()}); the union of "
                      f"{merged} scans: {comparison.verdict.headline if comparison.verdict else ''}")
    if _rescannable(comparison.verdict) and settings.rescans:
        reporter.info(f"cycle {record.cycle}: {_still(comparison)} after {settings.rescans} rescan(s): "
                      "the cycle needs review")
    return Measured(comparison, scans)


def _still(comparison) -> str:
    """What the rescans left: set-aside points beyond the tolerance not re-measured, areas not measured."""
    points = sum(s["count"] for s in _spots(comparison, None))
    areas = len(comparison.coverage.regions) if comparison.coverage is not None else 0
    still = [f"{points} set-aside point(s) beyond the tolerance still not re-measured within it"] if points else []
    still += [f"{areas} area(s) still not measured"] if areas else []
    return " and ".join(still)


def _take_rescan(run, record, job, number: int, regions: list, scans: list, spots: int) -> Path:
    """The rescan file: the request posted, the file taken (never one taken before), the request withdrawn.

    Raises
    ------
    InputError
        No rescan came (the scanner's wait ended): the cycle stays "scanned", ``--resume`` asks again.
    """
    first = {"path": scans[0]["path"], "sha256": scans[0]["sha256"]}
    ask = RescanAsk(number, tuple(regions), first, spots)
    request = post_request(run.plate, record, job, run.settings, run.scan_folder, run.reporter, rescan=ask)
    try:
        context = scan_context(run.history, run.plate, record, run.press, run.reporter)
        taken = tuple(s["path"] for s in scans) + rescan_paths(run.history, run.plate.plate_id)
        context = dataclasses.replace(context, used_paths=context.used_paths + taken, regions=tuple(regions),
                                      wait_s=run.settings.rescan_timeout_s)
        path = Path(run.scanner.rescan(record.cycle, number, context)).resolve()
    finally:
        request.withdraw()
    return path


def _union(run, record, scans: list, scan: dict, path: Path, start_from):
    """The comparison of the union with the new rescan (its sha256 and count filled in), registered from
    ``start_from`` (the last comparison: the scans share its frame); (union, None) or (None, why not)."""
    try:
        points = read_points(path)
    except InputError as exc:
        return None, f"it cannot be read ({exc.message})"
    scan.update(sha256=points.sha256, n_points=int(points.points.shape[0]))
    try:
        union = compare_union(run.plate, record, run.design, run.settings, scans[1:], start_from)
    except (GeometryError, AmbiguousStart) as exc:
        return None, f"the union of the scans does not register onto the design ({exc.message})"
    return union, None


def _finite(value: float):
    return None if not np.isfinite(value) else float(value)
