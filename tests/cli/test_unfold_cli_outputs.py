"""``mppf unfold`` outputs: per-point strain in --json, pictures checked before any work."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mppf.cli import main
from mppf.geometry.read import read_points
from mppf.geometry.write import write_points


@pytest.fixture()
def sphere_cap(tmp_path):
    """A 2.4 x 1.6 m cap of a 4 m sphere, 25 x 17 points (about 0.6 % strain)."""
    u, v = np.meshgrid(np.linspace(-1200, 1200, 25), np.linspace(-800, 800, 17), indexing="ij")
    radius = 4000.0
    z = radius - np.sqrt(radius**2 - u**2 - v**2)
    return write_points(tmp_path / "cap.csv", np.column_stack([u.ravel(), v.ravel(), z.ravel()]))


def test_json_has_the_strain_of_every_point(sphere_cap, tmp_path, capsys):
    out = tmp_path / "flat.csv"
    assert main(["unfold", str(sphere_cap), "-o", str(out), "--json", "--strain-limit", "0.3"]) == 0
    report = json.loads(capsys.readouterr().out)
    strain = np.array(report["strain_pct"])
    assert strain.shape == (report["n_points"],) == (25 * 17,)
    assert strain.max() == pytest.approx(report["max_strain_pct"], abs=1e-5)
    assert np.sqrt(np.mean(strain**2)) == pytest.approx(report["rms_strain_pct"], abs=1e-5)
    assert int(np.argmax(strain)) == report["worst_point"]
    flat = read_points(out).points
    np.testing.assert_allclose(report["worst_flat_xy_mm"], flat[report["worst_point"], :2], atol=1e-6)
    # over the limit: one warning naming the region of the worst point, which is a corner of the cap
    assert report["max_strain_pct"] > 0.3
    assert len(report["warnings"]) == 1 and report["worst_region"] in report["warnings"][0]
    x_m, y_m = np.array(report["worst_flat_xy_mm"]) / 1000.0
    assert f"x={x_m:+.2f} m, y={y_m:+.2f} m on the flat plate" in report["warnings"][0]
    # the cap's strain is largest at its rim: the named region is an edge or corner, and the
    # worst point lies in the outer quarters of the plate in the named direction(s)
    design = read_points(sphere_cap).points
    worst = design[report["worst_point"]] / [1200.0, 800.0, 1.0]
    region = report["worst_region"]
    assert region.endswith(("edge", "corner"))
    if "u" in region:
        assert abs(worst[0]) > 0.5
    if "v" in region:
        assert abs(worst[1]) > 0.5


@pytest.mark.parametrize("plot_name, message", [("strain.xyz", "unknown picture type"),
                                                ("strain", "unknown picture type"),
                                                ("no/strain.png", "does not exist")])
def test_bad_picture_path_is_refused_before_any_file_is_written(sphere_cap, tmp_path, capsys, plot_name, message):
    out = tmp_path / "flat.csv"
    assert main(["unfold", str(sphere_cap), "-o", str(out), "--plot", str(tmp_path / plot_name)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "cannot write the strain picture" in err and message in err and "what to do:" in err
    assert not out.exists()


def test_failed_unfold_keeps_a_pre_existing_flat_file(tmp_path, capsys):
    design = write_points(tmp_path / "line.csv", [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0], [5.0, 5, 5]])
    out = tmp_path / "flat.csv"
    out.write_text("previous\n")
    assert main(["unfold", str(design), "-o", str(out)]) == 2
    assert "collinear" in capsys.readouterr().err
    assert out.read_text() == "previous\n"
