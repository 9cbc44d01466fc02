"""Mirrored left/right calibrations."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from servoface.calibration.errors import CalibrationError
from servoface.calibration.head import HeadCalibration
from servoface.calibration.mirror import mirror_servo, with_mirrored


def test_the_builtin_right_side_is_the_mirror_of_the_left(calibration: HeadCalibration) -> None:
    for left in ("brow_inner_l", "upper_lid_l", "lip_corner_l", "lip_depressor_l"):
        right = left[:-2] + "_r"
        m = mirror_servo(calibration[left], right, calibration[right].servo_id)
        shipped = calibration[right]
        assert (m.min_tick, m.max_tick, m.neutral_tick) == (
            shipped.min_tick,
            shipped.max_tick,
            shipped.neutral_tick,
        )
        t = np.linspace(shipped.min_target, shipped.max_target, 101)
        assert np.array_equal(m.to_ticks(t), shipped.to_ticks(t))
        assert m.direction == -calibration[left].direction


def test_with_mirrored_replaces_only_the_named_servos(calibration: HeadCalibration) -> None:
    skewed = dataclasses.replace(calibration["brow_outer_r"], neutral_tick=2050)
    cal = HeadCalibration("h", [skewed if s.role == "brow_outer_r" else s for s in calibration.servos])
    fixed = with_mirrored(cal, [("brow_outer_l", "brow_outer_r")])
    assert fixed["brow_outer_r"].neutral_tick == 2048 and fixed["brow_outer_r"].servo_id == 4
    assert fixed["jaw"] is cal["jaw"]


def test_mirroring_refuses_to_leave_the_tick_range() -> None:
    from servoface.calibration.curves import LinearCurve
    from servoface.calibration.servo import ServoCalibration

    near_zero = ServoCalibration("lid_l", 5, "XL330-M288", LinearCurve(100, 11.4, 1), 50, 300, 100, "deg")
    with pytest.raises(CalibrationError, match="outside 0..4095"):
        mirror_servo(near_zero, "lid_r", 6)
