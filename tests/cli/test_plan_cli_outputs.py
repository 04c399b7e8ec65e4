"""``mppf plan`` outputs: the job file's contents, the hashes of the inputs, step counts,
the ICP path, and that no job file (new or pre-existing) is touched when the command fails."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from mppf.cli import main
from mppf.geometry.write import write_points
from mppf.model.press import example_press_path, load_press
from plan_helpers import cylinder_points, developed_cylinder

PRESS = load_press(example_press_path())
RADIUS = 2500.0


@pytest.fixture(scope="module")
def cylinder_files(tmp_path_factory):
    """A cylinder plate (axis along x), its development (paired) and a coarser development."""
    folder = tmp_path_factory.mktemp("plan_out")
    design = write_points(folder / "design.csv", cylinder_points(RADIUS, 2800.0, 1500.0))
    flat = write_points(folder / "flat.csv", developed_cylinder(RADIUS, 2800.0, 1500.0))
    coarse = write_points(folder / "flat_coarse.csv", developed_cylinder(RADIUS, 2800.0, 1500.0, n_u=33, n_v=23))
    return design, flat, coarse


def _sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_job_file_holds_everything_the_issue_lists(cylinder_files, tmp_path, capsys):
    design, flat, _ = cylinder_files
    job_path = tmp_path / "job.json"
    assert main(["plan", str(design), str(flat), "--thickness", "16", "-o", str(job_path), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    doc = json.loads(job_path.read_text())
    assert doc["format"] == "mppf-job" and doc["version"] == 5 and doc["seal"]["algorithm"] == "HMAC-SHA256"
    assert doc["press"] == PRESS.to_dict()
    for key in ("tf_press_design", "tf_press_flat"):
        tf = np.array(doc[key])
        assert tf.shape == (4, 4) and tf[3].tolist() == [0.0, 0.0, 0.0, 1.0]
        np.testing.assert_allclose(tf[:3, :3] @ tf[:3, :3].T, np.eye(3), atol=1e-9)
    # the flat file's points lie on the bed: bottom skin at z = 0, mid-surface at t/2
    np.testing.assert_allclose(np.array(doc["tf_press_flat"])[2, 3], 8.0, atol=1e-6)
    assert doc["punch_x_mm"] == PRESS.punch_x_mm.tolist() and doc["punch_y_mm"] == PRESS.punch_y_mm.tolist()
    assert len(doc["steps"]) == doc["n_steps"] == summary["n_steps"] >= 1
    for step in doc["steps"]:
        active = np.array(step["active"])
        assert active.shape == PRESS.shape and 0 < active.sum() < active.size
        for key in ("upper_mm", "lower_mm"):
            grid = step[key]
            assert len(grid) == PRESS.rows and all(len(row) == PRESS.cols for row in grid)
            values = np.array([[np.nan if v is None else v for v in row] for row in grid])
            assert np.array_equal(np.isnan(values), ~active)
    assert doc["registration"]["method"] == "paired"
    assert doc["validation"]["passed"] is True
    assert doc["validation"]["min_gap_mm"] >= 16.0 - 0.01
    assert doc["inputs"]["design"]["sha256"] == _sha(design)
    assert doc["inputs"]["flat"]["sha256"] == _sha(flat)
    assert doc["inputs"]["press"]["sha256"] == _sha(example_press_path())
    assert summary["job"]["sha256"] == hashlib.sha256(job_path.read_bytes()).hexdigest()


def test_given_and_automatic_step_counts(cylinder_files, tmp_path, capsys):
    design, flat, _ = cylinder_files
    text = example_press_path().read_text().replace("max_neighbour_diff_mm = 30.0", "max_neighbour_diff_mm = 2.0")
    press = tmp_path / "press.toml"
    press.write_text(text)
    assert main(["plan", str(design), str(flat), "--thickness", "16", "--press", str(press), "--json"]) == 0
    auto = json.loads(capsys.readouterr().out)
    assert auto["n_steps"] >= 2
    assert auto["max_neighbour_step_mm"] <= 2.0 + 1e-6
    assert auto["max_neighbour_step_mm"] * auto["n_steps"] > 2.0 * (auto["n_steps"] - 1)  # the fewest steps
    job_path = tmp_path / "job.json"
    n = auto["n_steps"] + 3
    assert main(["plan", str(design), str(flat), "--thickness", "16", "--press", str(press), "--steps", str(n),
                 "-o", str(job_path), "--json"]) == 0
    capsys.readouterr()
    steps = json.loads(job_path.read_text())["steps"]
    assert [s["index"] for s in steps] == list(range(1, n + 1))
    upper = np.array([[[np.nan if v is None else v for v in row] for row in s["upper_mm"]] for s in steps])
    act = np.array(steps[-1]["active"])
    moves = np.diff(np.concatenate([np.full((1, *PRESS.shape), 16.0), upper]), axis=0)[:, act]
    # monotonic: every punch moves the same way in every step, in equal parts
    np.testing.assert_allclose(moves, np.broadcast_to(moves[-1], moves.shape), atol=2e-4)


def test_flat_with_another_point_count_uses_icp(cylinder_files, capsys):
    design, flat, coarse = cylinder_files
    assert main(["plan", str(design), str(flat), "--thickness", "16", "--json"]) == 0
    paired = json.loads(capsys.readouterr().out)
    assert main(["plan", str(design), str(coarse), "--thickness", "16", "--json"]) == 0
    icp = json.loads(capsys.readouterr().out)
    assert paired["registration"]["method"] == "paired" and icp["registration"]["method"] == "point"
    # the same plate: the same largest travel and stroke ranges
    assert icp["max_travel_mm"] == pytest.approx(paired["max_travel_mm"], abs=0.05)
    for side in ("upper", "lower"):
        assert icp[side]["active"] == paired[side]["active"]
        assert icp[side]["max_mm"] - icp[side]["min_mm"] == pytest.approx(
            paired[side]["max_mm"] - paired[side]["min_mm"], abs=0.05)


@pytest.mark.parametrize(
    "args, replace, message",
    [
        (["--thickness", "0"], None, "the plate thickness must be above 0 mm, got 0.0"),
        (["--thickness", "nan"], None, "got nan"),
        (["--thickness", "16"], ("tip_radius_mm = 60.0", "tip_radus_mm = 60.0"),
         "unknown key(s) ['tip_radus_mm'] in [matrix]"),
        (["--thickness", "16"], ("pitch_x_mm = 150.0", "pitch_x_mm = 1e308"), "[matrix] pitch_x_mm must be above 0 and at most 1e+06 mm, got 1e+308"),
        (["--thickness", "16"], ("max_mm = 300.0", "max_mm = 5.0", "-400.0", "-5.0"), "beyond the press limits"),
        (["--thickness", "16", "--steps", "1"], ("max_neighbour_diff_mm = 30.0", "max_neighbour_diff_mm = 2.0"),
         "dimpling limit 2"),
    ],
)
def test_failure_leaves_a_pre_existing_job_file_alone(cylinder_files, tmp_path, capsys, args, replace, message):
    design, flat, _ = cylinder_files
    text = example_press_path().read_text()
    for old, new in zip((replace or ())[::2], (replace or ())[1::2]):
        assert old in text
        text = text.replace(old, new)
    press = tmp_path / "press.toml"
    press.write_text(text)
    job_path = tmp_path / "job.json"
    job_path.write_text("the previous job\n")
    code = main(["plan", str(design), str(flat), "--press", str(press), *args, "-o", str(job_path)])
    err = " ".join(capsys.readouterr().err.split())
    assert code == 2
    assert message in err, err
    assert "Traceback" not in err
    assert job_path.read_text() == "the previous job\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["job.json", "press.toml"]


@pytest.mark.parametrize("plot_name, message", [("missing/s.png", "does not exist"), ("s.xyz", "unknown picture type")])
def test_bad_plot_path_is_refused_before_any_file_is_written(cylinder_files, tmp_path, capsys, plot_name, message):
    design, flat, _ = cylinder_files
    job_path = tmp_path / "job.json"
    code = main(["plan", str(design), str(flat), "--thickness", "16", "-o", str(job_path),
                 "--plot", str(tmp_path / plot_name)])
    err = capsys.readouterr().err
    assert code == 2 and message in " ".join(err.split())
    assert "placing" not in err  # refused before the planning started
    assert not job_path.exists()


def test_job_path_in_a_missing_folder_is_refused_first(cylinder_files, tmp_path, capsys):
    design, flat, _ = cylinder_files
    code = main(["plan", str(design), str(flat), "--thickness", "16", "-o", str(tmp_path / "no" / "job.json")])
    err = " ".join(capsys.readouterr().err.split())
    assert code == 2 and "cannot write the job file" in err and "placing" not in err


def test_step_count_is_bounded(cylinder_files, tmp_path, capsys):
    design, flat, _ = cylinder_files
    job_path = tmp_path / "job.json"
    assert main(["plan", str(design), str(flat), "--thickness", "16", "--steps", "201", "-o", str(job_path)]) == 2
    assert "the number of steps must be from 1 to 200, got 201" in " ".join(capsys.readouterr().err.split())
    text = example_press_path().read_text().replace("max_neighbour_diff_mm = 30.0", "max_neighbour_diff_mm = 0.01")
    press = tmp_path / "press.toml"
    press.write_text(text)
    assert main(["plan", str(design), str(flat), "--thickness", "16", "--press", str(press), "-o", str(job_path)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "press steps to keep within the dimpling limit of 0.01 mm, more than the 200" in err
    assert not job_path.exists()


@pytest.mark.parametrize("suffix", [".csv", ".ply"])
def test_plan_takes_the_flat_file_of_mppf_unfold(cylinder_files, tmp_path, capsys, suffix):
    design, flat, _ = cylinder_files
    unfolded = tmp_path / f"unfolded{suffix}"
    assert main(["unfold", str(design), "-o", str(unfolded), "--json"]) == 0
    capsys.readouterr()
    assert main(["plan", str(design), str(unfolded), "--thickness", "16", "--json"]) == 0
    via_unfold = json.loads(capsys.readouterr().out)
    assert main(["plan", str(design), str(flat), "--thickness", "16", "--json"]) == 0
    exact = json.loads(capsys.readouterr().out)
    assert via_unfold["registration"]["method"] == "paired"
    assert via_unfold["registration"]["neighbour_strain_p95_pct"] < 0.001
    assert via_unfold["max_travel_mm"] == pytest.approx(exact["max_travel_mm"], abs=0.01)
    for side in ("upper", "lower"):
        assert via_unfold[side]["min_mm"] == pytest.approx(exact[side]["min_mm"], abs=0.01)
        assert via_unfold[side]["max_mm"] == pytest.approx(exact[side]["max_mm"], abs=0.01)
