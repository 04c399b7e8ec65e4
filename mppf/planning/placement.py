"""Placement: the flat plate on the press bed, the design registered onto it, and the
vertical offset and small tilt that keep the punch travel smallest.

Press coordinates (see ``docs/press.md``): origin at the matrix centre, x along the
columns, z up; the flat plate's bottom skin lies at z = 0, so its mid-surface at
z = t/2. Point files hold the plate's mid-surface. See ``docs/planning.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, QhullError, cKDTree

from mppf.planning.contact import PlacedSurface, tip_heights
from mppf.core.errors import GeometryError, InputError, LimitError
from mppf.core.polygon import area, convex_outline
from mppf.geometry.frame import fit_frame
from mppf.planning.press import PressConfig
from mppf.core.progress import NULL_REPORTER
from mppf.registration.register import Registration, register_icp, register_paired
from mppf.core.transform import apply_tf, make_tf

FLATNESS_FRACTION = 0.01
"""A flat plate may deviate from its plane by at most this fraction of its size."""

MAX_FLAT_STRAIN_PCT = 1.0
"""95th percentile of the change of neighbour distances (percent) between the design and
its paired flat above which the flat is judged not to belong to the design."""

MAX_AREA_MISMATCH_PCT = 3.0
"""Largest difference (percent) of the areas of design and flat (unpaired flats)."""

MAX_TILT_DEG = 3.0
"""Largest tilt of the design against the bed that the stroke optimisation may choose."""

MIN_TILT_GAIN_MM = 1.0
"""A tilt is used only when it lowers the largest punch travel by at least this much."""


@dataclass(frozen=True, eq=False)
class FlatPlacement:
    """The flat plate lying on the bed.

    Attributes
    ----------
    tf_press_flat : (4, 4) float
        Maps the flat file's coordinates into press coordinates (mid-surface at z = t/2).
    flat_press_mm : (n, 3) float
        The flat's points in press coordinates.
    size_mm : (2,) float
        Extent of the flat along x and y.
    corners_mm : (4, 3) float
        The plate corners on the bed (bottom skin, z = 0), in the order
        (-x, -y), (+x, -y), (+x, +y), (-x, +y): where the operator puts the plate.
    """

    tf_press_flat: np.ndarray
    flat_press_mm: np.ndarray
    size_mm: np.ndarray
    corners_mm: np.ndarray


def place_flat(flat_points, press: PressConfig, thickness_mm: float) -> FlatPlacement:
    """Lay the flat plate on the bed: centred, longer side along x, bottom skin at z = 0.

    Parameters
    ----------
    flat_points : (n, 3) float, mm
        The flat plate's mid-surface in any coordinates.
    press : PressConfig
    thickness_mm : float

    Raises
    ------
    GeometryError
        The "flat" plate is not flat.
    LimitError
        The plate does not fit between the outermost punch axes.
    """
    frame = fit_frame(flat_points)
    local = frame.to_local(flat_points)
    size = float(np.ptp(local[:, :2], axis=0).max())
    bow = float(np.abs(local[:, 2]).max())
    if bow > FLATNESS_FRACTION * size:
        raise GeometryError(
            f"the flat plate is not flat: its points lie up to {bow:.1f} mm from their best plane "
            f"(allowed {FLATNESS_FRACTION * size:.1f} mm for a {size:.0f} mm plate)",
            hint="give the unfolded (flat) plate as the second file, e.g. from 'mppf unfold'",
        )
    # u (longest spread) along x, then centre the bounding box, mid-surface at t/2
    tf_press_local = make_tf(np.eye(3), [0.0, 0.0, thickness_mm / 2.0])
    if press.cols * press.pitch_x_mm < press.rows * press.pitch_y_mm:  # longer axis is y
        tf_press_local[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    tf_press_flat = tf_press_local @ frame.tf_local_world
    flat_press = apply_tf(tf_press_flat, flat_points)
    centre = (flat_press[:, :2].min(axis=0) + flat_press[:, :2].max(axis=0)) / 2.0
    tf_press_flat = make_tf(translation=[-centre[0], -centre[1], 0.0]) @ tf_press_flat
    flat_press = apply_tf(tf_press_flat, flat_points)
    extent = np.ptp(flat_press[:, :2], axis=0)
    bed = np.array(press.bed_size_mm)
    if np.any(extent > bed + 1e-6):
        raise LimitError(
            f"the plate ({extent[0]:.0f} x {extent[1]:.0f} mm) does not fit on the bed of "
            f"{press.name} ({bed[0]:.0f} x {bed[1]:.0f} mm between the outermost punch axes)",
            hint="split the plate or use a larger press",
        )
    half = extent / 2.0
    box = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * half
    _, nearest = cKDTree(flat_press[:, :2]).query(box)
    corners = np.column_stack([flat_press[nearest, :2], np.zeros(4)])
    return FlatPlacement(tf_press_flat, flat_press, extent, corners)


def neighbour_strain_pct(design_points, flat_points, k: int = 4) -> np.ndarray:
    """Relative change (percent) of the distances between paired neighbours.

    Parameters
    ----------
    design_points, flat_points : (n, 3) float, mm, same order

    Returns
    -------
    (n * k,) float
        ``100 * (|d_i - d_j| / |f_i - f_j| - 1)`` over the k nearest neighbours j of
        each flat point i.
    """
    flat = np.asarray(flat_points, dtype=float)
    design = np.asarray(design_points, dtype=float)
    dist, idx = cKDTree(flat).query(flat, k=k + 1)
    dist, idx = dist[:, 1:], idx[:, 1:]
    ok = dist > 0
    lengths = np.linalg.norm(design[idx] - design[:, None, :], axis=2)
    return 100.0 * (lengths[ok] / dist[ok] - 1.0)


def check_flat_belongs(design_points, flat_press_mm, paired: bool, design_area_mm2: float) -> dict:
    """Refuse a flat plate that is not the unfolding of the design.

    ``flat_press_mm`` is the flat lying on the bed (:class:`FlatPlacement`).

    Paired (same point count and order): the distances between neighbouring points
    must agree within ``MAX_FLAT_STRAIN_PCT`` (95th percentile). Unpaired: the plate
    areas must agree within ``MAX_AREA_MISMATCH_PCT``.

    Returns
    -------
    dict
        The measured figures (for the job's registration report).

    Raises
    ------
    GeometryError
    """
    flat_area = area(convex_outline(np.asarray(flat_press_mm)[:, :2], "the flat plate"))
    area_pct = 100.0 * (flat_area / design_area_mm2 - 1.0)
    report = {"paired": paired, "flat_area_m2": flat_area / 1e6, "design_area_m2": design_area_mm2 / 1e6,
              "area_mismatch_pct": area_pct}
    if paired:
        strain = np.abs(neighbour_strain_pct(design_points, flat_press_mm))
        p95 = float(np.percentile(strain, 95))
        report["neighbour_strain_p95_pct"] = p95
        if p95 > MAX_FLAT_STRAIN_PCT:
            raise GeometryError(
                f"the flat plate does not belong to the design: neighbouring points change their "
                f"distance by up to {p95:.2f} % (95th percentile) between flat and design, "
                f"allowed {MAX_FLAT_STRAIN_PCT} %",
                hint="give the unfolding of this design (mppf unfold DESIGN), in the same point order",
            )
    elif abs(area_pct) > MAX_AREA_MISMATCH_PCT:
        raise GeometryError(
            f"the flat plate does not belong to the design: its area {flat_area / 1e6:.3f} m2 differs "
            f"by {area_pct:+.1f} % from the design's {design_area_mm2 / 1e6:.3f} m2 "
            f"(allowed {MAX_AREA_MISMATCH_PCT} %)",
            hint="give the unfolding of this design (mppf unfold DESIGN)",
        )
    return report


def tilt_tf(slope_x: float, slope_y: float, centre_mm) -> np.ndarray:
    """Rotation about a horizontal axis through ``centre_mm`` that adds ``slope_x * x +
    slope_y * y`` to the heights of a horizontal surface (to first order).

    Returns
    -------
    (4, 4) float
    """
    theta_y = -np.arcsin(np.clip(slope_x, -1, 1))  # about y: z' = -x sin(theta_y) + ...
    theta_x = np.arcsin(np.clip(slope_y, -1, 1))   # about x: z' = y sin(theta_x) + ...
    cy, sy = np.cos(theta_y), np.sin(theta_y)
    cx, sx = np.cos(theta_x), np.sin(theta_x)
    rot_y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rot_x = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    centre = np.asarray(centre_mm, dtype=float)
    return make_tf(translation=centre) @ make_tf(rot_x @ rot_y) @ make_tf(translation=-centre)


def minimax_offset(dev_mm, x_mm, y_mm, low_mm, high_mm, *, max_slope: float):
    """Plane ``a x + b y + c`` added to all strokes that minimises the largest travel.

    Solves the linear programme: minimise s subject to
    ``-s <= dev_i + a x_i + b y_i + c <= s`` (travel of every active tip) and
    ``low_i <= dev_i + a x_i + b y_i + c <= high_i`` (stroke limits, expressed as
    travel), ``|a|, |b| <= max_slope``. With ``max_slope = 0`` (a pure offset) the
    answer is closed form: the mid-range offset, clamped to the limits.

    Parameters
    ----------
    dev_mm : (m,) float
        Travel of each active tip (height minus its flat-plate height), both matrices.
    x_mm, y_mm : (m,) float
        Punch axes.
    low_mm, high_mm : (m,) float
        Allowed travel range of each tip.
    max_slope : float
        0 for a pure vertical offset.

    Returns
    -------
    (a, b, c, s) : floats, or None when no plane keeps every stroke inside its limits.
    """
    if max_slope == 0.0:
        lo, hi = float(np.max(low_mm - dev_mm)), float(np.min(high_mm - dev_mm))
        if lo > hi + 1e-9:
            return None
        c = float(np.clip(-(dev_mm.max() + dev_mm.min()) / 2.0, lo, hi))
        return 0.0, 0.0, c, float(np.abs(dev_mm + c).max())
    # A plane's extremes over a point set are taken at its convex hull's vertices:
    # only those rows are needed (same limits within a group of rows).
    keep = _hull_rows(dev_mm, x_mm, y_mm, low_mm, high_mm)
    dev_mm, x_mm, y_mm, low_mm, high_mm = dev_mm[keep], x_mm[keep], y_mm[keep], low_mm[keep], high_mm[keep]
    ones = np.ones_like(dev_mm)
    zero = np.zeros_like(dev_mm)
    # x, y scaled to order 1 so the programme is well conditioned
    scale = max(float(np.abs(np.concatenate([x_mm, y_mm])).max()), 1.0)
    cols = np.column_stack([x_mm / scale, y_mm / scale, ones])
    # variables (a', b', c, s); rows: A z <= b_ub
    a_ub = np.vstack([
        np.column_stack([cols, -ones]),    # dev + plane <= s
        np.column_stack([-cols, -ones]),   # -(dev + plane) <= s
        np.column_stack([cols, zero]),     # dev + plane <= high
        np.column_stack([-cols, zero]),    # dev + plane >= low
    ])
    b_ub = np.concatenate([-dev_mm, dev_mm, high_mm - dev_mm, dev_mm - low_mm])
    bound = max_slope * scale
    bounds = [(-bound, bound), (-bound, bound), (None, None), (0, None)]
    res = linprog([0, 0, 0, 1], A_ub=a_ub, b_ub=b_ub, bounds=bounds, method="highs")
    if res.status != 0:
        return None
    a, b, c, s = res.x
    return a / scale, b / scale, c, s


def _hull_rows(dev_mm, x_mm, y_mm, low_mm, high_mm) -> np.ndarray:
    """Indices of the rows on the convex hull of (x, y, dev), per group of equal limits."""
    keep = []
    groups = np.unique(np.column_stack([low_mm, high_mm]), axis=0, return_inverse=True)[1].reshape(-1)
    for g in np.unique(groups):
        rows = np.flatnonzero(groups == g)
        try:
            hull = ConvexHull(np.column_stack([x_mm[rows], y_mm[rows], dev_mm[rows]]), qhull_options="QJ")
            keep.append(rows[hull.vertices])
        except (QhullError, ValueError):  # too few or degenerate points: keep them all
            keep.append(rows)
    return np.concatenate(keep)


def limit_violations(values_mm, low_mm, high_mm, labels) -> list[str]:
    """Human-readable list of values outside [low, high] (at most 10)."""
    bad = np.flatnonzero((values_mm < low_mm - 1e-6) | (values_mm > high_mm + 1e-6))
    return [f"{labels[i]} {values_mm[i]:.1f} mm (limits {low_mm[i]:.0f}..{high_mm[i]:.0f})" for i in bad[:10]]


def stroke_limit_error(what: str, items: list[str], total: int) -> LimitError:
    """The LimitError raised when strokes cannot be kept inside the press limits."""
    more = f" and {total - len(items)} more" if total > len(items) else ""
    return LimitError(
        f"{what}: {'; '.join(items)}{more}",
        hint="use a press with longer strokes, a thinner or flatter plate, or split the plate",
    )


def register_design(design_points, flat_press_mm, reporter=NULL_REPORTER) -> Registration:
    """Register the design onto the flat plate lying on the bed (gives ``tf_press_design``).

    Paired (closed form) when both have the same number of points, which the
    unfolding keeps in order; ICP point-to-point from the principal axes otherwise.

    Returns
    -------
    Registration
        ``tf`` maps design coordinates into press coordinates.
    """
    design = np.asarray(design_points, dtype=float)
    flat = np.asarray(flat_press_mm, dtype=float)
    if design.shape == flat.shape:
        return register_paired(design, flat)
    return register_icp(design, flat, method="point", init="principal", reporter=reporter)


def design_area_mm2(fitted, design_points, faces=None) -> float:
    """Surface area of the design: its triangles, or its outline in the plate plane
    times the mean slope factor sqrt(1 + zu^2 + zv^2) of the fitted surface."""
    pts = np.asarray(design_points, dtype=float)
    if faces is not None:
        tri = np.asarray(faces, dtype=np.int64)
        cross = np.cross(pts[tri[:, 1]] - pts[tri[:, 0]], pts[tri[:, 2]] - pts[tri[:, 0]])
        return float(0.5 * np.linalg.norm(cross, axis=1).sum())
    uv = fitted.frame.to_local(pts)[:, :2]
    _, zu, zv, *_ = fitted.surface.derivatives(uv[:, 0], uv[:, 1])
    return area(convex_outline(uv, "the design")) * float(np.mean(np.sqrt(1.0 + zu**2 + zv**2)))


@dataclass(frozen=True)
class Pose:
    """The design's final pose and its strokes.

    Attributes
    ----------
    tf_adjust : (4, 4) float
        Press -> press correction (tilt, then offset) applied after registration.
    tilt_x_deg, tilt_y_deg : float
        Rotation about press x and y through the plate centre.
    offset_mm : float
        Vertical shift of the design after the tilt.
    upper_mm, lower_mm : (m,) float
        Final tip heights of the active punches.
    exact : (m,) bool
        Newton contact converged for both punches of the pair.
    contact_xy_mm : (2m, 2) float
        Where the upper, then the lower balls touch the mid-surface, seen from above.
    travel_mm : float
        Largest |tip height - flat-plate tip height| over both matrices.
    """

    tf_adjust: np.ndarray
    tilt_x_deg: float
    tilt_y_deg: float
    offset_mm: float
    upper_mm: np.ndarray
    lower_mm: np.ndarray
    exact: np.ndarray
    contact_xy_mm: np.ndarray
    travel_mm: float


def _tips(placed: PlacedSurface, tf_adjust, x_mm, y_mm, press, thickness_mm):
    moved = PlacedSurface(placed.surface, tf_adjust @ placed.tf_press_local)
    up, lo = tip_heights(moved, x_mm, y_mm, tip_radius_mm=press.tip_radius_mm, thickness_mm=thickness_mm)
    return up.tip_mm, lo.tip_mm, (up.exact & lo.exact, np.vstack([up.contact_mm, lo.contact_mm]))


def optimise_pose(placed: PlacedSurface, x_mm, y_mm, labels, press: PressConfig, thickness_mm: float,
                  centre_mm) -> Pose:
    """Vertical offset and small tilt that keep strokes in limits with the least travel.

    The travel of an active tip is its height minus its flat-plate height (upper t,
    lower 0). A tilt adds, to first order, a plane ``a x + b y`` to every tip height
    and an offset a constant ``c``; the linear programme of :func:`minimax_offset`
    gives the plane that minimises the largest travel within the stroke limits. The
    tilt is applied as a true rotation and the contact re-solved (twice, which
    converges the linearisation); the final offset is exact, since a vertical shift
    moves every tip by the same amount. A tilt is kept only when it lowers the
    largest travel by ``MIN_TILT_GAIN_MM`` or more.

    Parameters
    ----------
    placed : PlacedSurface
        The design's mid-surface after registration.
    x_mm, y_mm : (m,) float
        Axes of the active punches.
    labels : list of str
        "[row,col]" of each active punch, for error messages.
    press : PressConfig
    thickness_mm : float
    centre_mm : (3,) float
        Centre of the tilt (the plate centre).

    Raises
    ------
    LimitError
        No offset and tilt keep every stroke inside the press limits.
    """
    x_mm = np.asarray(x_mm, dtype=float)
    y_mm = np.asarray(y_mm, dtype=float)
    up0, lo0 = thickness_mm, 0.0
    xx, yy = np.concatenate([x_mm, x_mm]), np.concatenate([y_mm, y_mm])
    m = len(x_mm)
    low = np.concatenate([np.full(m, press.upper.min_mm - up0), np.full(m, press.lower.min_mm - lo0)])
    high = np.concatenate([np.full(m, press.upper.max_mm - up0), np.full(m, press.lower.max_mm - lo0)])

    def travel(tf):
        up, lo, contact = _tips(placed, tf, x_mm, y_mm, press, thickness_mm)
        return np.concatenate([up - up0, lo - lo0]), contact

    tf = np.eye(4)
    dev, contact = travel(tf)
    level = minimax_offset(dev, xx, yy, low, high, max_slope=0.0)
    tilted = minimax_offset(dev, xx, yy, low, high, max_slope=np.tan(np.radians(MAX_TILT_DEG)))
    if tilted is None:
        c = -(dev.max() + dev.min()) / 2.0
        items = limit_violations(dev + c + np.concatenate([np.full(m, up0), np.full(m, lo0)]),
                                 low + np.concatenate([np.full(m, up0), np.full(m, lo0)]),
                                 high + np.concatenate([np.full(m, up0), np.full(m, lo0)]),
                                 [f"upper{lab}" for lab in labels] + [f"lower{lab}" for lab in labels])
        raise stroke_limit_error(
            f"the plate needs strokes beyond the press limits (range of travel {np.ptp(dev):.0f} mm) "
            f"even with the best offset and a tilt up to {MAX_TILT_DEG:g} deg", items,
            int(np.count_nonzero((dev + c < low) | (dev + c > high))))
    if level is None or level[3] - tilted[3] >= MIN_TILT_GAIN_MM:
        for _ in range(3):
            a, b = tilted[0], tilted[1]
            tf = tilt_tf(a, b, centre_mm) @ tf
            dev, contact = travel(tf)
            tilted = minimax_offset(dev, xx, yy, low, high, max_slope=np.tan(np.radians(MAX_TILT_DEG)))
            if tilted is None or max(abs(tilted[0]), abs(tilted[1])) < 1e-7:
                break
    final = minimax_offset(dev, xx, yy, low, high, max_slope=0.0)
    if final is None:  # cannot happen unless the tilt iteration went astray: fall back to level
        tf = np.eye(4)
        dev, contact = travel(tf)
        final = level
    offset = final[2]
    tf = make_tf(translation=[0.0, 0.0, offset]) @ tf
    dev = dev + offset
    rot = tf[:3, :3]
    return Pose(
        tf_adjust=tf,
        tilt_x_deg=float(np.degrees(np.arctan2(rot[2, 1], np.hypot(rot[2, 0], rot[2, 2])))),
        tilt_y_deg=float(np.degrees(np.arctan2(-rot[2, 0], rot[2, 2]))),
        offset_mm=float(offset),
        upper_mm=dev[:m] + up0,
        lower_mm=dev[m:] + lo0,
        exact=contact[0],
        contact_xy_mm=contact[1][:, :2],
        travel_mm=float(np.abs(dev).max()),
    )
