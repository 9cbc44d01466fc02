"""The calm cycle (`CalmCycle`) and the one-pass goal frame (`Driver._goal_frame`) change nothing but when
the work is done.

Two drivers on two identical manual-clock chains, one with both paths and one without (every cycle the full
path: `validate_goals` then `_write_goals`, `_read_positions`, `_freeze`), get the same random goals and the
same faults injected from the emulator's side: silent servos, corrupt replies, overload alarms, servo
resets (RAM defaults, torque off), an obstacle (load back-off), a hot servo (derate), low voltage, refused
frames; telemetry folded into the position read as by default. Every cycle's snapshot must equal, field by
field and type by type, the one built from the records with `ServoRecord.freeze_full`, and the reference
driver's; the wire bytes and the events must be the same; earlier snapshots must not move.
"""

from __future__ import annotations

import dataclasses
import random
from collections.abc import Mapping

import pytest
from servoface.hardware.driver import Driver
from servoface.hardware.emulator import ServoChain
from servoface.hardware.errors import GoalRejectedError
from servoface.hardware.fault_policy import FaultPolicy
from servoface.hardware.servo_record import ServoRecord
from servoface.hardware.snapshot import ChainSnapshot, ServoState, StateCapture

from tests.hardware.driver_helpers import DT_S, LIMITS, assert_goals_within_limits, make_driver

IDS = (1, 2, 3, 4, 5, 6)
SEEDS = (1, 2, 3, 4)


class FullPathDriver(Driver):
    """Every cycle the full path (no calm plan, goals validated then framed in two passes)."""

    def _goal_frame(self, goals_tick: Mapping[int, int]) -> dict[int, int] | None:
        return None

    def _plan_calm(self, now: float) -> None:
        return None


class CountingDriver(Driver):
    """The driver as shipped, counting its calm cycles (planned; planned and kept calm)."""

    planned = 0
    calm = 0

    def _read_positions_calm(
        self, plan: dict[int, tuple[ServoRecord, ServoState]], now: float
    ) -> dict[int, ServoState | StateCapture] | None:
        self.planned += 1
        items = super()._read_positions_calm(plan, now)
        self.calm += items is not None
        return items


def _fields(state: ServoState) -> list[tuple[str, type, object]]:
    """Every field with its type: equal values of another type (1 vs 1.0, True vs 1) are a difference."""
    return [(f.name, type(getattr(state, f.name)), getattr(state, f.name)) for f in dataclasses.fields(state)]


def _reference(driver: Driver) -> dict[int, list[tuple[str, type, object]]]:
    return {sid: _fields(rec.freeze_full()) for sid, rec in driver._records.items()}


def _snap_fields(snap: ChainSnapshot) -> dict[int, list[tuple[str, type, object]]]:
    return {sid: _fields(state) for sid, state in snap.servos.items()}


NOMINAL_V = 5.0
POLICY = FaultPolicy(overload_cooldown_s=0.2)  # recoveries inside the run: calm stretches between faults


def _inject(chain: ServoChain, rng: random.Random, step: int) -> None:
    """An emulator-side fault about every 30 cycles (the same sequence on both chains: the same ``rng``);
    supply and temperature back to normal every 100 cycles."""
    if step % 100 == 99:
        chain.set_input_voltage(None, NOMINAL_V)
        for sid in IDS:
            chain.servo(sid).temperature_c = 40.0
    if rng.random() > 1 / 30:
        return
    kind = rng.choice(["no_reply", "no_reply", "corrupt_crc", "overload", "reset", "obstacle", "hot", "voltage"])
    sid = rng.choice(IDS)
    if kind == "no_reply":
        chain.faults.inject(sid, "no_reply", duration_s=rng.choice([0.005, 0.03, 0.3]))
    elif kind == "corrupt_crc":
        chain.faults.inject(sid, "corrupt_crc", duration_s=0.005)
    elif kind == "overload":
        chain.faults.inject(sid, "overload", duration_s=0.02)
    elif kind == "reset":
        chain.servo(sid).reboot(0.0)  # e.g. a brown-out: RAM defaults, torque off, no error bit
    elif kind == "obstacle":
        chain.set_obstacle(1, 2200 if (step // 200) % 2 == 0 else None)
    elif kind == "hot":
        chain.servo(sid).temperature_c = rng.choice([40.0, 66.0])
    else:
        chain.set_input_voltage(sid, rng.choice([5.0, 3.2]))


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("fast", [False, True])
def test_calm_cycles_give_the_full_paths_snapshots_bytes_and_events(seed: int, fast: bool) -> None:
    runs = []
    for cls in (CountingDriver, FullPathDriver):
        chain, plain = make_driver(ids=IDS)
        driver = cls(plain.bus, list(plain._specs.values()), policy=POLICY, clock=chain.clock, fast_sync_read=fast)
        driver.configure()
        driver.torque_on()
        runs.append((chain, driver, random.Random(seed)))
    goals_rng = random.Random(seed)
    kept: list[tuple[ChainSnapshot, dict[int, list[tuple[str, type, object]]]]] = []
    for step in range(1000):
        goals: dict = {  # type: ignore[type-arg]
            sid: goals_rng.randint(*LIMITS.get(sid, (1024, 3072)))
            for sid in goals_rng.sample(IDS, goals_rng.randint(0, 6))
        }
        if goals_rng.random() < 0.02:
            goals[goals_rng.choice([1, 9])] = goals_rng.choice([2048.5, True, 99999, "x"])  # refused whole
        if goals_rng.random() < 0.01:
            runs[0][1].torque_off([2])  # between cycles, on both: a record changed outside a cycle
            runs[1][1].torque_off([2])
        if goals_rng.random() < 0.01:
            runs[0][1].torque_on([2])
            runs[1][1].torque_on([2])
        outcomes = []
        for chain, driver, rng in runs:
            _inject(chain, rng, step)
            try:
                snap = driver.cycle(goals)
            except GoalRejectedError as err:
                outcomes.append(("rejected", str(err)))
            else:
                want = _reference(driver)
                assert _snap_fields(snap) == want, (step, type(driver).__name__)
                outcomes.append((snap.t_s, snap.cycle, snap.events, snap.stats, snap.bus_connected, want))
                if step % 7 == 0:
                    kept.append((snap, want))
            chain.advance(DT_S)
        assert outcomes[0] == outcomes[1], step
    (chain_a, drv_a, _), (chain_b, drv_b, _) = runs
    assert [(round(e.t_s, 9), e.id, e.instruction, bytes(e.params)) for e in chain_a.log] == [
        (round(e.t_s, 9), e.id, e.instruction, bytes(e.params)) for e in chain_b.log
    ]
    assert list(drv_a.events) == list(drv_b.events)
    assert drv_a._sentinel and drv_b._sentinel  # positions through the sentinel
    assert all(_snap_fields(snap) == want for snap, want in kept)  # built late, after the records moved on
    assert isinstance(drv_a, CountingDriver)
    assert drv_a.calm > 150  # many cycles were calm ...
    assert drv_a.planned - drv_a.calm > 0  # ... some planned calm turned out not to be (a fault in the replies)
    assert drv_a._cycle - drv_a.planned > 50  # ... and many took the full path from the start
    assert {e.kind.value for e in drv_a.events} >= {"missing", "overload", "reconnected"}
    assert_goals_within_limits(chain_a, drv_a)
