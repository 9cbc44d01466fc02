"""The vectorised bank of all a head's curves agrees with each servo's own (exact) curve."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from servoface.calibration.bank import CurveBank
from servoface.calibration.errors import TargetOutOfRangeError, TickOutOfRangeError
from servoface.calibration.head import HeadCalibration


def test_forward_and_inverse_match_every_servo(calibration: HeadCalibration) -> None:
    bank = CurveBank(calibration.servos)
    rng = np.random.default_rng(5)
    lo, hi = bank.min_target, bank.max_target
    t = lo + rng.uniform(-0.1, 1.1, (300, len(lo))) * (hi - lo)  # includes the straight continuations
    expected = np.stack([s.curve.forward(t[:, j]) for j, s in enumerate(calibration.servos)], axis=1)
    assert np.allclose(bank.forward(t), expected, atol=1e-9)
    ticks = bank.min_tick + rng.integers(0, 10_000, (300, len(lo))) % (bank.max_tick - bank.min_tick + 1)
    exact = np.stack([s.to_targets(ticks[:, j]) for j, s in enumerate(calibration.servos)], axis=1)
    assert np.array_equal(bank.to_targets(ticks), exact)  # integer goals: table lookup == exact inverse
    half = ticks + 0.5
    half = np.minimum(half, bank.max_tick)
    exact_half = np.stack([s.to_targets(half[:, j]) for j, s in enumerate(calibration.servos)], axis=1)
    res = np.array([s.target_resolution() for s in calibration.servos])
    assert np.all(np.abs(bank.to_targets(half) - exact_half) <= 1e-2 * res)


@settings(max_examples=50, deadline=None)
@given(frac=st.lists(st.floats(0.0, 1.0), min_size=30, max_size=30))
def test_head_round_trip_target_goal_target_within_one_tick(frac: list[float]) -> None:
    from pathlib import Path

    from servoface.calibration.fileformat import load_calibration

    cal = _HUMAN.get("cal") or _HUMAN.setdefault(
        "cal", load_calibration(Path(__file__).resolve().parents[2] / "sim/heads/human/calibration.json")
    )
    lo = np.array([s.min_target for s in cal.servos])
    hi = np.array([s.max_target for s in cal.servos])
    targets = (lo + np.array(frac) * (hi - lo))[None, :]
    goals = cal.targets_to_goals_array(targets)
    back = cal.goals_to_targets_array(goals)
    res = np.array([s.target_resolution() for s in cal.servos])
    assert np.all(np.abs(back - targets) <= res + 1e-9)
    assert np.array_equal(cal.targets_to_goals_array(back)[0], goals[0])  # goal -> target -> goal: identity


_HUMAN: dict[str, HeadCalibration] = {}


def test_batch_refusals_name_the_servo(calibration: HeadCalibration) -> None:
    bank = CurveBank(calibration.servos)
    row = np.array([[s.neutral_target for s in calibration.servos]] * 3)
    row[2, calibration.roles.index("jaw")] = 40.0
    with pytest.raises(TargetOutOfRangeError, match="'jaw'"):
        bank.to_ticks(row)
    goals = np.array([[s.neutral_tick for s in calibration.servos]] * 2, dtype=float)
    goals[1, calibration.roles.index("lip_pucker")] = np.nan
    with pytest.raises(TickOutOfRangeError, match="'lip_pucker'"):
        bank.to_targets(goals, clip=True)
    goals[1, calibration.roles.index("lip_pucker")] = 4095
    with pytest.raises(TickOutOfRangeError, match="'lip_pucker'"):
        bank.to_targets(goals)
    clipped = bank.to_targets(goals, clip=True)[1, calibration.roles.index("lip_pucker")]
    assert clipped == pytest.approx(calibration["lip_pucker"].to_target(calibration["lip_pucker"].max_tick))
