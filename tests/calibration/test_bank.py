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


def _rows(bank: CurveBank, rng: np.random.Generator, n: int) -> np.ndarray:
    """Rows of targets: inside the range, on the curves' knots exactly, at the range ends, and a few just
    outside what is accepted (or non-finite)."""
    lo, hi = bank._accept_lo, bank._accept_hi
    rows = lo + rng.uniform(0.0, 1.0, (n, len(lo))) * (hi - lo)
    knots = [k[np.isfinite(k)] for k in bank._knots]
    for row in rows:
        for j in np.flatnonzero(rng.random(len(lo)) < 0.3):
            pick = rng.integers(4)
            if pick == 0 and knots[j].size:
                row[j] = float(rng.choice(knots[j]))
            elif pick == 1:
                row[j] = float(rng.choice([lo[j], hi[j], bank.min_target[j], bank.max_target[j]]))
            elif pick == 2 and rng.random() < 0.1:
                row[j] = float(rng.choice([np.nextafter(hi[j], np.inf), np.nextafter(lo[j], -np.inf), np.nan]))
    return rows


@pytest.mark.parametrize("head_name", ["human", "dog"])
def test_to_ticks_row_is_to_ticks_of_that_row(head_name: str) -> None:
    from servoface.controller.face import head_calibration
    from servoface.sim.heads import load_head

    cal = head_calibration(load_head(head_name))
    bank = CurveBank(cal.servos)
    rng = np.random.default_rng(21)
    errors = 0
    for row in _rows(bank, rng, 600):
        finite = np.where(np.isfinite(row), row, 0.0)
        assert np.array_equal(bank.forward_row(finite), bank.forward(finite[None, :])[0])  # bit for bit
        try:
            want: object = bank.to_ticks(row[None, :])[0]
        except TargetOutOfRangeError as err:
            want = (type(err), str(err))
        try:
            got: object = bank.to_ticks_row(row.copy())
        except TargetOutOfRangeError as err:
            got = (type(err), str(err))
        if isinstance(want, tuple):
            errors += 1
            assert got == want
        else:
            assert isinstance(got, np.ndarray) and got.dtype == np.int64 and np.array_equal(got, want)
    assert errors > 10
    roles = list(cal.roles)
    for row in _rows(bank, rng, 300):
        some = rng.permutation(len(roles))[: int(rng.integers(1, len(roles) + 1))]
        cols = cal.columns([roles[i] for i in some])
        try:
            want = cal.column_goals_plain(cols, row[some])
        except TargetOutOfRangeError as err:
            want = str(err)
        try:
            got = cal.column_goals(cols, row[some])
        except TargetOutOfRangeError as err:
            got = str(err)
        assert got == want if isinstance(want, str) else np.array_equal(got, want)  # type: ignore[arg-type]
