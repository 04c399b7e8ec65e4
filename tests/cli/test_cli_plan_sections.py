"""``mppf plan`` on a plate larger than the bed: planned in sections, as ``mppf batch`` does."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mppf.cli import main
from mppf.examples import analytic
from mppf.planning.job import load_job

LONG = Path(analytic.__file__).parent / "long"


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    """The 7.5 x 2.4 m cylinder planned by the command, with its JSON summary."""
    folder = tmp_path_factory.mktemp("plan_sections")
    job_path = folder / "long.job.json"
    return job_path, folder


def test_a_plate_longer_than_the_bed_is_planned_in_sections(planned, capsys):
    job_path, _ = planned
    code = main(["plan", str(LONG / "long_cylinder_7500x2400_R20m.csv"),
                 str(LONG / "long_cylinder_7500x2400_R20m_flat.csv"), "--thickness", "20",
                 "-o", str(job_path), "--json"])
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    job = load_job(job_path)
    assert job.sections and len(job.sections) == len(summary["sections"]) >= 3
    # every section sits on the bed and its border with the earlier sections does not step
    for section in summary["sections"]:
        assert section["n_steps"] >= 1
        assert section["border_step_mm"] is None or section["border_step_mm"] <= 0.2
    # the sections walk the plate over the bed: their plate centres differ
    centres = {tuple(round(c) for c in s["plate_centre_mm"][:2]) for s in summary["sections"]}
    assert len(centres) == len(summary["sections"])


def test_a_press_too_small_for_the_plate_plans_it_in_sections_not_refuses_it(hull_dir, tmp_path, capsys):
    """Once refused with "does not fit on the bed": a 3 x 2 m hull plate on a press of 12 columns (1.8 m)."""
    from mppf.geometry.read import read_points
    from mppf.geometry.unfold import unfold
    from mppf.geometry.write import write_points
    from mppf.model.press import example_press_path

    design = hull_dir / "P2_bow_flare_smooth.csv"
    flat = write_points(tmp_path / "P2_flat.csv", unfold(read_points(design).points).flat)
    text = example_press_path().read_text()
    assert "cols = 24" in text
    press = tmp_path / "press.toml"
    press.write_text(text.replace("cols = 24", "cols = 12"))
    job_path = tmp_path / "job.json"
    code = main(["plan", str(design), str(flat), "--press", str(press), "--thickness", "20", "-o", str(job_path),
                 "--json"])
    assert code == 0, capsys.readouterr().err
    summary = json.loads(capsys.readouterr().out)
    assert len(summary["sections"]) >= 2 and len(load_job(job_path).sections) == len(summary["sections"])


@pytest.mark.parametrize("value", ["0", "-300", "nan"])
def test_a_bad_transition_width_exits_2_before_planning(planned, value, capsys):
    job_path, folder = planned
    out = folder / f"bad_{value}.job.json"
    code = main(["plan", str(LONG / "long_cylinder_7500x2400_R20m.csv"),
                 str(LONG / "long_cylinder_7500x2400_R20m_flat.csv"), "--thickness", "20",
                 "--transition", value, "-o", str(out)])
    assert code == 2
    err = capsys.readouterr().err
    assert "--transition" in err and value in err
    assert not out.exists()


def test_plan_prints_the_border_warnings_of_sections_that_step(tmp_path, capsys):
    """Sections that step at their borders are warned of, in the table output and in the JSON summary
    (docs/sections.md). A plate longer AND wider than the bed with springback (4.2 x 2.4 m cylinder, 2 x 2
    sections) no longer steps: every section presses the whole plate's one over-bent target, and nothing is
    printed. The 9.4 m KCS stern plate with springback still steps (its curvature varies strongly): warned."""
    from mppf.examples.analytic import cylinder_plate
    from mppf.geometry.read import read_points
    from mppf.geometry.unfold import unfold
    from mppf.geometry.write import write_points

    design, flat = cylinder_plate(4200.0, 2400.0, 20000.0, spacing_mm=200.0)
    design_path = write_points(tmp_path / "design.csv", design)
    flat_path = write_points(tmp_path / "flat.csv", flat)
    args = ["plan", str(design_path), str(flat_path), "--thickness", "20", "--springback", "--material", "steel",
            "-o", str(tmp_path / "job.json")]
    assert main(args) == 0
    assert not [line for line in capsys.readouterr().out.splitlines() if line.startswith("warning:")]
    assert main([*args, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["warnings"] == []
    kcs = LONG / "kcs_stern_bilge_9000x2400.csv"
    kcs_flat = write_points(tmp_path / "kcs_flat.csv", unfold(read_points(kcs).points).flat)
    args = ["plan", str(kcs), str(kcs_flat), "--thickness", "20", "--springback", "--material", "steel",
            "-o", str(tmp_path / "kcs.job.json")]
    assert main(args) == 0
    out = capsys.readouterr().out
    warned = [line for line in out.splitlines() if line.startswith("warning: section")]
    assert warned and all("--springback" in line and "mm at its border" in line for line in warned)
    assert main([*args, "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert warned == [f"warning: {w}" for w in summary["warnings"]]  # the same words, one line each
