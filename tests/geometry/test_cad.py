"""Ship CAD in (mppf.geometry.cad, cad_mesh, cad_query, gmsh_gate): IGES and STEP read through gmsh.

The round trips go through gmsh itself: an analytic B-spline plate written to STEP and IGES by
gmsh and read back. The KCS check: every point of the bundled patches K1-K3 (cut from
ship_kcs.igs and scaled by 31.6) lies within 1 mm, at full scale, of the surface mppf reads.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest

from cad_helpers import (KCS_IGES, KCS_SCALE, PLATE_L_MM, PLATE_W_MM, cad_model, plate_height,
                         trimmed_plate_area_mm2, truncated, write_bspline_plate)
from mppf.core.errors import FileFormatError, InputError
from mppf.geometry import files
from mppf.geometry.cad import CadModel
from mppf.geometry.cad_mesh import MAX_TRIANGLES, tessellate
from mppf.geometry.cad_query import closest_points, intersect_lines
from mppf.geometry.read import read_points


@pytest.fixture(scope="session")
def kcs():
    """The KCS hull model at model scale (mm), read once per test process."""
    return cad_model(KCS_IGES, 1.0)


@pytest.fixture(scope="module", params=["step", "igs"])
def plate_file(request, tmp_path_factory):
    """The analytic plate written by gmsh as STEP, then as IGES."""
    return write_bspline_plate(tmp_path_factory.mktemp("cad") / f"plate.{request.param}")


@pytest.fixture(scope="module")
def step_plate(tmp_path_factory):
    """The analytic plate as STEP only (the tests that do not depend on the format)."""
    return write_bspline_plate(tmp_path_factory.mktemp("cad") / "plate.step")


def test_bspline_plate_round_trip_within_005_mm(plate_file):
    cloud = read_points(plate_file)
    x, y, z = cloud.points.T
    # every vertex on the analytic surface, and inside the trimmed face (a cut corner u + v <= 1.7)
    assert np.abs(z - plate_height(x, y)).max() < 0.05
    assert x.min() == pytest.approx(0.0, abs=1e-6) and x.max() == pytest.approx(PLATE_L_MM, abs=1e-6)
    assert np.all(x / PLATE_L_MM + y / PLATE_W_MM <= 1.7 + 1e-9)
    assert np.any(np.isclose(x / PLATE_L_MM + y / PLATE_W_MM, 1.7, atol=1e-6))  # the trim edge is meshed
    # the triangles: within the chordal tolerance (0.1 mm) of the surface, and its area
    corners = cloud.points[cloud.faces]
    centroid = corners.mean(axis=1)
    deviation = np.abs(centroid[:, 2] - plate_height(centroid[:, 0], centroid[:, 1]))
    assert 0.01 < deviation.max() < 0.1
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1).sum()
    assert area == pytest.approx(trimmed_plate_area_mm2(), rel=2e-6)
    assert len(cloud.sha256) == 64


def test_scale_and_tolerance_are_at_full_scale(step_plate):
    full = read_points(step_plate, chord_tolerance_mm=0.5)
    model = read_points(step_plate, scale=10.0, chord_tolerance_mm=0.5)
    assert np.ptp(model.points[:, 0]) == pytest.approx(10.0 * PLATE_L_MM, rel=1e-12)
    # the same 0.5 mm at full scale is 0.05 mm in the file: a finer mesh of the ten times larger plate
    assert model.points.shape[0] > 2 * full.points.shape[0]
    corners = model.points[model.faces] / 10.0
    centroid = corners.mean(axis=1)
    assert np.abs(centroid[:, 2] - plate_height(centroid[:, 0], centroid[:, 1])).max() < 0.05


def test_closest_points_are_exact_on_the_trimmed_face(plate_file):
    rng = np.random.default_rng(3)
    with CadModel(plate_file) as model:
        x, y = rng.uniform(100, 1900, 200), rng.uniform(100, 1100, 200)
        on = np.column_stack([x, y, plate_height(x, y)])
        normal = np.column_stack([-(4e-5 * (x - 1500) + 3e-6 * (y - 1000)),
                                  -(-2e-5 * (y - 1000) + 3e-6 * (x - 1500)), np.ones_like(x)])
        normal /= np.linalg.norm(normal, axis=1)[:, None]
        offset = rng.uniform(-30.0, 30.0, 200)
        hits = closest_points(model, on + offset[:, None] * normal)
        # a point beyond the cut corner: its foot on the untrimmed surface is outside the face
        beyond = closest_points(model, [[2900.0, 1900.0, plate_height(2900.0, 1900.0)]])
    assert hits.found.all()
    np.testing.assert_allclose(hits.distance_mm, np.abs(offset), atol=1e-6)
    np.testing.assert_allclose(hits.points_mm, on, atol=1e-6)
    assert not beyond.found[0] and beyond.distance_mm[0] < 1e-6


def test_seed_trees_are_built_once_per_model_and_direction(step_plate):
    with CadModel(step_plate) as model:
        assert model.seed_trees_xyz is None and model.seed_trees_along == {}
        first = closest_points(model, [[1000.0, 600.0, plate_height(1000.0, 600.0) + 5.0]])
        trees = model.seed_trees_xyz
        assert len(trees) == len(model.faces) and all(gap >= model.seed_spacing_mm for _, gap in trees)
        again = closest_points(model, [[1000.0, 600.0, plate_height(1000.0, 600.0) + 5.0]])
        assert model.seed_trees_xyz is trees  # the same trees, not built again
        origins = [[1000.0, 600.0, 500.0], [400.0, 300.0, 500.0]]
        down = intersect_lines(model, origins, [0.0, 0.0, -1.0])
        twice_as_long = intersect_lines(model, origins, [0.0, 0.0, -2.0])  # the same direction: one entry
        assert list(model.seed_trees_along) == [(0.0, 0.0, -1.0)]
        intersect_lines(model, origins, [0.0, 0.1, -1.0])
        assert len(model.seed_trees_along) == 2
    np.testing.assert_array_equal(first.points_mm, again.points_mm)
    np.testing.assert_array_equal(down.points_mm, twice_as_long.points_mm)
    np.testing.assert_allclose(down.points_mm[:, 2], plate_height(np.array([1000.0, 400.0]), np.array([600.0, 300.0])),
                               atol=1e-6)


@pytest.mark.parametrize("name", ["K1_midbody_bilge", "K2_fwd_bilge_convex", "K3_stern_saddle"])
def test_kcs_patches_lie_on_the_hull_within_1_mm(kcs, hull_dir, name):
    full_scale = read_points(hull_dir / f"{name}.csv").points
    hits = closest_points(kcs, full_scale / KCS_SCALE)
    assert hits.found.all()
    assert np.max(hits.distance_mm) * KCS_SCALE < 1.0  # measured: 0.041, 0.040, 0.049 mm


def test_kcs_model_faces_and_bounds(kcs):
    assert len(kcs.faces) == 18
    assert all(face.loops_uv is not None and face.seed_uv.shape[0] > 0 for face in kcs.faces)
    length = np.ptp(kcs.bounds_mm[:, 0]) * KCS_SCALE
    assert 235_000 < length < 250_000  # KCS: Lpp 230 m, LOA about 243 m
    assert kcs.bounds_mm[0, 1] > -1.0  # a half hull: port side only


def test_a_whole_hull_at_the_default_tolerance_is_refused(kcs):
    with pytest.raises(InputError, match="mppf extract") as info:
        tessellate(kcs, 0.1 / KCS_SCALE)
    assert f"more than {MAX_TRIANGLES:,}" in str(info.value) and "18 surfaces" in str(info.value)


def test_nothing_reaches_the_terminal(plate_file, capfd):
    with CadModel(plate_file) as model:
        tessellate(model, 0.2)
    read_points(plate_file)
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_two_threads_share_gmsh(step_plate):
    points = np.array([[1000.0, 500.0, 200.0], [2000.0, 800.0, -100.0]])
    expected = None
    with CadModel(step_plate) as model:
        expected = closest_points(model, points).distance_mm
    results, errors = [], []

    def work():
        try:
            with CadModel(step_plate) as model:
                for _ in range(5):
                    results.append(closest_points(model, points).distance_mm)
        except Exception as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [threading.Thread(target=work) for _ in range(3)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not errors and len(results) == 15
    for distance in results:
        np.testing.assert_allclose(distance, expected, atol=1e-9)


@pytest.mark.parametrize("suffix", [".igs", ".stp"])
def test_bad_cad_files(tmp_path, suffix):
    source = write_bspline_plate(tmp_path / f"good{suffix}")
    empty = tmp_path / f"empty{suffix}"
    empty.write_bytes(b"")
    text = tmp_path / f"points{suffix}"
    text.write_text("x,y,z\n1,2,3\n4,5,6\n")
    cut = truncated(source, tmp_path / f"cut{suffix}", 0.6)
    kind = "IGES" if suffix == ".igs" else "STEP"
    for path, message in ((empty, "file is empty"), (text, f"is not an {kind} file" if kind == "IGES"
                                                     else "is not a STEP file"), (cut, "is truncated"),
                          (tmp_path / f"missing{suffix}", "file not found")):
        with pytest.raises(FileFormatError, match=message) as info:
            read_points(path)
        assert str(path) in str(info.value) and info.value.hint


def test_iges_counts_that_do_not_match_are_damage(tmp_path):
    lines = KCS_IGES.read_text().splitlines(keepends=True)
    damaged = tmp_path / "damaged.igs"
    damaged.write_text("".join(lines[:1000] + lines[1060:]))  # 60 parameter records gone, the T record kept
    with pytest.raises(FileFormatError, match="declares 24250 P records, the file holds 24190"):
        CadModel(damaged)


def test_step_that_opencascade_cannot_read(tmp_path):
    bad = tmp_path / "bad.step"
    bad.write_text("ISO-10303-21;\nHEADER;\nthis is not STEP;\nENDSEC;\nEND-ISO-10303-21;\n")
    with pytest.raises(FileFormatError, match="OpenCASCADE cannot read it|holds no surfaces"):
        read_points(bad)


def test_a_cad_file_larger_than_memory_is_refused(step_plate, monkeypatch):
    monkeypatch.setattr(files, "available_bytes", lambda: 1000)
    with pytest.raises(FileFormatError, match="too large to read"):
        read_points(step_plate)
