"""Helpers for the driver tests: a manual-clock chain, a configured driver, the goal-limit audit."""

from __future__ import annotations

from collections.abc import Sequence

from servoface.hardware.bus import open_bus
from servoface.hardware.driver import Driver, FastSyncRead
from servoface.hardware.emulator import ServoChain
from servoface.hardware.fault_policy import FaultPolicy
from servoface.hardware.servo_config import ServoSpec

LIMITS = {1: (1024, 3072), 2: (1500, 2600), 3: (1024, 3072), 4: (2000, 2100)}
DT_S = 0.01


def make_driver(
    ids: Sequence[int] = (1, 2, 3, 4),
    policy: FaultPolicy | None = None,
    torque: bool = True,
    *,
    fast_sync_read: FastSyncRead = "auto",
    **spec_kw: int,
) -> tuple[ServoChain, Driver]:
    chain = ServoChain.create(ids=list(ids), model="XL330-M288", baud=1_000_000, wire_time=False, clock="manual")
    bus = open_bus("emulator", chain=chain)
    specs = [
        ServoSpec(
            i,
            "XL330-M288",
            role=f"r{i}",
            min_position_tick=LIMITS.get(i, (1024, 3072))[0],
            max_position_tick=LIMITS.get(i, (1024, 3072))[1],
            **spec_kw,
        )
        for i in ids
    ]
    driver = Driver(bus, specs, policy=policy, clock=chain.clock, fast_sync_read=fast_sync_read)
    driver.configure()
    if torque:
        driver.torque_on()
    return chain, driver


def run(chain: ServoChain, driver: Driver, goals: dict[int, int], seconds: float, dt_s: float = DT_S) -> list:  # type: ignore[type-arg]
    """Cycle for ``seconds`` of chain time; returns the snapshots."""
    snaps = []
    for _ in range(max(1, round(seconds / dt_s))):
        snaps.append(driver.cycle(goals))
        chain.advance(dt_s)
    return snaps


def assert_goals_within_limits(chain: ServoChain, driver: Driver) -> int:
    """No Goal Position outside a servo's configured limits ever reached the wire; returns how many."""
    writes = chain.goal_writes()
    for t, sid, goal in writes:
        lo, hi = driver.limits_tick(sid)
        assert lo <= goal <= hi, f"goal {goal} for servo {sid} at {t:.3f}s outside {lo}..{hi}"
    return len(writes)


def events_of(driver: Driver, kind: object, servo_id: int | None = None) -> list:  # type: ignore[type-arg]
    return [e for e in driver.events if e.kind == kind and (servo_id is None or e.servo_id == servo_id)]
