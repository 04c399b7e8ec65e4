"""Compare with a trim margin: a scan of the gross plate (net design + excess band)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mppf.cli import main
from mppf.measure.compare import compare
from mppf.core.errors import InputError
from mppf.geometry.io import write_points
from mppf.core.transform import apply_tf, make_tf, rotation_angle_deg

MARGIN_MM = 100.0
HALF_U, HALF_V = 1500.0, 1000.0  # the net plate: 3000 x 2000 mm
BUMP_UV = (0.0, HALF_V + 60.0)   # a bump in the band, 60 mm beyond the net edge
BUMP_SIGMA_MM = 12.0


def _height(u, v):
    """A saddle (radii 10 m and 12 m) with a small cubic and twist, so that its pose is unique (mm)."""
    return u**2 / (2 * 10000.0) - v**2 / (2 * 12000.0) + u**3 / 6e7 + u * v / 40000.0


def _normals(u, v):
    zu = u / 10000.0 + u**2 / 2e7 + v / 40000.0
    zv = -v / 12000.0 + u / 40000.0
    n = np.column_stack([-zu, -zv, np.ones_like(u)])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _design():
    """The net design on a 40 mm grid."""
    uu, vv = np.meshgrid(np.arange(-HALF_U, HALF_U + 1, 40.0), np.arange(-HALF_V, HALF_V + 1, 40.0))
    return np.column_stack([uu.ravel(), vv.ravel(), _height(uu, vv).ravel()])


def _pose():
    return make_tf(Rotation.from_euler("xyz", [15, -30, 60], degrees=True).as_matrix(), [400.0, -1500.0, 250.0])


def _bump(u, v):
    return 6.0 * np.exp(-((u - BUMP_UV[0]) ** 2 + (v - BUMP_UV[1]) ** 2) / (2 * BUMP_SIGMA_MM**2))


def _scan(n=12000, bump=False, seed=5):
    """(u, v, scan): the surface sampled over the grown rectangle, 0.2 mm noise, moved by ``_pose``.

    A few points sit on the bump's centre, so that it is seen whether or not it is there.
    """
    rng = np.random.default_rng(seed)
    extra = np.array([[0, 0], [4, 0], [-4, 0], [0, 4], [0, -4]], dtype=float) + BUMP_UV
    u = np.concatenate([rng.uniform(-HALF_U - MARGIN_MM, HALF_U + MARGIN_MM, n), extra[:, 0]])
    v = np.concatenate([rng.uniform(-HALF_V - MARGIN_MM, HALF_V + MARGIN_MM, n), extra[:, 1]])
    rise = _bump(u, v) if bump else np.zeros(u.size)
    pts = np.column_stack([u, v, _height(u, v)]) + rise[:, None] * _normals(u, v)
    pts += rng.normal(0.0, 0.2, pts.shape)
    return u, v, apply_tf(_pose(), pts)


def _band(u, v):
    return (np.abs(u) > HALF_U) | (np.abs(v) > HALF_V)


@pytest.fixture(scope="module")
def runs():
    """The gross scan with margin 100, the same scan's net points alone with margin 0."""
    u, v, scan = _scan()
    net = ~_band(u, v)
    return {
        "u": u, "v": v,
        "gross": compare(_design(), scan, margin_mm=MARGIN_MM),
        "net": compare(_design(), scan[net], tolerance_mm=2.5),
        "net_mask": net,
    }


def test_margin_recovers_the_pose_and_the_net_statistics(runs):
    u, v, c, n = runs["u"], runs["v"], runs["gross"], runs["net"]
    error = c.transform @ _pose()
    assert rotation_angle_deg(error) < 0.05
    assert np.linalg.norm(error[:3, 3]) < 10.0
    assert np.linalg.norm((n.transform @ _pose())[:3, 3]) < 10.0
    # the statistics are those of the net plate: the same as a scan of the net area alone
    assert c.rms_mm == pytest.approx(0.2, abs=0.02)
    assert c.rms_mm == pytest.approx(n.rms_mm, abs=0.01)
    assert c.mean_mm == pytest.approx(n.mean_mm, abs=0.01)
    assert c.form_rms_mm == pytest.approx(n.form_rms_mm, abs=0.01)
    assert c.max_abs_mm < 1.2 and c.form_max_abs_mm < 0.6
    assert c.n_inliers == pytest.approx(n.n_inliers, rel=0.01)
    # the band's points are in the margin: measured, not outside, not in the statistics
    band = _band(u, v)
    assert c.in_margin.shape == (u.size,)
    assert c.in_margin.sum() == pytest.approx(band.sum(), rel=0.02)
    assert (c.in_margin == band).mean() > 0.995
    assert not (c.in_margin & c.inlier).any() and not (c.in_margin & c.is_outside).any()
    assert c.is_outside.sum() == 0
    assert c.histogram_counts.sum() == c.n_inliers
    assert c.rms_mm == pytest.approx(np.sqrt(np.mean(c.deviation_mm[c.inlier] ** 2)))
    # the band is measured against the surface's extension: small, finite deviations
    assert np.all(np.isfinite(c.deviation_mm[c.in_margin]))
    assert np.percentile(np.abs(c.deviation_mm[c.in_margin]), 95) < 1.2
    # ... and has form values for maps, kept out of the form statistics
    assert np.isfinite(c.form_deviation_mm[c.in_margin & ~c.is_outlier]).all()
    assert c.form_max_abs_mm == pytest.approx(np.max(np.abs(c.form_deviation_mm[c.inlier])))
    doc = c.to_dict()
    json.dumps(doc)
    assert doc["margin_mm"] == MARGIN_MM and doc["n_margin"] == int(c.in_margin.sum())
    assert any("trim margin" in note for note in c.notes)
    # without a margin nothing changes: no margin points, no note
    assert n.margin_mm == 0.0 and not n.in_margin.any() and n.to_dict()["n_margin"] == 0
    assert not any("trim margin" in note for note in n.notes)


