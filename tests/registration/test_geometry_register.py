"""Registration on the real hull patches with the default options: identical surfaces land
exactly (the paper's model 1), and the real unfolded flat plate lands centred on its design."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mppf.geometry.frame import fit_frame
from mppf.geometry.read import read_points
from mppf.registration.register import register_icp
from mppf.registration.settings import RegisterOptions
from mppf.core.transform import apply_tf, make_tf
from mppf.geometry.unfold import unfold

HULL = ["P1_midbody_bilge.csv", "P2_bow_flare.csv", "P3_stern_saddle.csv",
        "K1_midbody_bilge.csv", "K2_fwd_bilge_convex.csv", "K3_stern_saddle.csv"]


@pytest.mark.parametrize("method", ["point", "plane"])
@pytest.mark.parametrize("name", HULL)
def test_identical_hull_patch_in_two_positions_registers_exactly(hull_dir, name, method):
    src = read_points(hull_dir / name).points
    rng = np.random.default_rng(HULL.index(name))
    tf_true = make_tf(Rotation.random(random_state=rng.integers(1 << 30)).as_matrix(), rng.uniform(-3000, 3000, 3))
    # defaults: principal start, pin auto
    result = register_icp(src, apply_tf(tf_true, src), RegisterOptions(method=method))
    assert result.converged
    assert result.rms_mm < 1e-6
    assert np.abs(apply_tf(result.tf, src) - apply_tf(tf_true, src)).max() < 1e-6


@pytest.mark.parametrize("name", ["P2_bow_flare.csv", "K3_stern_saddle.csv"])
def test_unfolded_flat_plate_lands_centred_on_its_design(hull_dir, name):
    # the real flat shape from the unfolding (larger than the projection by the developed
    # length), moved and turned at random, registered without its point pairs
    curved = read_points(hull_dir / name).points
    flat = unfold(curved).flat
    moved_flat = apply_tf(make_tf(Rotation.random(random_state=11).as_matrix(), [3000, -200, 900]), flat)
    result = register_icp(moved_flat, curved, RegisterOptions(method="plane"))
    assert result.method == "point" and result.outline_pinned
    frame = fit_frame(curved)
    landed = frame.to_local(apply_tf(result.tf, moved_flat))
    assert np.hypot(*landed[:, :2].mean(axis=0)) < 1.0  # centred in-plane, mm
    assert abs(landed[:, 2].mean()) < 1.0  # on the best-fit plane
    assert np.ptp(landed[:, 2]) < 0.1  # still flat: a rigid motion
    landed_u = fit_frame(apply_tf(result.tf, moved_flat)).axes[0]
    assert np.degrees(np.arccos(min(1.0, abs(landed_u @ frame.axes[0])))) < 0.05  # axes aligned
