"""The driver's split cycle, the Alert bit in group reads, and telemetry that fills idle bus time."""

from __future__ import annotations

import pytest
from servoface.hardware.errors import DriverThreadError
from servoface.hardware.registers import Register
from servoface.hardware.snapshot import FaultKind

from tests.hardware.driver_helpers import make_driver, run

GOALS = {1: 2048, 2: 2048, 3: 2048, 4: 2048}


def test_sync_read_start_then_finish_is_sync_read_and_keeps_alert_bits() -> None:
    chain, driver = make_driver()
    bus = driver.bus
    ids = list(chain.ids)
    plain = bus.sync_read(ids, (Register.PRESENT_POSITION,))
    bus.sync_read_start(ids, (Register.PRESENT_POSITION,))
    assert bus.sync_read_finish() == plain
    chain.faults.inject(2, "overload", duration_s=0.01)
    chain.advance(0.02)
    bus.alerts.clear()
    for fast in (False, True):
        got = bus.sync_read(ids, (Register.PRESENT_POSITION,), fast=fast)
        assert set(got) == set(ids) and bus.alerts == {2}, fast  # values still come; the alarm is kept
        bus.alerts.clear()


def test_an_alarm_in_the_position_read_reaches_the_policy_the_same_cycle() -> None:
    from servoface.hardware.fault_policy import FaultPolicy

    chain, driver = make_driver(policy=FaultPolicy(status_hz=0.1))  # polling alone would take 10 s
    run(chain, driver, GOALS, 0.5)
    chain.faults.inject(1, "overload", duration_s=0.01)
    chain.advance(0.02)
    snap = driver.cycle(GOALS)  # no single transaction in between: the sync read's reply carried the bit
    assert FaultKind.OVERLOAD in snap[1].faults


def test_cycle_start_and_finish_pair_up() -> None:
    chain, driver = make_driver()
    driver.cycle_start(GOALS)
    with pytest.raises(DriverThreadError, match="twice"):
        driver.cycle_start(GOALS)
    snap = driver.cycle_finish()
    assert all(s.position_tick is not None for s in snap)
    with pytest.raises(DriverThreadError, match="without cycle_start"):
        driver.cycle_finish()


def test_telemetry_reads_fill_idle_time_and_fall_to_the_floor_rate_without_it() -> None:
    chain, driver = make_driver()
    run(chain, driver, GOALS, 0.3)
    now = driver._clock()
    group = driver._groups[1]  # motion, 10 Hz
    for g in driver._groups:
        g.due_s, g.cost_s = now + 100.0, 0.005  # only `group` is due below
    driver._idle_s = 0.001  # the caller left 1 ms idle; the read takes 5 ms
    group.due_s = now - 0.01
    assert driver._due_group(now) is None  # due, does not fit, not yet past the floor
    late = group.period_s * (1 / driver.policy.telemetry_floor_share - 1)
    group.due_s = now - late - 1e-6
    assert driver._due_group(now) is group  # past the floor rate: read anyway
    group.due_s = now - 0.01
    driver._idle_s = 0.006
    assert driver._due_group(now) is group  # fits in the idle time: nominal rate
    group.due_s, driver._idle_s = float("-inf"), 0.0
    assert driver._due_group(now) is group  # asked for (an alert, a reaction): at once


def test_a_cycle_that_fails_to_start_does_not_block_the_next(monkeypatch: pytest.MonkeyPatch) -> None:
    from servoface.hardware.errors import BusError

    chain, driver = make_driver()
    real = driver._send_goals

    def busy(frame):  # type: ignore[no-untyped-def]
        raise BusError("sync write: port in use")

    monkeypatch.setattr(driver, "_send_goals", busy)
    with pytest.raises(BusError):
        driver.cycle_start(GOALS)
    monkeypatch.setattr(driver, "_send_goals", real)
    assert driver.cycle(GOALS)[1].goal_tick == GOALS[1]
