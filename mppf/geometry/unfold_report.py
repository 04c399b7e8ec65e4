"""The report of an unfolding: strain per triangle and point, placement of the flat plate, warnings."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from mppf.core.errors import GeometryError
from mppf.core.polygon import convex_outline
from mppf.core.rigid import fit_rigid
from mppf.geometry.mesh import edge_lengths, signed_areas_2d, triangle_areas, triangles_in_own_plane

if TYPE_CHECKING:
    from mppf.geometry.frame import LocalFrame

STRAIN_LIMIT_PCT = 1.5
"""Default in-plane strain (percent) above which press forming needs a warning."""

DEVELOPABLE_PCT = 0.1
"""Maximum strain (percent) below which a plate counts as (practically) developable."""


@dataclass(frozen=True, eq=False)
class Unfolding:
    """The flat shape of a plate and the strain it costs.

    Attributes
    ----------
    flat : (n, 3) float, mm
        Flat points in the input order, z = 0; the minimum-area bounding rectangle is
        centred at the origin with its longer side along x.
    strain_pct : (n,) float, percent
        In-plane strain per point: area-weighted mean over the incident triangles of
        the largest principal strain magnitude ``max(|s1 - 1|, |s2 - 1|)``.
    triangle_strain_pct : (m, 2) float, percent
        Signed principal strains (smaller, larger) of each triangle (+ stretched,
        - compressed when the curved plate is laid flat).
    faces : (m, 3) int
        Triangles used, wound counter-clockwise seen from the design's +n side.
    rms_strain_pct, max_strain_pct : float
        RMS and maximum of ``strain_pct``.
    area_change_pct : float
        Flat area minus curved (triangulated) area, in percent of the curved area.
    outline_length_change_pct : float
        Flat outline length minus curved outline length, percent of the curved one.
    developable : bool
        ``max_strain_pct`` below :data:`DEVELOPABLE_PCT`.
    worst_point : int
        Index of the point with the largest strain.
    worst_uv_mm : (2,) float
        That point in the plate's own frame (u, v), mm from the centroid.
    worst_region : str
        Where it is, e.g. ``"the +u/-v corner"``.
    warnings : tuple of str
    frame : LocalFrame
        The plate's own frame (u, v, n) used.
    tf_flat_design : (4, 4) float
        Best rigid fit mapping design points onto the flat points (for orientation only;
        the flat plate is not a rigid image of the curved one).
    strain_limit_pct : float
    iterations : int
        Gauss-Newton steps taken.
    cost : float, mm^2
        Final ``0.5 * sum(residual^2)``.
    """

    flat: np.ndarray
    strain_pct: np.ndarray
    triangle_strain_pct: np.ndarray
    faces: np.ndarray
    rms_strain_pct: float
    max_strain_pct: float
    area_change_pct: float
    outline_length_change_pct: float
    developable: bool
    worst_point: int
    worst_uv_mm: np.ndarray
    worst_region: str
    frame: LocalFrame
    tf_flat_design: np.ndarray
    strain_limit_pct: float
    iterations: int
    cost: float
    warnings: tuple[str, ...] = field(default_factory=tuple)

    @property
    def n_points(self) -> int:
        """Number of points."""
        return int(self.flat.shape[0])

    def to_dict(self) -> dict:
        """The report as plain values (for JSON)."""
        return {
            "rms_strain_pct": self.rms_strain_pct,
            "max_strain_pct": self.max_strain_pct,
            "area_change_pct": self.area_change_pct,
            "outline_length_change_pct": self.outline_length_change_pct,
            "n_points": self.n_points,
            "n_triangles": int(self.faces.shape[0]),
            "developable": self.developable,
            "strain_limit_pct": self.strain_limit_pct,
            "worst_point": self.worst_point,
            "worst_uv_mm": self.worst_uv_mm.tolist(),
            "worst_region": self.worst_region,
            "flat_size_mm": np.ptp(self.flat[:, :2], axis=0).tolist(),
            "iterations": self.iterations,
            "cost_mm2": self.cost,
            "warnings": list(self.warnings),
        }


def principal_strains(pts: np.ndarray, tri: np.ndarray, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal stretches of each triangle's deformation gradient curved -> flat.

    Returns
    -------
    stretches : (m, 2) float
        Smaller and larger singular value of the 2x2 deformation gradient F.
    det : (m,) float
        det F (negative for a triangle flipped in the flat layout).
    """
    len12, x3, y3 = triangles_in_own_plane(pts, tri)
    f1, f2, f3 = flat[tri[:, 0]], flat[tri[:, 1]], flat[tri[:, 2]]
    # F @ [[len12, x3], [0, y3]] = [f2 - f1, f3 - f1]
    g1, g2 = f2 - f1, f3 - f1
    a = g1[:, 0] / len12
    c = g1[:, 1] / len12
    b = (g2[:, 0] - a * x3) / y3
    d = (g2[:, 1] - c * x3) / y3
    # singular values of [[a, b], [c, d]]
    s_sum = np.hypot(a + d, c - b)
    s_dif = np.hypot(a - d, c + b)
    stretches = np.column_stack([0.5 * np.abs(s_sum - s_dif), 0.5 * (s_sum + s_dif)])
    return stretches, a * d - b * c


