"""Unfold a curved plate into its flat shape, with the in-plane strain it costs.

The flat (developed) plate is what the cutting machine cuts and the press forms. The
method (see ``docs/unfold.md``):

1. find the plate's own frame (:func:`mppf.geometry.frame.fit_frame`) and refuse plates that
   fold over in it (:func:`mppf.geometry.frame.check_height_field`);
2. triangulate: the given mesh faces, or a Delaunay triangulation of the (u, v)
   projection with the sliver triangles of a non-convex outline removed;
3. start from the projection on the best-fit plane when it keeps every edge within
   1 % (a shallow plate), otherwise from the least-squares conformal map (LSCM, a
   sparse linear solve, exact up to scale for developable plates); both preserve
   orientation;
4. minimise ``sum_edges (|f_i - f_j| - L_ij)^2`` (L_ij the 3D edge lengths) by
   Gauss-Newton steps with the analytic sparse Jacobian and a sparse direct solve
   (scipy.sparse.linalg.splu), plus a fold guard that is zero unless a flat triangle
   shrinks below half its true area;
5. measure the strain of every triangle from its deformation gradient, and place the
   flat plate at z = 0, its minimum-area bounding rectangle centred at the origin,
   longer side along x, turned as close as possible to the design's (u, v) view.

The flat points keep the order and count of the input, so design and flat are a set of
known correspondences. Pure: arrays in, arrays out.
"""

from __future__ import annotations

from mppf.core.validate import check_positive
from mppf.geometry.check import check_plate
from mppf.geometry.flatten import EdgeProblem, solve, start_layout
from mppf.geometry.frame import check_height_field, fit_frame
from mppf.geometry.mesh import check_all_used, check_faces, edge_lengths, triangle_areas, triangulate, unique_edges, wind_ccw
from mppf.geometry.unfold_report import STRAIN_LIMIT_PCT, CurvedMesh, Unfolding, report


def unfold(points, faces=None, *, strain_limit_pct: float = STRAIN_LIMIT_PCT) -> Unfolding:
    """Flatten a curved plate with the least change of its edge lengths.

    Parameters
    ----------
    points : (n, 3) float, mm
        The curved plate in any coordinates (a grid, a point cloud or mesh vertices).
    faces : (m, 3) int, optional
        Mesh triangles; without them the (u, v) projection is triangulated.
    strain_limit_pct : float
        Strain (percent) above which the result carries a warning.

    Returns
    -------
    Unfolding

    Raises
    ------
    GeometryError
        Fewer than 3 non-collinear points, a plate that folds over in its own frame,
        points that belong to no triangle, a flattening that folds.
    InputError
        Bad ``faces`` or ``strain_limit_pct``.
    """
    pts = check_plate(points, 3, "the design")
    strain_limit_pct = check_positive("the strain limit", strain_limit_pct, unit="%", hint="give e.g. 1.5 (percent)")
    # 1. the plate's own frame; refuse plates that are not one layer in it
    frame = fit_frame(pts)
    tri = None if faces is None else check_faces(faces, pts.shape[0])
    check_height_field(frame, pts, tri)
    uv = frame.to_local(pts)[:, :2]
    # 2. triangles, wound counter-clockwise seen from +n
    tri = triangulate(uv, pts) if tri is None else wind_ccw(uv, tri)
    check_all_used(tri, pts.shape[0])
    edges, boundary = unique_edges(tri)
    lengths_mm = edge_lengths(pts, edges)
    # 3. start: the projection on the best-fit plane for a shallow plate, else the LSCM
    start = start_layout(pts, tri, uv, edges, lengths_mm)
    # 4. least-squares edge lengths, with a fold guard
    problem = EdgeProblem(edges, lengths_mm, tri, triangle_areas(pts, tri), pts.shape[0])
    flat2, iterations, cost = solve(start, problem)
    # 5. strain, placement, report
    curved = CurvedMesh(pts, tri, uv, frame, edges, boundary, lengths_mm)
    return report(curved, flat2, strain_limit_pct=strain_limit_pct, iterations=iterations, cost=cost)
