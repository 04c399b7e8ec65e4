"""Helpers of the registration tests: random motions, their errors, plate-like clouds and scans."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from mppf.core.transform import apply_tf, invert_tf, make_tf, rotation_angle_deg


def random_motion(seed: int, shift_mm: float = 2000.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return make_tf(Rotation.random(random_state=seed).as_matrix(), rng.uniform(-shift_mm, shift_mm, 3))


def motion_error(tf: np.ndarray, tf_true: np.ndarray, at: np.ndarray) -> tuple[float, float]:
    """(rotation error deg, displacement error mm at the point ``at`` of the source)."""
    diff = tf @ invert_tf(tf_true)
    moved = apply_tf(tf_true, at[None])
    return rotation_angle_deg(diff), float(np.linalg.norm(apply_tf(diff, moved) - moved))


def asymmetric_surface(n_u: int = 40, n_v: int = 25) -> np.ndarray:
    """A plate-like grid with no symmetry (3 x 2 m, 200 mm deep, cubic terms)."""
    u, v = np.meshgrid(np.linspace(-1500, 1500, n_u), np.linspace(-1000, 1000, n_v))
    u, v = u.ravel(), v.ravel()
    w = u**2 / 9000 + u * v / 20000 + v**3 / 4e6 + u**3 / 3e7
    return np.column_stack([u, v, w])


def random_plate(n: int, rng: np.random.Generator) -> np.ndarray:
    """n random points on an asymmetric 3 x 1.5 m plate, about 140 mm deep (mm)."""
    u, v = rng.uniform(-1500, 1500, n), rng.uniform(-750, 750, n)
    return np.column_stack([u, v, u * u / 16000 - v * v / 24000 + u**3 / 3e8])


PLATE_POSE = make_tf(Rotation.from_euler("xyz", [12.0, -8.0, 20.0], degrees=True).as_matrix(),
                    [250.0, -150.0, 400.0])
"""Pose of the scanner frame relative to the design in the differently-sampled cases."""


def sampled_scan(n_design: int, n_scan: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(design, scan in the scanner frame with 0.5 mm noise), sampled independently."""
    rng = np.random.default_rng(seed)
    design = random_plate(n_design, rng)
    scan = random_plate(n_scan, rng) + rng.normal(scale=0.5, size=(n_scan, 3))
    return design, apply_tf(invert_tf(PLATE_POSE), scan)
