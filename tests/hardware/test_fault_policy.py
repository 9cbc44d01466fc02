"""The fault policy's pure decisions: thermal prediction, load back-off, voltage bands."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st
from servoface.hardware.fault_policy import (
    FaultPolicy,
    ThermalTrend,
    eased_goal,
    thermal_level,
    voltage_state,
)


def test_rising_temperature_predicts_time_to_limit() -> None:
    trend = ThermalTrend(window_s=30)
    for i in range(21):  # 0.5 C/s from 40 C, sampled at 2 Hz
        trend.add(i * 0.5, 40 + int(0.25 * i))
    slope = trend.slope_c_per_s
    assert slope == pytest.approx(0.5, abs=0.05)
    eta = trend.seconds_to(70)
    assert eta is not None and 50 < eta < 70


def test_flat_or_falling_temperature_predicts_nothing() -> None:
    trend = ThermalTrend(window_s=30)
    for i in range(10):
        trend.add(float(i), 45.0 - 0.1 * i)
    assert trend.seconds_to(70) is None
    trend.add(11.0, 71.0)
    assert trend.seconds_to(70) == 0.0


def test_thermal_levels_act_before_the_limit() -> None:
    policy = FaultPolicy()
    assert thermal_level(50, 70, None, policy) == 0
    assert thermal_level(50, 70, 100.0, policy) == 1  # far from the limit, but rising fast enough
    assert thermal_level(50, 70, 10.0, policy) == 2  # will reach it within the torque-off horizon
    assert thermal_level(66, 70, None, policy) == 1
    assert thermal_level(69, 70, None, policy) == 2


def test_voltage_state() -> None:
    assert voltage_state(4.9, 3.7, 6.0) == 0
    assert voltage_state(3.5, 3.7, 6.0) == -1
    assert voltage_state(6.5, 3.7, 6.0) == 1


def test_policy_refuses_nonsense() -> None:
    with pytest.raises(ValueError, match="backoff_gain"):
        FaultPolicy(backoff_gain=2.0)
    with pytest.raises(ValueError, match="retries"):
        FaultPolicy(retries=-1)
    with pytest.raises(ValueError, match="overload_cooldown_s"):
        FaultPolicy(overload_cooldown_s=float("nan"))


@given(
    goal=st.integers(0, 4095),
    present=st.integers(-5000, 9000),
    gain=st.floats(0, 1),
    lo=st.integers(0, 2000),
    width=st.integers(0, 2095),
)
def test_eased_goal_stays_inside_limits(goal: int, present: int, gain: float, lo: int, width: int) -> None:
    hi = lo + width
    goal = max(lo, min(hi, goal))
    eased = eased_goal(goal, present, gain, lo, hi)
    assert lo <= eased <= hi
