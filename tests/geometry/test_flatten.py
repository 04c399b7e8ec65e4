"""The flattening energy of an unfolding: residuals and their analytic Jacobian (mppf.geometry.flatten)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay

from mppf.geometry.flatten import EdgeProblem
from mppf.geometry.mesh import triangle_areas, unique_edges


def test_energy_jacobian_matches_finite_differences_with_the_fold_guard_active():
    rng = np.random.default_rng(2)
    pts = np.column_stack([rng.uniform(0, 100, (12, 2)), rng.uniform(0, 5, 12)])
    tri = Delaunay(pts[:, :2]).simplices
    edges, _ = unique_edges(tri)
    lengths = np.linalg.norm(pts[edges[:, 0]] - pts[edges[:, 1]], axis=1)
    problem = EdgeProblem(edges, lengths, tri, triangle_areas(pts, tri), len(pts))
    z = (pts[:, :2] + rng.normal(0, 8.0, (12, 2))).ravel()  # squashes some triangles
    assert np.any(problem.residuals(z)[len(edges):] > 0)  # the guard acts somewhere
    numeric = np.empty((len(edges) + len(tri), z.size))
    for k in range(z.size):
        step = np.zeros_like(z)
        step[k] = 1e-6
        numeric[:, k] = (problem.residuals(z + step) - problem.residuals(z - step)) / 2e-6
    np.testing.assert_allclose(problem.jacobian(z).toarray(), numeric, atol=1e-5)
