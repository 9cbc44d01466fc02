"""Mirrored left/right servos: derive one side's calibration from the other's.

On a symmetric head the right-side servo is usually the left one mounted mirror-wise: the same target
needs the same tick offset from neutral, in the other direction. ``mirror_servo`` reflects a calibration
about its neutral tick (tick' = 2 * neutral - tick), keeping targets, points and neutral; it refuses when
the reflected limits leave 0..4095 and does not mirror a coupled servo (its neighbours differ by side).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable

import numpy as np
from servoface.calibration.curves import Curve, LinearCurve, PchipCurve, PiecewiseLinearCurve
from servoface.calibration.errors import CalibrationError
from servoface.calibration.head import HeadCalibration
from servoface.calibration.servo import MAX_POSITION_TICK, MIN_POSITION_TICK, ServoCalibration


def _mirror_curve(curve: Curve, centre: float) -> Curve:
    if isinstance(curve, LinearCurve):
        return LinearCurve(2 * centre - curve.offset_tick, curve.scale_tick_per_unit, -curve.direction)
    if isinstance(curve, PiecewiseLinearCurve | PchipCurve):
        pts = curve.points
        pts[:, 1] = 2 * centre - pts[:, 1]
        return type(curve)(pts)
    raise CalibrationError(f"cannot mirror a curve of kind {curve.kind!r}")


def mirror_servo(source: ServoCalibration, role: str, servo_id: int, model: str | None = None) -> ServoCalibration:
    """The calibration of ``role`` (id ``servo_id``) as the mirror image of ``source``."""
    if source.coupling is not None:
        raise CalibrationError(
            f"servo '{source.role}' is coupled to {list(source.coupling.neighbours)}; calibrate '{role}' itself"
        )
    centre = float(source.neutral_tick)
    lo, hi = 2 * source.neutral_tick - source.max_tick, 2 * source.neutral_tick - source.min_tick
    if lo < MIN_POSITION_TICK or hi > MAX_POSITION_TICK:
        raise CalibrationError(
            f"mirroring '{source.role}' onto '{role}' gives ticks {lo}..{hi}, outside "
            f"{MIN_POSITION_TICK}..{MAX_POSITION_TICK}"
        )
    points = np.asarray(source.measured_points, dtype=np.float64).copy()
    if points.size:
        points[:, 1] = 2 * centre - points[:, 1]
    return dataclasses.replace(
        source,
        role=role,
        servo_id=servo_id,
        model=model or source.model,
        curve=_mirror_curve(source.curve, centre),
        min_tick=lo,
        max_tick=hi,
        measured_points=points,
    )


def with_mirrored(cal: HeadCalibration, pairs: Iterable[tuple[str, str]]) -> HeadCalibration:
    """A copy of ``cal`` where each ``(source_role, mirrored_role)`` pair's second servo is replaced by the
    mirror image of the first (both must be in ``cal``; the mirrored servo keeps its id and model)."""
    replaced = {}
    for src, dst in pairs:
        target = cal[dst]
        replaced[dst] = mirror_servo(cal[src], dst, target.servo_id, target.model)
    return HeadCalibration(cal.head, [replaced.get(s.role, s) for s in cal.servos], cal.metadata)
