"""Look-at geometry (eyes within their swing limits, the neck takes the rest) and gaze shifts in time."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from servoface.controller.alive import GazeConfig, GazeLayer, solve_look_at
from servoface.controller.alive.gaze import (
    clamp_swing,
    direction,
    eye_position_mm,
    gaze_config_for,
    rotation,
    swing_ratio,
)
from servoface.controller.errors import TimelineError
from servoface.controller.timeline import Timeline
from servoface.sim.rig import Joint

CFG = GazeConfig()  # eyes comfortable 18/12 deg, eye limits 35/25, neck 60/30


def composite_direction(pose, cfg: GazeConfig = CFG) -> np.ndarray:
    """Where the eyes point in the neutral head frame for a solved pose."""
    return rotation(pose.head_yaw_deg, pose.head_pitch_deg) @ direction(pose.eye_yaw_deg, pose.eye_pitch_deg)


def aim_error_deg(target, pose, cfg: GazeConfig = CFG) -> float:
    to = np.asarray(target, float) - eye_position_mm(pose.head_yaw_deg, pose.head_pitch_deg, cfg)
    d = composite_direction(pose, cfg)
    cos = float(np.dot(d, to) / np.linalg.norm(to))
    return math.degrees(math.acos(max(-1.0, min(1.0, cos))))


def test_directions_follow_the_head_frame() -> None:
    assert direction(0, 0) == pytest.approx([0, 0, 1])
    assert direction(90, 0) == pytest.approx([1, 0, 0])  # yaw + = the head's own left, +x
    assert direction(0, 90) == pytest.approx([0, 1, 0])  # pitch + = up


def test_small_targets_are_taken_by_the_eyes_alone() -> None:
    eye = CFG.eye_center_mm
    target = (eye[0] + 1000 * math.tan(math.radians(10)), eye[1], eye[2] + 1000)
    pose = solve_look_at(target, CFG)
    assert pose.head_yaw_deg == 0.0 and pose.head_pitch_deg == 0.0
    assert pose.eye_yaw_deg == pytest.approx(10.0) and pose.eye_pitch_deg == pytest.approx(0.0, abs=1e-9)
    assert pose.reachable


def test_beyond_the_eye_range_the_neck_takes_the_rest() -> None:
    target = (1000.0, 60.0, 1000.0)  # 45 deg to the head's left
    pose = solve_look_at(target, CFG)
    assert pose.eye_yaw_deg == pytest.approx(CFG.eye_range_yaw_deg, abs=1e-4)  # eyes at the edge of their range
    assert pose.head_yaw_deg > 20 and pose.head_yaw_deg < CFG.neck_limit_yaw_deg
    assert aim_error_deg(target, pose) < 1e-4  # the eyes hit the target exactly (parallax included)
    right = solve_look_at((-1000.0, 60.0, 1000.0), CFG)
    assert right.head_yaw_deg == pytest.approx(-pose.head_yaw_deg) and right.eye_yaw_deg < 0


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-1500, 1500),
    st.floats(-600, 800),
    st.floats(300, 2500),
)
def test_property_eyes_within_limits_and_aim_when_reachable(x: float, y: float, z: float) -> None:
    pose = solve_look_at((x, y, z), CFG)
    eye = direction(pose.eye_yaw_deg, pose.eye_pitch_deg)
    assert swing_ratio(eye, CFG.eye_limit_yaw_deg, CFG.eye_limit_pitch_deg) <= 1 + 1e-6
    head = direction(pose.head_yaw_deg, pose.head_pitch_deg)
    assert swing_ratio(head, CFG.neck_limit_yaw_deg, CFG.neck_limit_pitch_deg) <= 1 + 1e-6
    if pose.head_yaw_deg or pose.head_pitch_deg:
        # the neck moved: the eyes sit on the edge of their comfortable range (beyond it if the neck is out)
        assert swing_ratio(eye, CFG.eye_range_yaw_deg, CFG.eye_range_pitch_deg) >= 1 - 1e-4
    if pose.reachable:
        assert aim_error_deg((x, y, z), pose) < 1e-3


def test_unreachable_target_saturates_and_says_so() -> None:
    pose = solve_look_at((0.0, 60.0, -800.0), CFG)  # behind the head
    assert not pose.reachable
    eye = direction(pose.eye_yaw_deg, pose.eye_pitch_deg)
    assert swing_ratio(eye, CFG.eye_limit_yaw_deg, CFG.eye_limit_pitch_deg) <= 1 + 1e-6


def test_swing_clamp_is_radial_onto_the_ellipse() -> None:
    d, clamped = clamp_swing(direction(40, 0), 20, 10)
    assert clamped and math.degrees(math.atan2(d[0], d[2])) == pytest.approx(20)
    d, clamped = clamp_swing(direction(5, 5), 20, 10)
    assert not clamped


def test_bad_targets() -> None:
    with pytest.raises(TimelineError, match="look_at_mm: target .* coincides with the eyes"):
        solve_look_at(CFG.eye_center_mm, CFG)
    with pytest.raises(TimelineError, match="look_at_mm: expected three finite numbers"):
        solve_look_at((0.0, math.nan, 1.0), CFG)
    with pytest.raises(TimelineError, match=r"gaze.eye_limit_yaw_deg: expected a finite positive number"):
        GazeConfig(eye_limit_yaw_deg=-1)


def test_au_scales_come_from_the_au_table_and_the_head() -> None:
    human = gaze_config_for("human")
    assert human.eye_limit_yaw_deg == pytest.approx(30.0) and human.neck_limit_yaw_deg == pytest.approx(45.0)

    class FakeHead:
        joints = (
            Joint("neck_pan", None, (0.0, -10.0, 0.0), (0, 1, 0), -60, 60),
            Joint("eye_pan_l", None, (32.0, 70.0, 60.0), (0, 1, 0), -35, 35),
            Joint("eye_pan_r", None, (-32.0, 70.0, 60.0), (0, 1, 0), -35, 35),
        )

    cfg = gaze_config_for("human", FakeHead())
    assert cfg.eye_center_mm == pytest.approx((0.0, 70.0, 60.0)) and cfg.neck_pivot_mm == pytest.approx((0, -10, 0))


def test_gaze_shift_eyes_lead_then_head_follows_with_vor() -> None:
    layer = GazeLayer("human", CFG)
    goal = layer.look_at(1.0, (1000.0, 60.0, 1000.0))
    assert layer.sample(0.5) == {}  # no shift yet: the layer provides nothing
    early = layer.pose_at(1.0 + CFG.saccade_s)  # saccade done, neck barely moving
    assert early.eye_yaw_deg > 0.9 * CFG.eye_range_yaw_deg
    assert early.head_yaw_deg < 0.2 * goal.head_yaw_deg
    mid = layer.pose_at(1.3)
    assert 0 < mid.head_yaw_deg < goal.head_yaw_deg
    assert aim_error_deg((1000.0, 60.0, 1000.0), mid) < 1e-4  # eyes stay on target while the head turns
    late = layer.pose_at(1.0 + CFG.head_move_s)
    assert late.head_yaw_deg == pytest.approx(goal.head_yaw_deg)
    assert late.eye_yaw_deg == pytest.approx(goal.eye_yaw_deg, abs=1e-6)


def test_gaze_aus_for_human_and_dog() -> None:
    human = GazeLayer("human", CFG)
    goal = human.look_at(0.0, (-1000.0, 600.0, 1000.0))  # to the head's right and up
    aus = human.sample(5.0)
    assert aus["AU62"] == pytest.approx(-goal.eye_yaw_deg / CFG.eye_limit_yaw_deg) and aus["AU61"] == 0.0
    assert aus["AU52"] == pytest.approx(-goal.head_yaw_deg / CFG.neck_limit_yaw_deg) and aus["AU51"] == 0.0
    assert aus["AU53"] > 0 and aus["AU63"] > 0
    dog = GazeLayer("dog", CFG)
    dog.look_at(0.0, (-1000.0, 600.0, 1000.0))
    daus = dog.sample(5.0)
    assert daus["AU12"] < 0 and daus["AU10"] < 0 and daus["AU9"] > 0 and daus["AU13"] > 0


def test_gaze_shift_during_another_starts_from_where_it_got_to() -> None:
    layer = GazeLayer("human", CFG)
    layer.look_at(0.0, (1000.0, 60.0, 1000.0))
    before = layer.pose_at(0.3 - 1e-9)
    layer.look_at(0.3, (-1000.0, 60.0, 1000.0))
    at = layer.pose_at(0.3)
    assert at.head_yaw_deg == pytest.approx(before.head_yaw_deg, abs=1e-6)
    assert at.eye_yaw_deg == pytest.approx(before.eye_yaw_deg, abs=1e-6)
    layer.look_ahead(3.0)
    assert layer.pose_at(5.0).head_yaw_deg == pytest.approx(0.0, abs=1e-12)


def test_gaze_on_a_timeline_gives_valid_frames() -> None:
    tl = Timeline("human")
    layer = GazeLayer("human")
    tl.add_layer("gaze", layer)
    layer.look_at(0.0, (2000.0, -500.0, 500.0))  # far left and down: saturates
    for k in range(60):
        frame = tl.sample(k / 20)
        assert all(0.0 <= v <= 1.0 for v in frame.aus.values())
