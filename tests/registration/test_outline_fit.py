"""Re-placing a registered scan by its outline: the edge envelope fit, plates badly formed or tilted on the press
(mppf.registration.outline_fit)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

import scan_helpers as sh
from mppf.core.transform import apply_tf, make_tf
from mppf.measure.compare import compare
from mppf.measure.options import CompareOptions
from mppf.sim.scanner import SimulatedScanner


def test_edge_fit_is_not_pulled_towards_the_side_showing_more_edge():
    """A scan's edge points stand up to a spacing inside the plate's edge; a stretch of one
    edge hidden (its outer rows missing) must not pull the fit towards the other side."""
    from mppf.core.polygon import closest_on_segments
    from mppf.core.rigid import fit_rigid
    from mppf.registration.outline_fit import fit_outline_2d

    rng = np.random.default_rng(3)
    spacing = 20.0
    corners = np.array(sh.OUTLINE)
    xx, yy = np.meshgrid(np.arange(-1500.0, 1500.1, spacing), np.arange(-1000.0, 1000.1, spacing))
    points = np.column_stack([xx.ravel(), yy.ravel()]) + rng.uniform(-0.5, 0.5, (xx.size, 2)) * spacing
    inside = (np.abs(points[:, 0]) < 1500.0) & (np.abs(points[:, 1]) < 1000.0)
    hidden = (points[:, 1] > 1000.0 - 3 * spacing) & (points[:, 0] > -500.0)  # 2 m of the top edge
    points = points[inside & ~hidden]
    edge = points[(1500.0 - np.abs(points[:, 0]) < 3 * spacing) | (1000.0 - np.abs(points[:, 1]) < 3 * spacing)
                  | (points[:, 1] > 1000.0 - 5 * spacing)]
    seg_a, seg_b = corners, np.roll(corners, -1, axis=0)
    total = fit_outline_2d(edge, seg_a, seg_b, True, spacing)
    shift_mm = np.hypot(*total[:2, 2])
    assert shift_mm < 4.0
    assert abs(np.degrees(np.arctan2(total[1, 0], total[0, 0]))) < 0.05
    # fitted point by point to the outline (ICP), the edge is pulled by the inset times the imbalance
    plain = edge.copy()
    for _ in range(30):
        step = fit_rigid(plain, closest_on_segments(plain, seg_a, seg_b)[0])
        plain = plain @ step[:2, :2].T + step[:2, 2]
    plain_shift_mm = np.linalg.norm(plain.mean(axis=0) - edge.mean(axis=0))
    assert plain_shift_mm > 2.5 * shift_mm


def test_outline_fit_places_a_badly_formed_plate():
    """Springback left the plate half as curved as designed: the outline still places it."""
    t = sh.THICKNESS_MM
    formed = sh.form(2500.0, 6000.0)
    design = formed.mid_surface_points(50.0, loaded=True)  # the plate as held, before springback
    sample = SimulatedScanner(seed=0, max_turn_deg=20.0).sample(formed)
    c = compare(design, sample.points, CompareOptions(offset_mm=t / 2, tf_press_design=np.eye(4),
            rotation_hint=np.eye(3),
                fit_outline=True))
    error = c.transform @ sample.tf_scan_press  # press -> design (= press): identity when placed right
    assert np.linalg.norm(error[:2, 3]) < 20.0
    assert abs(np.degrees(np.arctan2(error[1, 0], error[0, 0]))) < 0.5  # turn about the vertical
    assert "outline fit" in c.notes[0]
    assert c.rms_mm > 20.0  # and the deviations are large, as they should be


def test_outline_fit_works_from_above_the_press_on_a_plate_tilted_on_it():
    """The design comes in its own coordinates, tilted on the press by some degrees.

    The plate is cut and placed as seen from above the press; seen along the design's own
    normal its outline would move by the plate's depth times the tilt. The outline fit
    keeps the right place (the design here is the formed plate itself: no deviation).
    """
    press = sh.press()
    t = sh.THICKNESS_MM
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    formed = sh.form(2500.0, 6000.0)
    tilt = make_tf(Rotation.from_euler("xy", [7.0, -5.0], degrees=True).as_matrix(), [120.0, -80.0, 400.0])
    design = apply_tf(tilt, formed.mid_surface_points(40.0))  # press -> design coordinates
    tf_press_design = np.linalg.inv(tilt)
    for seed in (1, 2):
        sample = SimulatedScanner(seed=seed).sample(formed)
        c = compare(design, sample.points, CompareOptions(offset_mm=t / 2, tf_press_design=tf_press_design,
                    punch_xy_mm=np.stack([px, py], axis=-1)))
        assert "outline fit (from above the press)" in c.notes[0]
        error = tf_press_design @ c.transform @ sample.tf_scan_press  # identity when placed right
        assert np.linalg.norm(error[:2, 3]) < 4.0, seed
        assert abs(np.degrees(np.arctan2(error[1, 0], error[0, 0]))) < 0.2, seed
        assert np.nanmax(np.abs(c.punch_deviation_mm)) < 1.0, seed


def test_outline_fit_keeps_the_surface_turn_of_a_well_formed_bilge():
    """A bilge formed as designed, occluded scans: the outline shifts the scan but does not turn
    it by the few tenths of a degree its edge is uncertain by (a twist of mm at the corners)."""
    press = sh.press()
    t = sh.THICKNESS_MM
    from mppf.model.job_parts import reference_corner_xy

    formed = sh.form(3400.0, -1e7, asymmetric=False)
    design = formed.mid_surface_points(50.0)
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    corner = reference_corner_xy(formed.outline_xy_mm)
    design_mark = design[np.argmin(np.linalg.norm(design[:, :2] - corner, axis=1))]
    for seed in (7, 10):
        sample = SimulatedScanner(seed=seed, occlusion_fraction=0.3).sample(formed, corner)
        c = compare(design, sample.points, CompareOptions(offset_mm=t / 2, tf_press_design=np.eye(4),
                    punch_xy_mm=np.stack([px, py], axis=-1), reference_mark=(sample.mark_mm, design_mark)))
        error = c.transform @ sample.tf_scan_press  # press -> design (= press): identity when placed right
        assert abs(np.degrees(np.arctan2(error[1, 0], error[0, 0]))) < 0.1, seed
        assert c.rms_mm < 0.45 and c.max_abs_mm < 2.5
