"""The live marks: lagging punches, faulted punches, the progress of a motion, the press state."""

from __future__ import annotations

import numpy as np

from mppf.panel.live import LAG_S, LiveTracker, grid_json, press_state


def _grids(value, shape=(2, 3)):
    return {"upper": np.full(shape, float(value)), "lower": np.full(shape, float(value))}


def test_a_punch_standing_short_of_its_target_while_the_press_moves_lags():
    tracker = LiveTracker(tolerance_mm=0.2)
    targets, t = _grids(100.0), 0.0
    positions = _grids(0.0)
    out = tracker.update(t, False, targets, positions, {})
    assert out["progress_pct"] is None and not out["flagged"]
    for _ in range(12):  # every punch moves 10 mm per reading, but upper (1, 2) is stuck at 20 mm
        t += 0.25
        for side in positions:
            positions[side] = np.minimum(positions[side] + 10.0, 100.0)
        positions["upper"][1, 2] = min(positions["upper"][1, 2], 20.0)
        out = tracker.update(t, True, targets, positions, {})
    assert t > LAG_S
    assert out["flags"]["upper"][1][2] == "lagging"
    assert sum(f != "" for row in out["flags"]["upper"] for f in row) == 1
    assert [f["name"] for f in out["flagged"]] == ["upper R2 C3"]
    assert out["flagged"][0]["actual_mm"] == 20.0 and out["flagged"][0]["target_mm"] == 100.0
    assert 0 < out["progress_pct"] < 100


def test_moving_punches_and_the_start_of_a_motion_do_not_lag():
    tracker = LiveTracker(tolerance_mm=0.2)
    targets, positions = _grids(50.0), _grids(0.0)
    out = tracker.update(0.0, True, targets, positions, {})  # motion just started: nobody moved yet
    assert not out["flagged"] and out["progress_pct"] == 0.0
    for k in range(1, 6):
        positions = _grids(10.0 * k)
        out = tracker.update(0.25 * k, True, targets, positions, {})
        assert not out["flagged"]
    assert out["progress_pct"] == 100.0


def test_the_lag_mark_stays_after_the_motion_and_clears_at_the_next():
    tracker = LiveTracker(tolerance_mm=0.2)
    targets, positions = _grids(50.0), _grids(0.0)
    tracker.update(0.0, True, targets, positions, {})
    out = tracker.update(1.0, True, targets, positions, {})  # nothing moved for 1 s
    assert out["n_flagged"] == 12
    out = tracker.update(1.5, False, targets, positions, {})  # stopped
    assert out["n_flagged"] == 12
    out = tracker.update(2.0, True, _grids(0.0), positions, {})  # a new motion
    assert out["n_flagged"] == 0


def test_faulted_punches_come_from_the_fault_bits_and_are_listed_first():
    tracker = LiveTracker(tolerance_mm=0.2, base=1)
    bits = {"upper": np.zeros((2, 3), bool), "lower": np.zeros((2, 3), bool)}
    bits["lower"][0, 1] = True
    tracker.update(0.0, True, _grids(10.0), _grids(0.0), {})
    out = tracker.update(1.0, False, _grids(10.0), _grids(0.0), bits)
    assert out["flags"]["lower"][0][1] == "faulted"
    assert out["flagged"][0] == {"side": "lower", "name": "lower R1 C2", "kind": "faulted", "target_mm": 10.0,
                                 "actual_mm": 0.0}


def test_press_state_in_one_word():
    assert press_state(None, False) == "LINK LOST"
    assert press_state({"estop": True, "fault": True}, True) == "E-STOP"
    assert press_state({"fault": True}, True) == "FAULT"
    assert press_state({"busy": True, "ready": False}, True) == "MOVING"
    assert press_state({"ready": True}, True) == "READY"
    assert press_state({"ready": False}, True) == "NOT READY"
    assert press_state({"busy": True}, True, "EXECUTING") == "MOVING"
    assert press_state({"busy": True}, True, "STOPPING") == "STOPPING"
    assert press_state({"ready": True}, True, "STOPPED") == "STOPPED"
    assert press_state({"ready": True}, True, "COMPLETE") == "READY"
    assert press_state({"estop": True}, True, "FAULT") == "E-STOP"


def test_heartbeat_stale_after_a_second_without_change():
    tracker = LiveTracker(tolerance_mm=0.2)
    assert not tracker.heartbeat_stale(0.0, 5)
    assert not tracker.heartbeat_stale(0.9, 5)
    assert tracker.heartbeat_stale(1.2, 5)
    assert not tracker.heartbeat_stale(1.3, 6)


def test_grids_are_json_ready():
    assert grid_json(np.array([[1.234, np.nan]])) == [[1.23, None]]
