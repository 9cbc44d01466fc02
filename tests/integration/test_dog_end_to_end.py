"""The dog head end to end on the emulated chain: the shipped dog performance (signed DFACS AUs, counter AUs
included) through muscle model, calibration, gate and driver; the wire stays inside limits and caps, and
after settling the servos stand on the gate's last goals, whose twin pose is the calibration's.

The full gate runs, part collisions included: built from nothing, the dog's TSS tables take a few seconds
(cached per geometry in ~/.cache/servoface/tss afterwards)."""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest
from servoface.controller.face import head_calibration
from servoface.controller.head_servos import servo_specs, temperature_limits_c
from servoface.controller.pipeline import FrameTrace, Pipeline
from servoface.controller.script import SCRIPTS_DIR, load_script
from servoface.hardware.bus import open_bus
from servoface.hardware.driver import Driver
from servoface.hardware.emulator import ServoChain
from servoface.sim.heads import load_head

from tests.integration.wire_checks import check_wire

RATE_HZ = 50.0


@dataclass
class DogRun:
    pipeline: Pipeline
    chain: ServoChain
    traces: list[FrameTrace]


@pytest.fixture(scope="module")
def dog() -> Iterator[DogRun]:
    head = load_head("dog")
    cal = head_calibration(head)
    specs = servo_specs(head, cal)
    chain = ServoChain.create([(s.servo_id, s.model) for s in specs], baud=1_000_000, wire_time=False)
    for s in specs:
        chain.servo(s.servo_id).move_by_hand(cal.by_id(s.servo_id).neutral_tick)
    bus = open_bus("dynamixel", port=chain, baud=1_000_000)
    driver = Driver(bus, specs)
    try:
        driver.configure()
        driver.torque_on()
        frame_clock_s = [0.0]  # the pipeline's clock is the script's: each step is one 50 Hz frame later
        pipeline = Pipeline(
            head,
            cal,
            driver=driver,
            rate_hz=RATE_HZ,
            temperature_limits_c=temperature_limits_c(specs),
            clock=lambda: frame_clock_s[0],
        )
        pipeline.pin_to(driver.read_state().positions_tick())
        script = load_script(SCRIPTS_DIR / "dog_performance.toml")
        # time-driven samples at 50 Hz, stepped back to back in wall time but a frame apart on the pipeline's
        # clock, so the per-second caps allow what a 50 Hz loop gets (the servo physics lags; the wire counts)
        n = int(script.end_s * RATE_HZ) + 1
        traces = []
        for k in range(n):
            frame_clock_s[0] = k / RATE_HZ
            traces.append(pipeline.step(script.sample(k / RATE_HZ), k / RATE_HZ))
        yield DogRun(pipeline, chain, traces)
    finally:
        driver.close(torque_off=True)
        chain.close()


def test_the_performance_uses_signed_aus_and_moves_the_dog(dog: DogRun) -> None:
    assert len(dog.traces) > 100
    values = [v for t in dog.traces for v in t.aus.values()]
    assert min(values) < 0 < max(values)  # counter AUs (negative DFACS values) and positive ones
    cal = dog.pipeline.calibration
    neutral = cal.neutral_goals()
    moved = {cal.role_of(sid) for t in dog.traces for sid, g in t.goals_sent.items() if abs(g - neutral[sid]) > 20}
    assert {"ear_pan_l", "ear_pan_r", "jaw"} <= moved, moved
    assert any(t.verdict == "accept" for t in dog.traces)
    for t in dog.traces:
        if t.verdict != "accept":
            assert t.reasons and t.checks


def test_every_goal_on_the_wire_is_safe(dog: DogRun) -> None:
    n = check_wire(dog.pipeline, dog.chain)
    assert n >= len(dog.traces) * len(dog.pipeline.head.actuators)


def test_after_settling_the_servos_stand_where_the_twin_says(dog: DogRun) -> None:
    p = dog.pipeline
    final = dog.traces[-1]
    deadline = time.monotonic() + 3.0
    while time.monotonic() < deadline:  # keep holding (and walking capped goals home) until all servos arrive
        trace = p.step(final.aus)
        errors = {sid: abs(dog.chain.servo(sid).position_tick - g) for sid, g in p.last_goals_tick.items()}
        if trace.goals_sent == trace.goals_requested and max(errors.values()) <= 1:
            break
        time.sleep(1.0 / RATE_HZ)
    assert max(errors.values()) <= 1, errors
    joint_deg, offsets_mm, targets = p.gate.twin_pose(p.last_goals_tick)
    cal_targets = p.calibration.goals_to_targets(p.last_goals_tick)
    assert targets == pytest.approx(cal_targets, abs=1e-9)
    expected = p.face.pose_from_targets(cal_targets)
    assert joint_deg == pytest.approx(expected.joint_deg, abs=1e-6)
    np.testing.assert_allclose(offsets_mm, expected.skin_offset_mm, atol=1e-6)
