"""Does the flat plate belong to the design? Neighbour strain (paired points) or areas (unpaired).

A flat plate that is not the unfolding of the design would be pressed into the wrong
shape without any error, so the planner refuses it before it solves a single contact.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from mppf.core.errors import GeometryError
from mppf.core.polygon import area, convex_outline

MAX_FLAT_STRAIN_PCT = 1.0
"""95th percentile of the change of neighbour distances (percent) between the design and
its paired flat above which the flat is judged not to belong to the design."""

MAX_AREA_MISMATCH_PCT = 3.0
"""Largest difference (percent) of the areas of design and flat (unpaired flats)."""


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
