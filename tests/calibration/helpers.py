"""Small builders shared by the calibration tests (not fixtures: plain functions)."""

from __future__ import annotations

from servoface.calibration.builtin import builtin_calibration
from servoface.calibration.head import HeadCalibration
from servoface.calibration.spec import ServoSpec

MODEL = "XL330-M288"


def small_specs() -> list[ServoSpec]:
    """A 4-servo head: two joints (one reversed) and two anchors (one reversed)."""
    return [
        ServoSpec("jaw", 18, MODEL, "deg", 0.0, 25.0, 0.0, "joint", 1),
        ServoSpec("upper_lid_r", 6, MODEL, "deg", -15.0, 55.0, 0.0, "joint", -1),
        ServoSpec("brow_inner_l", 1, MODEL, "mm", -4.0, 8.0, 0.0, "anchor", 1),
        ServoSpec("lip_corner_r", 13, MODEL, "mm", -3.0, 10.0, 0.0, "anchor", -1),
    ]


def small_head() -> HeadCalibration:
    return builtin_calibration("small", small_specs())
