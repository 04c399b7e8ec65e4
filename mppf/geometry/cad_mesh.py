"""Tessellation of a CAD model's trimmed faces at a chordal tolerance.

OpenCASCADE's mesher (BRepMesh, through gmsh's ``importStl``) triangulates every trimmed face
so that no point of a triangle lies further than the linear deflection from the surface:
the chordal tolerance. It is given in mm at full scale; in the file's units it is divided
by the model's ``scale``. Before meshing, the number of triangles is estimated from the
surfaces' curvature, and a tessellation beyond :data:`MAX_TRIANGLES` is refused with the
estimate (a whole hull at 0.1 mm is millions of triangles: cut the plate out first).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import InputError
from mppf.core.validate import check_positive
from mppf.geometry.cad import CadModel
from mppf.geometry.cad_files import CHORD_TOLERANCE_MM
from mppf.geometry.files import quiet

MAX_TRIANGLES = 1_000_000
"""Largest tessellation made (OpenCASCADE makes 10,000 to 20,000 triangles a second)."""

MESHER_FACTOR = 3.0
"""OpenCASCADE's triangles are about a third the size the chordal tolerance allows
(measured on the KCS hull at 0.003 to 1 mm: 3.0 to 3.2 times the ideal count)."""


@dataclass(frozen=True, eq=False)
class Tessellation:
    """Triangles of a CAD model's faces.

    Attributes
    ----------
    points : (n, 3) float, mm
    triangles : (m, 3) int
    face : (m,) int
        Index into ``model.faces`` of each triangle's face.
    chord_tolerance_mm : float
        The chordal tolerance it was made at (full scale).
    """

    points: np.ndarray
    triangles: np.ndarray
    face: np.ndarray
    chord_tolerance_mm: float


def estimate_triangles(model: CadModel, chord_tolerance_mm: float) -> int:
    """Triangles a tessellation at ``chord_tolerance_mm`` would have, from the seeds' curvature.

    A triangle of side h on a surface of largest curvature k strays about k h^2 / 8 from it,
    so a face of area A needs about A k / (4 tolerance) triangles (times :data:`MESHER_FACTOR`).
    """
    total = 0.0
    for face in model.faces:
        if face.seed_uv.shape[0] < 3:
            continue
        s_u, s_v, s_uu, s_vv, s_uv = model.derivatives(face, face.seed_uv)
        normal = np.cross(s_u, s_v)
        jacobian = np.linalg.norm(normal, axis=1)
        n = normal / np.maximum(jacobian, 1e-300)[:, None]
        e, f, g = (np.einsum("nd,nd->n", a, b) for a, b in ((s_u, s_u), (s_u, s_v), (s_v, s_v)))
        l, m, k = (np.einsum("nd,nd->n", a, n) for a in (s_uu, s_uv, s_vv))
        det = np.maximum(e * g - f * f, 1e-300)
        mean = (e * k - 2 * f * m + g * l) / (2 * det)
        gauss = (l * k - m * m) / det
        kappa = np.abs(mean) + np.sqrt(np.maximum(mean * mean - gauss, 0.0))
        total += float(np.sum(jacobian * face.seed_cell_uv * kappa)) / (4.0 * chord_tolerance_mm)
    return int(MESHER_FACTOR * total) + 2 * len(model.faces)


def tessellate(model: CadModel, chord_tolerance_mm: float = CHORD_TOLERANCE_MM) -> Tessellation:
    """Triangles of every trimmed face at a chordal tolerance (mm, full scale).

    Raises
    ------
    InputError
        A bad tolerance, or one so fine that the tessellation would exceed
        :data:`MAX_TRIANGLES` (the message gives the estimate and what to do).
    """
    chord = check_positive("the chordal tolerance", chord_tolerance_mm, unit="mm",
                           hint="give e.g. 0.1 (mm at full scale)")
    expected = estimate_triangles(model, chord)
    if expected > MAX_TRIANGLES:
        raise InputError(
            f"{model.path.name}: a tessellation at {chord:g} mm would have about {expected:,} triangles "
            f"(more than {MAX_TRIANGLES:,}; {len(model.faces)} surfaces, {model.size_text()})",
            hint="cut the plate out of the hull model with 'mppf extract' (docs/cad.md), "
                 "or give a coarser chordal tolerance")
    with model.gmsh() as gmsh, quiet():
        gmsh.option.setNumber("Mesh.StlLinearDeflection", chord / model.scale)
        gmsh.option.setNumber("Mesh.StlLinearDeflectionRelative", 0)
        gmsh.model.mesh.clear()
        gmsh.model.mesh.importStl()
        tags, coords, _ = gmsh.model.mesh.getNodes()
        pieces = [np.asarray(gmsh.model.mesh.getElementsByType(2, face.tag)[1], dtype=np.int64)
                  for face in model.faces]
        gmsh.model.mesh.clear()
    tags = np.asarray(tags, dtype=np.int64)
    index = np.zeros(int(tags.max()) + 1 if tags.size else 1, dtype=np.int64)
    index[tags] = np.arange(tags.size)
    triangles = index[np.concatenate(pieces)].reshape(-1, 3)
    face = np.repeat(np.arange(len(model.faces)), [p.size // 3 for p in pieces])
    return Tessellation(np.asarray(coords, dtype=float).reshape(-1, 3) * model.scale, triangles, face, chord)


def read_cad_mesh(path, *, scale: float = 1.0,
                  chord_tolerance_mm: float = CHORD_TOLERANCE_MM) -> tuple[np.ndarray, np.ndarray | None]:
    """Tessellate an IGES/STEP file: points (n, 3) mm, and triangles where they make one surface.

    Coincident vertices (on edges shared by faces) are merged. The triangles are returned
    for a single face or faces sewn into one piece; for faces that do not share their edges
    (an unsewn export) only the points, so that a plate is triangulated downstream in its
    own frame rather than unfolded with cracks.
    """
    with CadModel(path, scale=scale) as model:
        mesh = tessellate(model, chord_tolerance_mm)
        sewn = len(model.faces) == 1 or _sewn(model)
    points, triangles = _merge_coincident(mesh.points, mesh.triangles, 1e-6 * max(float(np.ptp(mesh.points)), 1.0))
    if sewn and _closed(triangles):
        from mppf.core.errors import FileFormatError

        raise FileFormatError(path, f"is a closed solid ({len(model.faces)} face(s) without a free edge: a box, a "
                                    "sphere or a whole body), not the open surface of one plate",
                              hint="export only the plate's face(s) (see docs/cad.md), or cut it out of the hull "
                                   "with 'mppf extract'")
    return points, (triangles if sewn else None)


def _closed(triangles: np.ndarray) -> bool:
    """Whether a triangle mesh has no free edge (every edge shared by two triangles): a closed surface."""
    if triangles.size == 0:
        return False
    edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return bool(np.all(counts >= 2))


def _sewn(model: CadModel) -> bool:
    """Whether the faces are connected through shared edges into one piece."""
    neighbours = {face.tag: set() for face in model.faces}
    with model.gmsh() as gmsh:
        for _, curve in gmsh.model.getEntities(1):
            faces = [int(t) for t in gmsh.model.getAdjacencies(1, curve)[0] if int(t) in neighbours]
            for a in faces:
                neighbours[a].update(faces)
    seen, todo = set(), [model.faces[0].tag]
    while todo:
        tag = todo.pop()
        if tag not in seen:
            seen.add(tag)
            todo.extend(neighbours[tag] - seen)
    return len(seen) == len(model.faces)


def _merge_coincident(points: np.ndarray, triangles: np.ndarray, tolerance: float):
    """Merge vertices closer than ``tolerance`` (first of each group kept); drop triangles that collapse."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    n = points.shape[0]
    pairs = cKDTree(points).query_pairs(tolerance, output_type="ndarray").reshape(-1, 2)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    _, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    tri = inverse[triangles]
    good = (tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])
    return points[first], tri[good]
