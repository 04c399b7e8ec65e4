"""Helpers of the CAD and scan tests (tests/geometry, tests/cli): the public hull models opened once
per test process, CAD files written by gmsh itself (an analytic B-spline plate, a box-bilge hull),
scans written by pye57 and laspy, and damaged copies of files."""

from __future__ import annotations

import atexit
from functools import cache
from math import comb
from pathlib import Path

import numpy as np

from mppf.geometry.files import quiet
from mppf.geometry.gmsh_gate import GmshModel

CAD_DIR = Path("/work/shared/data/cad")
KCS_IGES = CAD_DIR / "ship_kcs.igs"
KVLCC2_IGES = CAD_DIR / "ship_kvlcc2.igs"
KCS_SCALE = 31.6
"""The KCS model's scale (1:31.6); the bundled patches K1-K3 were cut from it and scaled by this."""

KVLCC2_SCALE = 58.0
"""The KVLCC2 model's scale (MOERI model 1:58: Lpp 320 m on a 5.52 m model)."""

PLATE_L_MM, PLATE_W_MM = 3000.0, 2000.0
TRIM_UV = [(0.0, 0.0), (1.0, 0.0), (1.0, 0.7), (0.7, 1.0), (0.0, 1.0)]
"""The analytic plate's trimming loop in its parameters (u = x / L, v = y / W): a cut corner."""


@cache
def cad_model(path: Path, scale: float):
    """A :class:`CadModel` opened once per test process (closed at exit)."""
    from mppf.geometry.cad import CadModel

    model = CadModel(path, scale=scale)
    atexit.register(model.close)
    return model


def plate_height(x, y):
    """The analytic plate z(x, y) (mm): a doubly curved quadratic, 3 x 2 m, about 55 mm deep."""
    return 2e-5 * (x - 1500.0) ** 2 - 1e-5 * (y - 1000.0) ** 2 + 3e-6 * (x - 1500.0) * (y - 1000.0)


def write_bspline_plate(path: Path) -> Path:
    """Write the analytic plate as one trimmed bicubic B-spline face, by gmsh (STEP or IGES by suffix).

    A quadratic is exactly a bicubic Bezier patch: its control net is the inverse Bernstein
    transform of the heights at u, v = 0, 1/3, 2/3, 1.
    """
    t = np.linspace(0.0, 1.0, 4)
    bernstein = np.array([[comb(3, k) * s**k * (1 - s) ** (3 - k) for k in range(4)] for s in t])
    inverse = np.linalg.inv(bernstein)
    x, y = np.meshgrid(PLATE_L_MM * t, PLATE_W_MM * t, indexing="ij")
    z = inverse @ plate_height(x, y) @ inverse.T
    with GmshModel() as model, model.use() as gmsh, quiet():
        occ = gmsh.model.occ
        control = [occ.addPoint(PLATE_L_MM * t[i], PLATE_W_MM * t[j], z[i, j]) for j in range(4) for i in range(4)]
        corners = [occ.addPoint(u, v, 0.0) for u, v in TRIM_UV]
        lines = [occ.addLine(corners[k], corners[(k + 1) % len(corners)]) for k in range(len(corners))]
        wire = occ.addWire(lines)
        occ.addBSplineSurface(control, 4, degreeU=3, degreeV=3, wireTags=[wire], wire3D=False)
        occ.remove([(1, line) for line in lines] + [(0, p) for p in corners + control])
        occ.synchronize()
        gmsh.write(str(path))
    return path


def trimmed_plate_area_mm2() -> float:
    """Area of the analytic plate inside its trim (adaptive quadrature over u, then v up to the cut)."""
    from scipy.integrate import dblquad

    def element(v, u):
        x, y = PLATE_L_MM * u, PLATE_W_MM * v
        zx = 4e-5 * (x - 1500.0) + 3e-6 * (y - 1000.0)
        zy = -2e-5 * (y - 1000.0) + 3e-6 * (x - 1500.0)
        return np.sqrt(1 + zx * zx + zy * zy) * PLATE_L_MM * PLATE_W_MM

    full, _ = dblquad(element, 0.0, 0.7, 0.0, 1.0, epsabs=1e-6)
    cut, _ = dblquad(element, 0.7, 1.0, 0.0, lambda u: 1.7 - u, epsabs=1e-6)
    return full + cut


BOX_HALF_BREADTH_MM, BOX_DEPTH_MM, BOX_BILGE_MM, BOX_LENGTH_MM = 10000.0, 12000.0, 3000.0, 20000.0


def write_box_hull(path: Path) -> Path:
    """A half hull of constant section, by gmsh: flat bottom, a circular bilge, a vertical side.

    Its girth from the keel is known exactly (:func:`box_hull_point`).
    """
    b, d, r = BOX_HALF_BREADTH_MM, BOX_DEPTH_MM, BOX_BILGE_MM
    with GmshModel() as model, model.use() as gmsh, quiet():
        occ = gmsh.model.occ
        keel, turn, centre = occ.addPoint(0, 0, 0), occ.addPoint(0, b - r, 0), occ.addPoint(0, b - r, r)
        side, deck = occ.addPoint(0, b, r), occ.addPoint(0, b, d)
        curves = [occ.addLine(keel, turn), occ.addCircleArc(turn, centre, side), occ.addLine(side, deck)]
        occ.extrude([(1, c) for c in curves], BOX_LENGTH_MM, 0, 0)
        occ.synchronize()
        gmsh.write(str(path))
    return path


def box_hull_point(girth_mm) -> np.ndarray:
    """(y, z) of the box hull's section at a girth from the keel, (n, 2) mm."""
    g = np.asarray(girth_mm, dtype=float)
    b, r = BOX_HALF_BREADTH_MM, BOX_BILGE_MM
    bottom, arc = b - r, 0.5 * np.pi * r
    angle = np.clip((g - bottom) / r, 0.0, 0.5 * np.pi)
    y = np.where(g <= bottom, g, np.where(g <= bottom + arc, bottom + r * np.sin(angle), b))
    z = np.where(g <= bottom, 0.0, np.where(g <= bottom + arc, r - r * np.cos(angle), r + g - bottom - arc))
    return np.column_stack([y, z])


def write_e57(path: Path, scans) -> Path:
    """An E57 file with one scan per ``(points_m, quaternion_wxyz, translation_m)``, by pye57."""
    import pye57

    with quiet(), pye57.E57(str(path), mode="w") as e57:
        for points, rotation, translation in scans:
            data = {f"cartesian{axis}": np.ascontiguousarray(points[:, k]) for k, axis in enumerate("XYZ")}
            e57.write_scan_raw(data, rotation=np.asarray(rotation, dtype=float),
                               translation=np.asarray(translation, dtype=float))
    return path


def write_las(path: Path, points, scale=(0.001, 0.001, 0.001), offset=(0.0, 0.0, 0.0)) -> Path:
    """A LAS or LAZ file (by suffix) of ``points`` with the given header scale and offset, by laspy."""
    import laspy

    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales, header.offsets = np.asarray(scale), np.asarray(offset)
    las = laspy.LasData(header)
    las.x, las.y, las.z = points[:, 0], points[:, 1], points[:, 2]
    las.write(str(path))
    return path


def truncated(source: Path, target: Path, fraction: float = 0.5) -> Path:
    """A copy of ``source`` cut off after ``fraction`` of its bytes."""
    data = source.read_bytes()
    target.write_bytes(data[: int(len(data) * fraction)])
    return target
