"""``mppf unfold`` outputs: per-point strain in --json, pictures checked before any work."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mppf.cli import main
from mppf.core.seal import load_key, seal_document
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


def test_flat_for_the_cutter_beside_the_flat_file(sphere_cap, tmp_path, capsys):
    import ezdxf

    from mppf.core.polygon import area, convex_outline, offset_convex, perimeter

    csv, dxf = tmp_path / "flat.csv", tmp_path / "flat.dxf"
    assert main(["unfold", str(sphere_cap), "-o", str(csv), "-o", str(dxf), "--margin", "80", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["outputs"] == [str(csv), str(dxf)] and report["output"] == str(csv)
    flat = read_points(csv).points
    doc = ezdxf.readfile(dxf)
    assert not doc.audit().has_errors and doc.header["$INSUNITS"] == 4
    (cut,) = [np.array(e.get_points("xy")) for e in doc.modelspace().query('LWPOLYLINE[layer=="CUT"]')]
    grown = offset_convex(convex_outline(flat[:, :2]), 80.0)
    assert area(cut) == pytest.approx(area(grown), rel=1e-9) and perimeter(cut) == pytest.approx(perimeter(grown))
    assert report["dxf"]["margin_mm"] == 80.0
    assert report["dxf"]["cut_area_mm2"] == pytest.approx(area(grown), rel=1e-9)
    np.testing.assert_allclose(report["dxf"]["reference_corner_mm"], cut[np.argmin(cut.sum(axis=1))])


def test_the_default_margin_is_the_example_press_margin(sphere_cap, tmp_path, capsys):
    from mppf.model.press import example_press_path, load_press

    assert main(["unfold", str(sphere_cap), "-o", str(tmp_path / "flat.dxf"), "--json"]) == 0
    margin = json.loads(capsys.readouterr().out)["dxf"]["margin_mm"]
    assert margin == load_press(example_press_path()).margin_mm == 100.0
    assert main(["unfold", str(sphere_cap), "-o", str(tmp_path / "flat.dxf"), "--margin", "-5"]) == 2
    assert "--margin" in capsys.readouterr().err


def test_a_job_of_another_design_is_refused(sphere_cap, tmp_path, capsys):
    job = {"format": "mppf-job", "version": 2}
    path = tmp_path / "job.json"
    path.write_text(json.dumps(job))
    assert main(["unfold", str(sphere_cap), "-o", str(tmp_path / "flat.dxf"), "--job", str(path)]) == 2
    assert "error:" in capsys.readouterr().err
    assert not (tmp_path / "flat.dxf").exists()


def test_a_job_marks_its_punch_centres_on_the_flat(sphere_cap, tmp_path, capsys):
    import ezdxf

    from mppf.core.polygon import contains
    from mppf.core.transform import apply_tf
    from mppf.model.job_parts import reference_corner_xy
    from mppf.planning.job import load_job

    flat, job_path, dxf = tmp_path / "flat.csv", tmp_path / "job.json", tmp_path / "flat.dxf"
    assert main(["unfold", str(sphere_cap), "-o", str(flat)]) == 0
    assert main(["plan", str(sphere_cap), str(flat), "--thickness", "20", "--margin", "60", "-o", str(job_path)]) == 0
    assert main(["unfold", str(sphere_cap), "-o", str(dxf), "--job", str(job_path), "--json"]) == 0
    capsys.readouterr()
    job = load_job(job_path)
    msp = ezdxf.readfile(dxf).modelspace()
    (cut,) = [np.array(e.get_points("xy")) for e in msp.query('LWPOLYLINE[layer=="CUT"]')]
    centres = np.array([c.dxf.center for c in msp.query('CIRCLE[layer=="PUNCH"]')])[:, :2]
    active = job.steps[-1].active
    assert centres.shape[0] == int(active.sum()) and np.all(contains(cut, centres))
    on_press = apply_tf(job.tf_press_flat, np.column_stack([centres, np.zeros(len(centres))]))[:, :2]
    x, y = np.meshgrid(job.punch_x_mm, job.punch_y_mm)
    np.testing.assert_allclose(on_press, np.column_stack([x[active], y[active]]), atol=1e-6)
    # the job's margin, and the mark on the corner that lies at the smallest x + y on that press
    from mppf.core.polygon import area, convex_outline, offset_convex

    assert area(cut) == pytest.approx(area(offset_convex(convex_outline(read_points(flat).points[:, :2]), 60.0)))
    (mark,) = msp.query('POINT[layer=="MARK"]')
    cut_on_press = apply_tf(job.tf_press_flat, np.column_stack([cut, np.zeros(len(cut))]))[:, :2]
    mark_on_press = apply_tf(job.tf_press_flat, np.r_[np.array(mark.dxf.location)[:2], 0.0][None])[0, :2]
    np.testing.assert_allclose(mark_on_press, reference_corner_xy(cut_on_press), atol=1e-6)
    assert job.layout.margin_mm == 60.0
    # a job of another design is refused, and nothing is written
    doc = json.loads(job_path.read_text())
    doc["inputs"]["design"]["sha256"] = "0" * 64
    other = tmp_path / "other.json"
    other.write_text(json.dumps(seal_document(doc, load_key(), sealed_by="a test")))  # sealed: the design is checked
    assert main(["unfold", str(sphere_cap), "-o", str(tmp_path / "x.dxf"), "--job", str(other)]) == 2
    assert "planned for another design" in " ".join(capsys.readouterr().err.split())
    assert not (tmp_path / "x.dxf").exists()
