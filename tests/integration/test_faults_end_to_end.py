"""A servo faults in the middle of a motion (overload shutdown on the emulated chain): the driver reports it,
the gate narrows that servo's range and speed with reasons naming it, the rest of the face carries on; after
the driver's cool-down the servo is rebooted and re-pinned where it stands, and the pipeline walks it back
to its goal within the step and acceleration caps (no jump from the re-pinned goal); closing still turns
every torque off."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from servoface.controller.face import Face
from servoface.controller.performance import Performance
from servoface.hardware.emulator import ServoChain
from servoface.sim.gate import ServoHealth
from servoface.sim.gate.health import derate


@dataclass
class Faulted:
    face: Face
    chain: ServoChain
    perf: Performance
    servo_id: int
    first_write: int  # index into chain.goal_writes() where the motion starts


@pytest.fixture(scope="module")
def faulted() -> Iterator[Faulted]:
    face = Face.open("human", emulate=True, wire_time=False)
    chain = face.chain
    sid = face.pipeline.calibration.id_of("lip_corner_l")
    try:
        first = len(chain.goal_writes())
        chain.faults.inject(sid, "overload", duration_s=0.15)
        assert face.driver is not None
        cooldown_s = face.driver.policy.overload_cooldown_s  # then the driver reboots the servo
        perf = face.set_aus({"AU12": 0.4}, transition_s=0.3, hold_s=cooldown_s + 0.8)
        yield Faulted(face, chain, perf, sid, first)
    finally:
        face.close(ease_s=0.3)
        assert all(not chain.servo(s).torque_on for s in chain.ids)


def test_the_driver_reports_the_fault_and_the_gate_names_the_servo(faulted: Faulted) -> None:
    health = [t for t in faulted.perf.traces if "health" in t.checks]  # from the driver's snapshots
    assert health, "the gate never heard of the overload"
    assert all(any(f"servo {faulted.servo_id} 'lip_corner_l' overloaded" in r for r in t.reasons) for t in health)
    snap = faulted.face.pipeline.last_snapshot
    assert snap is not None and not snap[faulted.servo_id].faults  # recovered by the end


def test_the_faulted_servo_stays_in_its_narrowed_range(faulted: Faulted) -> None:
    gate = faulted.face.pipeline.gate
    i = gate.table.index()[faulted.servo_id]
    narrowed, _ = derate(
        gate.table, {faulted.servo_id: ServoHealth(25.0, 70.0, 0.0, overloaded=True)}, gate.config.health
    )
    lo, hi = int(narrowed.min_tick[i]), int(narrowed.max_tick[i])
    full = int(gate.table.max_tick[i]) - int(gate.table.min_tick[i])
    assert hi - lo < full  # the health policy really narrows it
    health = [t for t in faulted.perf.traces if "health" in t.checks]
    for t in health:
        assert lo <= t.goals_sent[faulted.servo_id] <= hi, t.reasons
    assert len(health) < len(faulted.perf.traces) - 5  # and it was lifted after the recovery


def test_after_recovery_the_servo_is_walked_back_within_the_caps(faulted: Faulted) -> None:
    gate = faulted.face.pipeline.gate
    i = gate.table.index()[faulted.servo_id]
    cap, speedup = int(gate.table.max_step_tick[i]), int(gate.table.max_speedup_tick[i])
    writes = [(t, g) for t, s, g in faulted.chain.goal_writes()[faulted.first_write :] if s == faulted.servo_id]
    # out of service the driver writes nothing; its recovery re-pins the goal where the servo stands (a
    # safety write, not a motion): check each run of writes on its own, from rest
    gaps = [b[0] - a[0] for a, b in zip(writes, writes[1:], strict=False)]
    k = 1 + max(range(len(gaps)), key=gaps.__getitem__)
    assert gaps[k - 1] > 1.0, "no out-of-service gap: the fault did not take the servo out"
    ticks = [g for _, g in writes]
    for run in (ticks[:k], ticks[k:]):
        steps = [b - a for a, b in zip(run, run[1:], strict=False)]
        assert all(abs(d) <= cap for d in steps), steps
        for prev, d in zip([0, *steps], steps, strict=False):  # accelerating from the step before, at most
            assert abs(d) <= (abs(prev) if prev * d > 0 else 0) + speedup, steps
    assert faulted.chain.servo(faulted.servo_id).torque_on
    state = faulted.face.pipeline.last_snapshot[faulted.servo_id]  # type: ignore[index]
    assert state.torque_on and not state.faults
    last = faulted.perf.traces[-1]
    assert ticks[-1] == last.goals_sent[faulted.servo_id] == last.goals_requested[faulted.servo_id]
    assert abs(faulted.chain.servo(faulted.servo_id).position_tick - ticks[-1]) <= 2


def test_the_rest_of_the_face_reaches_its_goal(faulted: Faulted) -> None:
    last = faulted.perf.traces[-1]
    other = faulted.face.pipeline.calibration.id_of("lip_corner_r")
    neutral = faulted.face.pipeline.calibration.neutral_goals()
    assert last.goals_sent[other] == last.goals_requested[other] != neutral[other]
