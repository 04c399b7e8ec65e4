"""The cutter's DXF of a plate planned in sections carries each section's placement marks."""

from __future__ import annotations

import numpy as np

from mppf.cli import main
from mppf.examples.analytic import cylinder_plate
from mppf.geometry.write import write_points
from mppf.planning.job import load_job


def test_the_flat_dxf_of_a_sectional_job_marks_every_section(tmp_path, capsys):
    import ezdxf

    from mppf.core.polygon import contains

    design_points, _ = cylinder_plate(5000.0, 2000.0, 15000.0, spacing_mm=150.0)  # longer than the 3.6 m bed
    design = write_points(tmp_path / "long.csv", design_points)
    flat, job_path, dxf = tmp_path / "flat.csv", tmp_path / "job.json", tmp_path / "flat.dxf"
    assert main(["unfold", str(design), "-o", str(flat)]) == 0
    assert main(["plan", str(design), str(flat), "--thickness", "20", "--steps", "2", "-o", str(job_path)]) == 0
    assert main(["unfold", str(design), "-o", str(dxf), "--job", str(job_path), "--json"]) == 0
    capsys.readouterr()
    job = load_job(job_path)
    assert len(job.sections) >= 2
    msp = ezdxf.readfile(dxf).modelspace()
    (cut,) = [np.array(e.get_points("xy")) for e in msp.query('LWPOLYLINE[layer=="CUT"]')]
    points = np.array([p.dxf.location for p in msp.query('POINT[layer=="MARK"]')])[:, :2]
    expected = {f"{s.index}{'ab'[k]}": s.marks_flat_mm[k, :2] for s in job.sections for k in range(2)}
    names = sorted(t.dxf.text for t in msp.query('TEXT[layer=="TEXT"]') if t.dxf.text in expected)
    assert names == sorted(expected)
    assert points.shape[0] == 1 + len(expected)  # the reference mark and the sections' marks
    for xy in expected.values():  # each section mark is drawn where the job puts it, on the plate
        assert np.min(np.linalg.norm(points - xy, axis=1)) < 1e-6
        assert contains(cut, xy[None])[0]
