"""ServoCalibration: rounding, refusals naming the role, limits, round trips for every curve type."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from servoface.calibration.curves import LinearCurve, PchipCurve, PiecewiseLinearCurve
from servoface.calibration.errors import CalibrationError, TargetOutOfRangeError, TickOutOfRangeError
from servoface.calibration.servo import ServoCalibration

CRANK = np.array([[-4.0, 1756.06], [-0.68, 1999.71], [0.0, 2048.0], [2.73, 2243.36], [5.76, 2487.01], [8.0, 2730.67]])


def _servos() -> list[ServoCalibration]:
    lin = LinearCurve(2048.0, 4096 / 360, -1)
    return [
        ServoCalibration("lid", 6, "XL330-M288", lin, 1422, 2219, 2048, "deg", -15.0, 55.0),
        ServoCalibration("brow", 1, "XL330-M288", PiecewiseLinearCurve(CRANK), 1756, 2731, 2048, "mm"),
        ServoCalibration("brow_pchip", 2, "XL330-M288", PchipCurve(CRANK), 1756, 2731, 2048, "mm", -4.0, 8.0),
        ServoCalibration(
            "brow_rev",
            3,
            "XL330-M288",
            PchipCurve(CRANK * [1, -1] + [0, 4096]),
            1365,
            2340,
            2048,
            "mm",
            -4.0,
            8.0,
        ),
    ]


SERVOS = _servos()


@pytest.mark.parametrize("servo", SERVOS, ids=[s.role for s in SERVOS])
@settings(max_examples=80, deadline=None)
@given(frac=st.floats(0.0, 1.0))
def test_round_trip_target_tick_target_within_one_tick(servo: ServoCalibration, frac: float) -> None:
    target = servo.min_target + frac * (servo.max_target - servo.min_target)
    tick = servo.to_tick(target)
    assert isinstance(tick, int)
    assert servo.min_tick <= tick <= servo.max_tick
    back = servo.to_target(tick)
    # the tick is the nearest one: the curve puts the wanted target within half a tick of it ...
    assert abs(servo.curve.forward(target) - tick) <= 0.5 + 1e-9
    # ... so the target comes back within one tick's worth of target units
    assert abs(back - target) <= servo.target_resolution() + 1e-9


@pytest.mark.parametrize("servo", SERVOS, ids=[s.role for s in SERVOS])
def test_batch_matches_scalar_and_ticks_round_trip_exactly(servo: ServoCalibration) -> None:
    targets = np.linspace(servo.min_target, servo.max_target, 101)
    ticks = servo.to_ticks(targets)
    assert ticks.dtype == np.int64
    assert ticks.tolist() == [servo.to_tick(float(t)) for t in targets]
    all_ticks = np.arange(servo.min_tick, servo.max_tick + 1)
    # tick -> target -> tick is the identity wherever the target is inside the target limits
    back = servo.to_targets(all_ticks)
    inside = (back >= servo.min_target) & (back <= servo.max_target)
    assert np.array_equal(servo.to_ticks(back[inside]), all_ticks[inside])
    assert inside.sum() >= len(all_ticks) - 2


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf"), 55.1, -15.1, 1e9])
def test_to_tick_refuses_bad_targets_naming_the_role(bad: float) -> None:
    servo = SERVOS[0]  # limits -15..55 deg, under one tick (0.088 deg) of rounding slack
    with pytest.raises(TargetOutOfRangeError, match="'lid'") as info:
        servo.to_tick(bad)
    assert info.value.role == "lid"
    with pytest.raises(TargetOutOfRangeError, match="'lid'"):
        servo.to_ticks(np.array([0.0, 10.0, bad]))


def test_targets_within_rounding_of_the_limits_are_accepted() -> None:
    servo = SERVOS[0]
    assert servo.to_tick(55.04) == servo.min_tick  # reversed servo: rounds onto the limit tick
    assert 0 < servo.accept_max_target - servo.max_target < 360 / 4096
    for tick in range(servo.min_tick, servo.max_tick + 1):  # goal -> target -> goal is the identity
        assert servo.to_tick(servo.to_target(tick)) == tick


def test_to_target_refuses_ticks_outside_limits_unless_clipped() -> None:
    servo = SERVOS[1]
    with pytest.raises(TickOutOfRangeError, match="'brow'"):
        servo.to_target(servo.max_tick + 1)
    with pytest.raises(TickOutOfRangeError, match="not a finite"):
        servo.to_targets(np.array([2048.0, float("nan")]))
    assert servo.to_target(5000, clip=True) == pytest.approx(servo.to_target(servo.max_tick))


def test_limits_neutral_and_eeprom_backstop() -> None:
    lid = SERVOS[0]
    assert lid.direction == -1
    assert lid.neutral_target == pytest.approx(0.0)
    assert lid.position_limits_tick() == (1422, 2219)
    assert lid.position_limits_tick(margin_tick=10) == (1412, 2229)
    assert lid.to_tick(-15.0) == 2219 and lid.to_tick(55.0) == 1422  # reversed servo
    brow = SERVOS[1]
    assert (brow.min_target, brow.max_target) == pytest.approx((brow.to_target(1756), brow.to_target(2731)))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"min_tick": 2300, "max_tick": 2200}, "min_tick < max_tick"),
        ({"min_tick": -1}, "0 <= min_tick"),
        ({"max_tick": 4096}, "max_tick <= 4095"),
        ({"neutral_tick": 3000}, "neutral tick 3000 is outside"),
        ({"unit": "rad"}, "unit 'rad'"),
        ({"servo_id": 253}, "id must be"),
        ({"min_target": 0.0, "max_target": 70.0}, "do not round into the tick limits"),
        ({"min_target": 5.0, "max_target": 1.0}, "min < max"),
    ],
)
def test_construction_checks(kwargs: dict[str, object], message: str) -> None:
    base: dict[str, object] = dict(
        role="lid",
        servo_id=6,
        model="XL330-M288",
        curve=LinearCurve(2048, 11.4, 1),
        min_tick=1900,
        max_tick=2200,
        neutral_tick=2048,
        unit="deg",
    )
    base.update(kwargs)
    with pytest.raises(CalibrationError, match=message):
        ServoCalibration(**base)  # type: ignore[arg-type]
