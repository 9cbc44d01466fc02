"""Property: whatever goals and faults come in, no Goal Position outside a servo's limits reaches the wire,
and a refused frame sends nothing at all."""

from __future__ import annotations

import math

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from servoface.hardware.errors import GoalRejectedError

from tests.hardware.driver_helpers import LIMITS, assert_goals_within_limits, make_driver

SYNC_WRITE = 0x83
goal_values = st.one_of(
    st.integers(-10_000, 10_000),
    st.integers(900, 3200),  # near the limits, where off-by-one bugs live
    st.floats(allow_nan=True, allow_infinity=True),
    st.booleans(),
)
frames = st.dictionaries(st.sampled_from([1, 2, 3, 4, 5]), goal_values, max_size=5)
faults = st.sampled_from([None, "no_reply", "corrupt_crc", "overload", "disconnect", "late_reply", "obstacle"])


def _valid(frame: dict) -> bool:  # type: ignore[type-arg]
    for sid, goal in frame.items():
        if sid not in LIMITS or isinstance(goal, bool) or not isinstance(goal, int):
            return False
        lo, hi = LIMITS[sid]
        if not lo <= goal <= hi:
            return False
    return True


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(steps=st.lists(st.tuples(frames, faults, st.integers(1, 4)), min_size=1, max_size=12))
def test_no_goal_outside_limits_ever_reaches_the_wire(steps: list) -> None:  # type: ignore[type-arg]
    chain, driver = make_driver()
    for frame, fault, sid in steps:
        if fault == "obstacle":
            chain.set_obstacle(sid, 2100)
        elif fault is not None:
            chain.faults.inject(sid, fault, duration_s=0.05)
        n_sync = len(chain.instructions(SYNC_WRITE))
        n_goals = len(chain.goal_writes())
        try:
            snap = driver.cycle(frame)
        except GoalRejectedError:
            assert not _valid(frame)
            assert len(chain.instructions(SYNC_WRITE)) == n_sync and len(chain.goal_writes()) == n_goals
        else:
            assert _valid(frame)
            for s in snap:
                if s.goal_tick is not None:
                    lo, hi = LIMITS[s.servo_id]
                    assert lo <= s.goal_tick <= hi
        chain.advance(0.03)
    assert_goals_within_limits(chain, driver)


@settings(max_examples=60, deadline=None)
@given(goal=st.one_of(st.floats(), st.integers(-(2**40), 2**40)))
def test_every_accepted_goal_is_an_in_limit_int(goal: float | int) -> None:
    chain, driver = make_driver(ids=(2,), torque=False)
    try:
        checked = driver.validate_goals({2: goal})
    except GoalRejectedError as err:
        assert "servo 2" in str(err)
        return
    assert isinstance(checked[2], int) and not isinstance(goal, float)
    assert 1500 <= checked[2] <= 2600 and math.isfinite(checked[2])
