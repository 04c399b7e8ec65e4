"""Registration: paired closed form and ICP end to end (mppf.registration.register)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from registration_helpers import (
    PLATE_POSE,
    asymmetric_surface,
    motion_error,
    random_motion,
    sampled_scan,
)
from scipy.spatial.transform import Rotation

from mppf.core.errors import GeometryError, InputError
from mppf.core.rigid import fit_rigid
from mppf.core.transform import (
    apply_tf,
    make_tf,
    matrix_to_rotvec,
    quaternion_to_matrix,
    rotvec_to_matrix,
)
from mppf.geometry.frame import fit_frame
from mppf.geometry.read import read_points
from mppf.registration.register import register_icp, register_paired
from mppf.registration.settings import RegisterOptions

HULL_FILES = [
    "P1_midbody_bilge.csv", "P1_midbody_bilge_smooth.csv", "P2_bow_flare.csv",
    "P2_bow_flare_smooth.csv", "P3_stern_saddle.csv", "P3_stern_saddle_smooth.csv",
    "K1_midbody_bilge.csv", "K2_fwd_bilge_convex.csv", "K3_stern_saddle.csv",
]


@pytest.fixture(scope="module")
def hull(hull_dir):
    return {name: read_points(hull_dir / name).points for name in HULL_FILES}


# ----------------------------------------------------------------------- paired


def test_quaternion_step_gives_the_standard_rotation_not_the_transpose():
    # a known 30 deg turn about z: x = R p must come back as R (eq. 2.8 printed R^T)
    p = np.array([[1000.0, 0, 0], [0, 500, 0], [0, 0, 200], [300, 300, 0]])
    rot = Rotation.from_euler("z", 30, degrees=True).as_matrix()
    tf = fit_rigid(p, p @ rot.T)
    assert np.allclose(tf[:3, :3], rot, atol=1e-12)
    assert tf[1, 0] > 0  # sin(30 deg) below the diagonal: the standard matrix
    q = Rotation.from_matrix(rot).as_quat()  # scalar last
    assert np.allclose(quaternion_to_matrix([q[3], q[0], q[1], q[2]]), rot, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 1e-3),
       st.sampled_from([1e-12, 1e-7, 1e-4, 0.3, 1.0, 3.0, np.pi - 1e-9]))
def test_rotation_vector_helpers_agree_with_scipy_at_every_angle(direction, angle):
    # the ICP steps turn by them: tiny increments (the stop test at 1e-5 rad) up to half turns
    rotvec = np.asarray(direction) / np.linalg.norm(direction) * angle
    rot = Rotation.from_rotvec(rotvec).as_matrix()
    assert np.abs(rotvec_to_matrix(rotvec) - rot).max() < 1e-14
    back = matrix_to_rotvec(rot)
    assert np.abs(back - rotvec).max() <= (1e-7 if angle > 3.1 else 2e-15 * angle)  # relative, also for tiny turns


def test_paired_recovers_a_known_motion_noise_free(hull):
    src = hull["P2_bow_flare.csv"]
    tf_true = random_motion(1)
    result = register_paired(src, apply_tf(tf_true, src))
    scale = np.abs(tf_true).max()
    assert np.abs(result.tf - tf_true).max() <= 1e-9 * scale
    assert result.rms_mm < 1e-6
    assert result.method == "paired" and result.converged and result.iterations == 1


def test_paired_with_noise_and_weights(hull):
    rng = np.random.default_rng(2)
    src = hull["K1_midbody_bilge.csv"]
    tf_true = random_motion(2)
    tgt = apply_tf(tf_true, src) + rng.normal(scale=0.5, size=src.shape)
    result = register_paired(src, tgt)
    rot_err, shift_err = motion_error(result.tf, tf_true, src.mean(axis=0))
    assert rot_err < 0.05 and shift_err < 0.5
    assert 0.75 < result.rms_mm < 0.95  # sqrt(3) * 0.5 mm of noise
    # a gross error on one pair is ignored when its weight is zero
    tgt[7] += 500.0
    weights = np.ones(len(src))
    weights[7] = 0.0
    weighted = register_paired(src, tgt, weights=weights)
    assert motion_error(weighted.tf, tf_true, src.mean(axis=0))[0] < 0.05


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.1),
       st.lists(st.floats(-5000.0, 5000.0), min_size=3, max_size=3))
def test_paired_property_random_rotations(quat, shift):
    src = asymmetric_surface(8, 6)
    tf_true = make_tf(quaternion_to_matrix(quat), shift)
    result = register_paired(src, apply_tf(tf_true, src))
    assert np.abs(result.tf - tf_true).max() <= 1e-9 * max(1.0, np.abs(tf_true).max())


@pytest.mark.parametrize(
    ("source", "target", "error", "words"),
    [
        (np.zeros((5, 3)) + [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0]], np.ones((4, 3)),
         InputError, "same number of points"),
        ([[0, 0, 0], [1, 0, 0]], [[0, 0, 0], [1, 0, 0]], GeometryError, "at least 3"),
        ([[0, 0, 0], [1, 1, 1], [2, 2, 2], [3, 3, 3]], [[0, 0, 0], [1, 1, 1], [2, 2, 2], [3, 3, 3]],
         GeometryError, "collinear"),
        ([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]], [[0, 0, 0], [1, 0, 0], [0, 1, 0]], InputError, "NaN"),
    ],
)
def test_paired_bad_input(source, target, error, words):
    with pytest.raises(error, match=words):
        register_paired(source, target)


def test_paired_bad_weights():
    pts = asymmetric_surface(4, 3)
    with pytest.raises(InputError, match="weights"):
        register_paired(pts, pts, weights=-np.ones(len(pts)))


# ----------------------------------------------------------------------- ICP basics


@pytest.mark.parametrize("init", ["principal", "identity"])
def test_icp_identical_surfaces_register_exactly(init):
    # the paper's model 1: the same surface in two positions (small motion for identity)
    src = asymmetric_surface()
    tf_true = random_motion(3) if init == "principal" else make_tf(
        Rotation.from_euler("xyz", [4, -3, 6], degrees=True).as_matrix(), [40, -25, 30])
    # unpinned: the paper's quaternion steps land exactly once the closest points are right
    result = register_icp(src, apply_tf(tf_true, src), RegisterOptions(init=init, pin_outline=False))
    assert result.converged
    assert result.rms_mm < 1e-6
    assert np.abs(result.tf - tf_true).max() <= 1e-9 * max(1.0, np.abs(tf_true).max())
    assert len(result.rms_history) >= result.iterations + 1
    assert result.rms_history[-1] == result.rms_mm


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_icp_property_random_rotations_principal_start(seed):
    src = asymmetric_surface(30, 20)
    tf_true = random_motion(seed)
    target = apply_tf(tf_true, src)
    exact = register_icp(src, target, RegisterOptions(pin_outline=False))
    assert np.abs(exact.tf - tf_true).max() <= 1e-9 * max(1.0, np.abs(tf_true).max())
    assert not exact.ambiguous_start
    # with the outline pin (default) the iterations stop at the increment tolerance
    pinned = register_icp(src, target)
    rot_err, shift_err = motion_error(pinned.tf, tf_true, src.mean(axis=0))
    assert pinned.outline_pinned and pinned.converged
    assert rot_err < 1e-4 and shift_err < 1e-3


HALF_TURN_SYMMETRIC = {"P1_midbody_bilge_smooth.csv"}
"""Plates whose half turn about the normal fits themselves within 0.03 mm RMS, their 50 mm grid included:
with 0.5 mm of noise no registration can tell the two turns apart (the issue-19 tie)."""


@pytest.mark.parametrize("name", HULL_FILES)
def test_each_hull_patch_registers_to_a_moved_noisy_copy(hull, name):
    seed = HULL_FILES.index(name) + 10
    rng = np.random.default_rng(seed)
    src = hull[name]
    tf_true = random_motion(seed)
    tgt = apply_tf(tf_true, src) + rng.normal(scale=0.5, size=src.shape)
    result = register_icp(src, tgt, RegisterOptions(method="point"))
    rot_err, shift_err = motion_error(result.tf, tf_true, src.mean(axis=0))
    if name in HALF_TURN_SYMMETRIC:
        # the two turns tie: flagged, and the result is one of them
        assert result.ambiguous_start, result.init
        frame = fit_frame(tgt)
        half_turn = frame.tf_world_local @ make_tf(np.diag([-1.0, -1.0, 1.0])) @ frame.tf_local_world
        rot_err, shift_err = min(motion_error(result.tf, tf_true, src.mean(axis=0)),
                                 motion_error(result.tf, half_turn @ tf_true, src.mean(axis=0)))
    else:
        assert not result.ambiguous_start, result.init
    assert rot_err < 0.05, result.init
    assert shift_err < 1.0
    assert result.converged
    assert 0.6 < result.rms_mm < 1.1


def test_point_to_point_turn_on_a_differently_sampled_100k_scan():
    # design and scan sampled independently: the closest-point offsets in the plane are about
    # the point spacing and follow the sampling, not the shape; point-to-point left the turn
    # about the normal to them and ended 0.097 degree off here (0.24 - 0.40 at 10k points)
    design, scan = sampled_scan(100_000, 100_000, seed=2)
    result = register_icp(scan, design, RegisterOptions(method="point"))
    rot_err, shift_err = motion_error(result.tf, PLATE_POSE, scan.mean(axis=0))
    assert result.outline_pinned and result.converged
    assert rot_err < 0.025, result.stop_reason
    assert shift_err < 0.5


def test_icp_reports_iteration_limit_and_history():
    src = asymmetric_surface()
    tf_true = make_tf(Rotation.from_euler("z", 8, degrees=True).as_matrix(), [60, 0, 0])
    result = register_icp(src, apply_tf(tf_true, src), RegisterOptions(init="identity", max_iterations=2))
    assert not result.converged
    assert result.stop_reason == "iteration limit reached"
    assert result.iterations == 4  # the limit holds for each stage, coarse and fine
    assert len(result.rms_history) == 5  # one per iteration and the final transform
    assert result.rms_history[-1] < result.rms_history[0]


def test_to_dict_is_json(hull):
    src = hull["P3_stern_saddle.csv"]
    result = register_icp(src, apply_tf(random_motion(4), src), RegisterOptions(method="plane"))
    data = json.loads(json.dumps(result.to_dict()))
    for key in ("rms_mm", "iterations", "transform", "method", "converged", "stop_reason",
                "inlier_fraction", "uncertainty", "init", "ambiguous_start", "outline_pinned"):
        assert key in data
    assert np.allclose(np.array(data["transform"]), result.tf)
    assert data["method"] == "plane"
    assert len(data["init"]["scores_mm"]) == 4


def test_icp_bad_points():
    pts = asymmetric_surface(6, 5)
    bad = pts.copy()
    bad[3, 2] = np.inf
    with pytest.raises(InputError, match="NaN or infinite"):
        register_icp(bad, pts)
    with pytest.raises(GeometryError, match="collinear"):
        register_icp(pts, np.outer(np.arange(10.0), [1.0, 2.0, 3.0]))


def test_the_register_command_runs_without_importing_scipy_or_the_cad_reader(tmp_path):
    # scipy's import is most of a small registration's time (docs/math-registration.md section 9): the
    # k-d trees (mppf.core.kdtree), the outline (mppf.core.polygon) and the frame's fit do without it;
    # a point file needs neither the CAD reader (gmsh's gate) nor a temporary file (counted from what the
    # interpreter had loaded before mppf: a site's .pth file may import tempfile at start-up)
    design, scan = sampled_scan(4000, 2000, seed=5)
    np.savetxt(tmp_path / "scan.csv", scan, delimiter=",")
    np.savetxt(tmp_path / "design.csv", design, delimiter=",")
    script = ("import json, sys; before = set(sys.modules); from mppf.cli import main; "
              f"args = [{str(tmp_path / 'scan.csv')!r}, {str(tmp_path / 'design.csv')!r}]; "
              "codes = [main(['register', *args, '--method', 'plane', '--json', '-o', "
              f"{str(tmp_path / 'moved.csv')!r}]), main(['register', *args, '--init', 'identity'])]; "
              "print(json.dumps([codes, sorted(m for m in set(sys.modules) - before "
              "if m.partition('.')[0] in ('scipy', 'gmsh', 'tempfile') "
              "or m in ('mppf.geometry.cad', 'mppf.geometry.cad_mesh', 'mppf.geometry.gmsh_gate'))]))")
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=False,
                          cwd=Path(__file__).resolve().parents[2])  # this checkout's mppf
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    out = json.loads(proc.stdout[:proc.stdout.index("\n}") + 2])
    assert result == [[0, 0], []], proc.stdout[-2000:]
    turn_deg, shift_mm = motion_error(np.asarray(out["transform"]), PLATE_POSE, scan.mean(axis=0))
    assert out["judgement"] == "converged" and turn_deg < 0.05 and shift_mm < 5.0  # 2,000 points: 0.011 deg, 2.1 mm
    assert (tmp_path / "moved.csv").exists()
