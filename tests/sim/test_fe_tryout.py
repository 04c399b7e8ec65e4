"""``mppf tryout``: a job's first cycle predicted on the FE plate and compared with the design."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.cli import main
from mppf.geometry.write import write_points


def _bowl(folder):
    """A 1400 x 900 mm doubly curved plate, its flat and its first-cycle job (20 mm steel, springback)."""
    x, y = np.meshgrid(np.linspace(-700.0, 700.0, 36), np.linspace(-450.0, 450.0, 24))
    z = x ** 2 / (2 * 6000.0) + y ** 2 / (2 * 15000.0) + 1e-7 * x ** 3
    design = write_points(folder / "bowl.csv", np.column_stack([x.ravel(), y.ravel(), z.ravel()]))
    flat, job = folder / "bowl.flat.csv", folder / "bowl.job.json"
    assert main(["unfold", str(design), "-o", str(flat)]) == 0
    assert main(["plan", str(design), str(flat), "--thickness", "20", "--springback", "--material", "steel",
                 "-o", str(job)]) == 0
    return design, flat, job


def test_tryout_without_ccx_exits_2_with_how_to_install_it(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("MPPF_CCX", "ccx-that-is-not-installed")
    assert main(["tryout", str(tmp_path / "job.json"), "--design", "d.csv", "--flat", "f.csv"]) == 2
    assert "apt-get install calculix-ccx" in capsys.readouterr().err


@pytest.mark.slow
def test_tryout_predicts_the_first_cycle_and_writes_the_deviation_map_and_report(tmp_path, capsys):
    design, flat, job = _bowl(tmp_path)
    capsys.readouterr()
    out = tmp_path / "tryout"
    code = main(["tryout", str(job), "--design", str(design), "--flat", str(flat), "-o", str(out)])
    assert code in (0, 5, 6)  # in tolerance, out of it or for review: the prediction is what counts
    text = capsys.readouterr().out
    assert "FE plate: the first cycle's" in text and "form max" in text
    assert (out / "deviation.png").stat().st_size > 0 and (out / "report.html").stat().st_size > 0
    assert (out / "scan-cycle-01.ply").exists()
    assert text.count("ccx: press step ") == 2  # the job's two steps, one ccx run each
    # again into the same folder, the last step only: a new plate pressed, not the first try-out's taken up
    first = (out / "scan-cycle-01.ply").read_bytes()
    code = main(["tryout", str(job), "--design", str(design), "--flat", str(flat), "-o", str(out), "--steps", "last"])
    assert code in (0, 5, 6)
    again = capsys.readouterr().out
    assert again.count("ccx: press step 1 done") == 1 and "ccx: press step 2" not in again
    assert (out / "scan-cycle-01.ply").read_bytes() != first
