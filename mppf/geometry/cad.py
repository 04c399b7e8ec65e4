"""Ship CAD surfaces (IGES, STEP) read through gmsh's OpenCASCADE kernel.

A :class:`CadModel` is one CAD file open in gmsh (see :mod:`mppf.geometry.gmsh_gate`):
its trimmed faces, evaluated exactly (``getValue`` and derivatives, in bulk), with their
trimming loops in parameter space and a set of seed points per face for the queries of
:mod:`mppf.geometry.cad_query`. Lengths are millimetres at full scale: OpenCASCADE
converts the file's declared unit (IGES global section, STEP ``SI_UNIT``) to mm, and
``scale`` (31.6 for a 1:31.6 model) multiplies them.

Tessellation is :mod:`mppf.geometry.cad_mesh`; exact queries :mod:`mppf.geometry.cad_query`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import FileFormatError
from mppf.core.polygon import contains, distance_to_outline
from mppf.core.validate import check_positive
from mppf.geometry.cad_files import check_cad_file
from mppf.geometry.cad_trim import (INSIDE, LOOP_SIMPLIFY, UNDECIDED, TrimRaster, chain, sample_on_face, simplify,
                                     trim_raster)
from mppf.geometry.files import check_fits, check_readable, quiet
from mppf.geometry.gmsh_gate import GmshModel, last_error

SEED_DIVISIONS = 400
"""Seed points are laid about (model diagonal / this) apart, at most ``SEED_MAX`` per face side."""

SEED_MIN, SEED_MAX = 6, 160
FaceTrees = list[tuple[object, float]]
"""Per face: the k-d tree (``scipy.spatial.cKDTree``, None for a face without seeds) of its seed points in
some coordinates, and its largest seed gap (mm); built by :mod:`mppf.geometry.cad_query`."""
CAD_BYTES_PER_FILE_BYTE = 40
"""Memory OpenCASCADE takes per byte of an IGES/STEP file, roughly."""


@dataclass(frozen=True, eq=False)
class CadFace:
    """One trimmed face of a CAD model.

    Attributes
    ----------
    tag : int
        gmsh's surface tag.
    uv_low, uv_high : (2,) float
        Bounds of the (untrimmed) parameter domain.
    loops_uv : tuple of (k, 2) float, or None
        Trimming loops in parameter space (outer and holes; a point is on the face when it
        lies inside an odd number of them); None where they could not be mapped, then
        gmsh decides point by point.
    seed_uv : (m, 2) float
        Parameters of seed points on the trimmed face.
    seed_mm : (m, 3) float
        The seed points, mm.
    seed_cell_uv : float
        Parameter area of the grid cell each seed stands for.
    loop_band_uv : float
        How far (in parameters) the sampled loops may stray from the true trimming curves:
        points that near a loop are decided by gmsh exactly.
    raster : TrimRaster or None
        Where the face is, cell by cell (None without loops).
    """

    tag: int
    uv_low: np.ndarray
    uv_high: np.ndarray
    loops_uv: tuple | None
    seed_uv: np.ndarray
    seed_mm: np.ndarray
    seed_cell_uv: float = 0.0
    loop_band_uv: float = 0.0
    raster: TrimRaster | None = None


class CadModel:
    """A CAD file's trimmed surfaces, open in gmsh; lengths in mm at full scale.

    Parameters
    ----------
    path : str or Path
        An IGES (``.igs``, ``.iges``) or STEP (``.stp``, ``.step``) file.
    scale : float
        Model scale factor: coordinates are multiplied by it (31.6 for a 1:31.6 model).

    Raises
    ------
    FileFormatError
        Missing, empty, truncated or damaged file, content that is not what the suffix says,
        a file OpenCASCADE cannot read, or one without surfaces.
    """

    def __init__(self, path, *, scale: float = 1.0):
        self.path = check_readable(path, "an IGES or STEP file")
        self.scale = check_positive("the model scale", scale, hint="give e.g. --scale 31.6 for a 1:31.6 model")
        check_fits(self.path, CAD_BYTES_PER_FILE_BYTE * self.path.stat().st_size,
                   f"its {self.path.stat().st_size:,} bytes of CAD data")
        check_cad_file(self.path)
        self.seed_trees_xyz: FaceTrees | None = None
        """The faces' seed trees in 3-D (mm), built by the first query that needs them (:mod:`.cad_query`)."""
        self.seed_trees_along: dict[tuple[float, float, float], FaceTrees] = {}
        """The faces' seed trees in the plane normal to a line direction, by that unit direction (rounded to 1e-12)."""
        self._gmsh = GmshModel()
        try:
            tags = self._import()
            self.bounds_mm = self._bounds()
            self._seed_spacing_mm = float(np.linalg.norm(np.ptp(self.bounds_mm, axis=0))) / SEED_DIVISIONS
            self.faces = tuple(self._face(tag) for tag in tags)
        except BaseException:
            self.close()
            raise

    @property
    def seed_spacing_mm(self) -> float:
        """Intended distance between neighbouring seed points (mm)."""
        return self._seed_spacing_mm

    # ------------------------------------------------------------------ reading

    def _import(self) -> list[int]:
        """Import the file's shapes; the surface tags (every face, also of solids)."""
        with self._gmsh.use() as gmsh, quiet() as printed:
            gmsh.option.setNumber("Geometry.OCCSewFaces", 1)
            try:
                gmsh.model.occ.importShapes(str(self.path), highestDimOnly=False)
                gmsh.model.occ.synchronize()
            except Exception:  # gmsh raises a bare Exception with its last error
                reason = last_error()
            else:
                reason = None
            tags = [tag for _, tag in gmsh.model.getEntities(2)]
        if reason is not None:
            said = " ".join(printed[0].split())[:300] if printed and printed[0].strip() else reason
            raise FileFormatError(self.path, f"OpenCASCADE cannot read it: {said}",
                                  hint="check that the file is a complete IGES/STEP export of surfaces")
        if not tags:
            raise FileFormatError(self.path, "holds no surfaces (only points, curves or nothing OpenCASCADE reads)",
                                  hint="export the hull or plate as surfaces (IGES 128/143/144, STEP faces)")
        return tags

    def _bounds(self) -> np.ndarray:
        """(2, 3) lower and upper corner of the model's bounding box, mm."""
        with self._gmsh.use() as gmsh:
            box = np.asarray(gmsh.model.getBoundingBox(-1, -1), dtype=float) * self.scale
        return box.reshape(2, 3)

    def _face(self, tag: int) -> CadFace:
        """Parameter bounds, trimming loops and seed points of one face."""
        with self._gmsh.use() as gmsh:
            low, high = (np.asarray(b, dtype=float) for b in gmsh.model.getParametrizationBounds(2, tag))
        loops, band = self._loops(tag)
        raster = None if loops is None else trim_raster(loops, low, high, band)
        face = CadFace(tag, low, high, loops, np.empty((0, 2)), np.empty((0, 3)), 0.0, band, raster)
        n_u, n_v = self._seed_counts(face)
        uv = _grid(low, high, n_u, n_v)
        uv = uv[self.inside(face, uv, exact=False)]
        cell = float(np.prod(high - low)) / ((n_u - 1) * (n_v - 1))
        return CadFace(tag, low, high, loops, uv, self.evaluate(face, uv), cell, band, raster)

    def _loops(self, tag: int) -> tuple[tuple | None, float]:
        """The face's trimming loops in its parameter space and their band (None, 0 when unmappable).

        Each curve is sampled at ``2 n - 1`` parameters: the even samples make the loop (straight
        runs thinned), the odd ones measure how far its chords stray from the curve (the band).
        """
        loops, band = [], 0.0
        with self._gmsh.use() as gmsh:
            low, high = gmsh.model.getParametrizationBounds(2, tag)
            tolerance = LOOP_SIMPLIFY * float(np.max(np.asarray(high) - np.asarray(low)))
            try:
                for curves in gmsh.model.occ.getCurveLoops(tag)[1]:
                    sampled = [sample_on_face(gmsh, abs(int(curve)), tag, tolerance) for curve in curves]
                    loops.append(chain([simplify(polyline, tolerance) for polyline, _ in sampled]))
                    band = max([band, tolerance] + [sagitta for _, sagitta in sampled])
            except Exception:  # noqa: BLE001 - an unmappable curve: gmsh decides per point instead
                last_error()
                return None, 0.0
        if not loops or any(loop is None for loop in loops):
            return None, 0.0
        span = float(np.max(np.ptp(np.vstack(loops), axis=0)))
        return tuple(loops), 2.0 * band + 1e-9 * span

    def _seed_counts(self, face: CadFace) -> tuple[int, int]:
        """Grid sizes along u and v that lay seeds about ``_seed_spacing_mm`` apart on the surface."""
        probe = _grid(face.uv_low, face.uv_high, 9, 9)
        xyz = self.evaluate(face, probe).reshape(9, 9, 3)
        length_u = np.linalg.norm(np.diff(xyz, axis=0), axis=2).sum(axis=0).max()
        length_v = np.linalg.norm(np.diff(xyz, axis=1), axis=2).sum(axis=1).max()
        spacing = max(self._seed_spacing_mm, 1e-12)
        n_u, n_v = (int(np.clip(np.ceil(n / spacing), SEED_MIN, SEED_MAX)) for n in (length_u, length_v))
        return n_u, n_v

    # ------------------------------------------------------------------ evaluation

    def evaluate(self, face: CadFace, uv) -> np.ndarray:
        """Surface points (n, 3) mm at parameters ``uv`` (n, 2) of ``face``."""
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        if uv.shape[0] == 0:
            return np.empty((0, 3))
        with self._gmsh.use() as gmsh:
            xyz = gmsh.model.getValue(2, face.tag, uv.ravel())
        return np.asarray(xyz, dtype=float).reshape(-1, 3) * self.scale

    def derivatives(self, face: CadFace, uv) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """First and second derivatives at ``uv`` (n, 2): ``s_u, s_v, s_uu, s_vv, s_uv``, each (n, 3) mm."""
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        with self._gmsh.use() as gmsh:
            first = np.asarray(gmsh.model.getDerivative(2, face.tag, uv.ravel()), dtype=float).reshape(-1, 2, 3)
            second = np.asarray(gmsh.model.getSecondDerivative(2, face.tag, uv.ravel()), dtype=float).reshape(-1, 3, 3)
        first, second = first * self.scale, second * self.scale
        return first[:, 0], first[:, 1], second[:, 0], second[:, 1], second[:, 2]

    def inside(self, face: CadFace, uv, *, exact: bool = True) -> np.ndarray:
        """Which parameters ``uv`` (n, 2) lie on the trimmed face, (n,) bool.

        The sampled loops decide; points within the loops' band are decided by OpenCASCADE
        (``exact``), or counted in (not ``exact``: a generous answer, enough for seed points).
        """
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        if face.loops_uv is None:
            return self._inside_exact(face, uv) if exact else np.ones(uv.shape[0], dtype=bool)
        state = face.raster.lookup(uv)
        flags = state == INSIDE
        rows = np.flatnonzero(state == UNDECIDED)  # near a loop: the loops, then OpenCASCADE in the band
        if rows.size:
            flags[rows] = self._inside_loops(face, uv[rows], exact)
        return flags

    def _inside_loops(self, face: CadFace, uv: np.ndarray, exact: bool) -> np.ndarray:
        flags = np.zeros(uv.shape[0], dtype=bool)
        near = np.zeros(uv.shape[0], dtype=bool)
        for loop in face.loops_uv:
            flags ^= contains(loop, uv)
        ask = np.flatnonzero(~flags) if not exact else np.arange(uv.shape[0])  # generous: only outside ones
        for loop in face.loops_uv:
            for block in range(0, ask.size, 2048):  # bounded memory: (points x segments) per block
                rows = ask[block:block + 2048]
                near[rows] |= distance_to_outline(loop, uv[rows]) < face.loop_band_uv
        if near.any():
            flags[near] = self._inside_exact(face, uv[near]) if exact else True
        return flags

    def _inside_exact(self, face: CadFace, uv: np.ndarray) -> np.ndarray:
        """gmsh's (OpenCASCADE's) own classification, point by point (slow: for few points)."""
        with self._gmsh.use() as gmsh:
            return np.array([gmsh.model.isInside(2, face.tag, list(q), parametric=True) > 0 for q in uv], dtype=bool)

    def size_text(self) -> str:
        """The model's extent, e.g. ``"243.0 x 16.1 x 15.0 m"``."""
        extent = np.ptp(self.bounds_mm, axis=0) / 1000.0
        return f"{extent[0]:.1f} x {extent[1]:.1f} x {extent[2]:.1f} m"

    # ------------------------------------------------------------------ lifetime

    def gmsh(self):
        """Context: the ``gmsh`` module with this model current, under the process-wide lock."""
        return self._gmsh.use()

    def close(self) -> None:
        """Release the gmsh model (safe to call twice)."""
        gate = getattr(self, "_gmsh", None)
        if gate is not None:
            gate.close()

    def __enter__(self) -> CadModel:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _grid(low, high, n_u: int, n_v: int) -> np.ndarray:
    """(n_u * n_v, 2) parameters of a regular grid over [low, high], u slowest."""
    u, v = np.meshgrid(np.linspace(low[0], high[0], n_u), np.linspace(low[1], high[1], n_v), indexing="ij")
    return np.column_stack([u.ravel(), v.ravel()])