def place_flat(flat: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Rotate and shift a flat layout: minimum-area rectangle centred, long side on x.

    Of the rotations that do so, the one closest to the design's (u, v) view is taken.
    """
    hull = convex_outline(flat) if flat.shape[0] > 3 else flat
    sides = np.roll(hull, -1, axis=0) - hull
    angles = np.arctan2(sides[:, 1], sides[:, 0])
    best = None
    for angle in angles:
        rot = _rotation(-angle)
        ext = np.ptp(hull @ rot.T, axis=0)
        if best is None or ext[0] * ext[1] < best[0] - 1e-9 * best[0]:
            best = (ext[0] * ext[1], -angle if ext[0] >= ext[1] else -angle + np.pi / 2)
    base = best[1]
    # rotation taking the (u, v) view onto the flat layout (2D Procrustes, no mirror)
    fc, uc = flat - flat.mean(axis=0), uv - uv.mean(axis=0)
    cross = np.sum(uc[:, 0] * fc[:, 1] - uc[:, 1] * fc[:, 0])
    dot = np.sum(uc * fc)
    view = np.arctan2(cross, dot)
    turn = min((base, base + np.pi), key=lambda t: abs(np.angle(np.exp(1j * (t + view)))))
    placed = flat @ _rotation(turn).T
    lo, hi = placed.min(axis=0), placed.max(axis=0)
    return placed - 0.5 * (lo + hi)


def _rotation(angle: float) -> np.ndarray:
    """(2, 2) rotation by ``angle`` rad."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def region_name(uv_mm: np.ndarray, point: int) -> str:
    """Name where ``point`` lies on the plate: a corner, an edge or the middle.

    The outer quarters of the (u, v) bounding box are the edges, where two meet a corner.

    Parameters
    ----------
    uv_mm : (n, 2) float
        The plate's points in its own frame.
    point : int

    Returns
    -------
    str
        e.g. ``"the +u/-v corner"``, ``"the -u edge"``, ``"the middle"``.
    """
    lo, hi = uv_mm.min(axis=0), uv_mm.max(axis=0)
    where = (uv_mm[point] - lo) / np.maximum(hi - lo, 1e-300)
    parts = []
    for name, t in zip("uv", where):
        if t < 0.25:
            parts.append(f"-{name}")
        elif t > 0.75:
            parts.append(f"+{name}")
    if len(parts) == 2:
        return f"the {parts[0]}/{parts[1]} corner"
    if parts:
        return f"the {parts[0]} edge"
    return "the middle"


@dataclass(frozen=True, eq=False)
class CurvedMesh:
    """The curved plate as it is unfolded: its points, triangles, own frame and edges.

    Attributes
    ----------
    points : (n, 3) float, mm
        The curved plate.
    faces : (m, 3) int
        Its triangles, counter-clockwise seen from +n.
    uv : (n, 2) float, mm
        The points in the plate's own frame.
    frame : LocalFrame
        That frame.
    edges : (k, 2) int
        The unique edges of ``faces``.
    boundary : (k,) bool
        Which edges are on the outline.
    lengths_mm : (k,) float
        The curved plate's edge lengths.
    """

    points: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    frame: LocalFrame
    edges: np.ndarray
    boundary: np.ndarray
    lengths_mm: np.ndarray


def report(curved: CurvedMesh, flat2: np.ndarray, *, strain_limit_pct: float, iterations: int,
           cost: float) -> Unfolding:
    """The :class:`Unfolding` of a solved flat layout: strains, area and outline changes, placement.

    Parameters
    ----------
    curved : CurvedMesh
        The curved plate, its triangles and edges.
    flat2 : (n, 2) float, mm
        The solved flat layout (any rigid placement).
    strain_limit_pct : float
        Strain (percent) above which the report warns.
    iterations : int
        Gauss-Newton steps the solve took.
    cost : float, mm^2
        Its final cost.

    Raises
    ------
    GeometryError
        The flat layout folds over (a mirrored triangle) or is not finite.
    """
    pts, tri, uv = curved.points, curved.faces, curved.uv
    stretches, det = principal_strains(pts, tri, flat2)
    _check_layout(flat2, det, uv, tri)
    # strain per triangle and per point
    principal = stretches - 1.0
    area = triangle_areas(pts, tri)
    strain_pct = _point_strain_pct(np.abs(principal).max(axis=1), area, tri, pts.shape[0])
    # area and outline
    flat_area, curved_area = float(np.sum(signed_areas_2d(flat2, tri))), float(np.sum(area))
    flat_outline = float(np.sum(edge_lengths(flat2, curved.edges[curved.boundary])))
    curved_outline = float(np.sum(curved.lengths_mm[curved.boundary]))
    # placement
    flat = np.column_stack([place_flat(flat2, uv), np.zeros(pts.shape[0])])
    worst = int(np.argmax(strain_pct))
    worst_uv = uv[worst] - uv.mean(axis=0)
    region, max_strain = region_name(uv, worst), float(strain_pct[worst])
    warnings = [] if max_strain <= strain_limit_pct else [
        _strain_warning(max_strain, strain_limit_pct, region, worst_uv, (worst, flat[worst]))]
    return Unfolding(
        flat=flat,
        strain_pct=strain_pct,
        triangle_strain_pct=100.0 * principal,
        faces=tri,
        rms_strain_pct=float(np.sqrt(np.mean(strain_pct ** 2))),
        max_strain_pct=max_strain,
        area_change_pct=100.0 * (flat_area - curved_area) / curved_area,
        outline_length_change_pct=100.0 * (flat_outline - curved_outline) / curved_outline,
        developable=bool(max_strain < DEVELOPABLE_PCT),
        worst_point=worst,
        worst_uv_mm=worst_uv,
        worst_region=region,
        frame=curved.frame,
        tf_flat_design=fit_rigid(pts, flat),
        strain_limit_pct=float(strain_limit_pct),
        iterations=iterations,
        cost=cost,
        warnings=tuple(warnings),
    )


def _check_layout(flat2: np.ndarray, det: np.ndarray, uv: np.ndarray, tri: np.ndarray) -> None:
    """Raise :class:`GeometryError` where the flat layout folds over (det F <= 0) or is not finite."""
    flipped = np.flatnonzero(det <= 0)
    if flipped.size:
        centre = uv[tri[flipped[0]]].mean(axis=0) / 1000.0
        raise GeometryError(
            f"the flattening folds over: {flipped.size} of {tri.shape[0]} triangles come out "
            f"mirrored, first near u={centre[0]:+.2f} m, v={centre[1]:+.2f} m in the plate frame",
            hint="check the design for spikes, overlaps or a badly wound mesh",
        )
    if not np.all(np.isfinite(flat2)):
        raise GeometryError("the flattening did not converge (non-finite coordinates)",
                            hint="check the design for duplicate or stray points")


def _point_strain_pct(magnitude: np.ndarray, area: np.ndarray, tri: np.ndarray, n_points: int) -> np.ndarray:
    """(n,) float, percent: the area-weighted mean strain magnitude ((m,) per triangle) of each point."""
    weight = np.bincount(tri.ravel(), weights=np.repeat(area, 3), minlength=n_points)
    per_point = np.bincount(tri.ravel(), weights=np.repeat(area * magnitude, 3), minlength=n_points) / weight
    return 100.0 * per_point


def _strain_warning(max_strain: float, strain_limit_pct: float, region: str, worst_uv: np.ndarray,
                    worst_flat: tuple[int, np.ndarray]) -> str:
    """The warning of a strain (percent) above the limit: where, in the plate frame and on the flat plate (mm)."""
    worst, flat_xyz = worst_flat
    return (
        f"in-plane strain {max_strain:.3g} % exceeds the limit {strain_limit_pct:g} % near {region} "
        f"(u={worst_uv[0] / 1000:+.2f} m, v={worst_uv[1] / 1000:+.2f} m in the plate frame, "
        f"x={flat_xyz[0] / 1000:+.2f} m, y={flat_xyz[1] / 1000:+.2f} m on the flat plate, point {worst}): "
        "press forming cannot take this without thinning or wrinkling; split the plate or add line heating"
    )