def test_without_the_margin_the_band_is_outside():
    """The same gross scan compared as if it were net: the band is not in the margin."""
    u, v, scan = _scan()
    c = compare(_design(), scan, margin_mm=0.0)
    assert not c.in_margin.any()
    far = (np.abs(u) > HALF_U + 70.0) | (np.abs(v) > HALF_V + 70.0)  # beyond 1.5 design spacings
    assert c.is_outside[far].mean() > 0.95


def test_a_bump_in_the_margin_leaves_the_net_statistics_alone(runs):
    u, v, scan = _scan(bump=True)
    c = compare(_design(), scan, margin_mm=MARGIN_MM)
    ref = runs["gross"]
    assert c.rms_mm == pytest.approx(ref.rms_mm, abs=0.005)
    assert c.max_abs_mm == pytest.approx(ref.max_abs_mm, abs=0.05)
    assert c.form_max_abs_mm == pytest.approx(ref.form_max_abs_mm, abs=0.05)
    assert c.form_max_abs_mm < 0.6  # a 6 mm bump in the statistics would be seen
    # the bump is measured (in the margin) but not in the statistics
    top = _bump(u, v) > 5.0
    assert top.sum() >= 5
    assert c.in_margin[top].all() and not c.inlier[top].any()
    assert np.median(c.deviation_mm[top]) == pytest.approx(6.0, abs=0.8)


def _punch_grid():
    """Punch axes every 120 mm in x and 80 mm in y; the outer ring lies in the band, the next one beyond it."""
    px, py = np.meshgrid(np.arange(-1680.0, 1681.0, 120.0), np.arange(-1120.0, 1121.0, 80.0))
    return px, py


def test_punches_under_the_margin_get_deviations():
    _, _, scan = _scan(n=25000, seed=8)  # about 14 points within the default radius (36 mm) of a punch
    px, py = _punch_grid()
    grid = np.stack([px, py], axis=-1)
    in_band = ((np.abs(px) == 1560.0) & (np.abs(py) <= 1040.0)) | ((np.abs(py) == 1040.0) & (np.abs(px) <= 1560.0))
    beyond = (np.abs(px) > 1600.0) | (np.abs(py) > 1100.0)
    net = ~in_band & ~beyond
    assert in_band.sum() == 2 * 27 + 2 * 25
    c = compare(_design(), scan, margin_mm=MARGIN_MM, tf_press_design=np.eye(4), punch_xy_mm=grid)
    assert "outline fit (from above the press): turned" in c.notes[0]  # the outline fit ran against the grown outline
    error = c.transform @ _pose()
    assert rotation_angle_deg(error) < 0.05
    assert np.linalg.norm(error[:3, 3]) < 5.0
    assert np.all(np.isfinite(c.punch_deviation_mm[in_band]))
    assert np.all(np.isfinite(c.punch_deviation_mm[net]))
    assert np.all(np.isnan(c.punch_deviation_mm[beyond]))
    assert not c.punch_interpolated.any()  # measured there, not filled in
    assert np.max(np.abs(c.punch_deviation_mm[net])) < 0.3
    assert np.max(np.abs(c.punch_deviation_mm[in_band])) < 1.0
    # without the margin those punches are off the plate
    plain = compare(_design(), scan, tf_press_design=np.eye(4), punch_xy_mm=grid)
    assert np.all(np.isnan(plain.punch_deviation_mm[in_band]))


@pytest.mark.parametrize("margin", [-5.0, float("nan"), float("inf"), "wide"])
def test_bad_margin_is_refused(margin):
    _, _, scan = _scan(n=500)
    with pytest.raises(InputError, match="trim margin") as info:
        compare(_design(), scan, margin_mm=margin)
    assert info.value.hint


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("margin")
    _, _, scan = _scan(n=6000)
    return (str(write_points(folder / "design.csv", _design())), str(write_points(folder / "scan.csv", scan)))


def test_cli_margin(files, capsys):
    design, scan = files
    code = main(["compare", design, scan, "--margin", "-1"])
    err = capsys.readouterr().err
    assert code == 2
    assert "--margin" in err and "-1" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    code = main(["compare", design, scan, "--margin", "100", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0
    assert doc["margin_mm"] == 100.0
    assert doc["n_margin"] > 500
    assert doc["rms_mm"] == pytest.approx(0.2, abs=0.03)
    code = main(["compare", design, scan, "--margin", "100"])
    out = capsys.readouterr().out
    assert code == 0 and "trim margin" in out
