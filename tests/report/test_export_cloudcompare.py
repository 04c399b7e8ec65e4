"""The per-point export cross-checked with CloudCompare: its scalar fields load, its cloud-to-mesh distances agree.

Slow: needs Debian's ``cloudcompare`` (``.ci/run`` installs it), run headless
(``QT_QPA_PLATFORM=offscreen CloudCompare -SILENT ...``).
"""

from __future__ import annotations

import os
import shutil
import subprocess

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

import scan_helpers as sh
from mppf.measure.compare import compare
from mppf.report.export import export_points

pytestmark = pytest.mark.slow

CLOUDCOMPARE = shutil.which("CloudCompare") or shutil.which("cloudcompare")


def _design_mesh(path, rows: int = 101, cols: int = 151):
    """The analytic design plate as a triangle mesh (20 mm grid) and its vertices; triangles turned later."""
    u, v = np.meshgrid(np.linspace(-1500, 1500, cols), np.linspace(-1000, 1000, rows))
    points = np.column_stack([u.ravel(), v.ravel(), sh.height(u, v).ravel()])
    idx = np.arange(rows * cols).reshape(rows, cols)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return points, faces


def _write_mesh(path, points, faces):
    vertex = np.array([tuple(p) for p in points], dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    face = np.array([(f,) for f in faces.tolist()], dtype=[("vertex_indices", "i4", (3,))])
    PlyData([PlyElement.describe(vertex, "vertex"), PlyElement.describe(face, "face")], text=False).write(str(path))


def _cloudcompare(*args, cwd):
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen")
    return subprocess.run([CLOUDCOMPARE, "-SILENT", "-AUTO_SAVE", "OFF", "-NO_TIMESTAMP", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=240)


@pytest.mark.skipif(CLOUDCOMPARE is None, reason="CloudCompare is not installed (Debian package cloudcompare)")
def test_cloudcompare_loads_the_scalar_fields_and_its_c2m_distances_agree(tmp_path):
    # a registered, bumped, noisy scan of the analytic plate, exported
    design, faces = _design_mesh(tmp_path / "mesh.ply")
    _, _, scan = sh.measured(n=20000, noise_mm=0.1, seed=3)
    c = compare(design, scan)
    export_points(c, tmp_path / "scan.ply")
    # the design mesh, its triangles turned so that their normals point to mppf's +deviation side
    up = c.design_frame.axes[2] * c.normal_sign
    if np.cross(design[faces[0, 1]] - design[faces[0, 0]], design[faces[0, 2]] - design[faces[0, 0]]) @ up < 0:
        faces = faces[:, ::-1]
    _write_mesh(tmp_path / "mesh.ply", design, faces)
    # CloudCompare: open the export (its scalar fields), signed cloud-to-mesh distances, save as text
    run = _cloudcompare("-O", "scan.ply", "-O", "mesh.ply", "-C2M_DIST", "-C_EXPORT_FMT", "ASC", "-ADD_HEADER",
                        "-PREC", "6", "-SAVE_CLOUDS", "FILE", "out.asc", cwd=tmp_path)
    assert run.returncode == 0, run.stdout + run.stderr
    text = (tmp_path / "out.asc").read_text()
    header = text.splitlines()[0].lstrip("/").split()
    for name in ("deviation", "form_deviation", "inlier", "set_aside", "outside", "margin"):
        assert name in header, header  # scalar_<name> loaded as the scalar field <name>
    distance_column = next(i for i, name in enumerate(header) if name.startswith("C2M"))
    table = np.loadtxt(tmp_path / "out.asc", comments="//")
    assert table.shape[0] == c.n_points
    inlier = table[:, header.index("inlier")] == 1
    ours = table[inlier, header.index("deviation")]
    theirs = table[inlier, distance_column]
    assert np.allclose(ours, c.deviation_mm[c.inlier], atol=1e-5)  # CloudCompare read our values back
    assert np.sqrt(np.mean((ours - theirs) ** 2)) < 0.05
    assert np.abs(ours).max() > 4.0  # the 5 mm bump is in both
