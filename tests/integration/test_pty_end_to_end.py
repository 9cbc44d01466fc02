"""End to end over a pseudo-terminal with the STOCK dynamixel_sdk: script -> muscle model -> calibration ->
twin gate -> driver -> PortHandler -> pty -> emulated chain (wire time on). After settling, the emulated
servos stand where the twin says the gate's last goals put them, and the twin's pose of those goals is the
calibration's."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest
from servoface.controller.face import Face, head_calibration
from servoface.controller.head_servos import servo_specs
from servoface.controller.performance import Performance
from servoface.hardware.emulator import ServoChain
from servoface.sim.heads import load_head

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals need a POSIX system")

SCRIPT = """
[script]
face = "human"
title = "integration: smile, then a brow raise"
end_s = 1.4

[poses]
smile = { AU6 = 0.2, AU12 = 0.4, AU25 = 0.1 }  # moderate: within the skin-strain limit at apex
brows = { AU1 = 0.4, AU2 = 0.4 }

[expressions.smile]
duration_s = 0.7
movements = [
  { pose = "smile", percent = 60, easing = "min_jerk" },
  { pose = "smile", percent = 40 },
]

[expressions.brows]
duration_s = 0.6
movements = [
  { pose = "brows", percent = 60, easing = "min_jerk" },
  { pose = "brows", percent = 40 },
]

[[play]]
at_s = 0.05
sequence = ["smile", "brows"]

[blink]
enabled = false

[idle]
enabled = false
"""


@dataclass
class Run:
    chain: ServoChain
    face: Face
    perf: Performance
    port: str
    positions_tick: dict[int, int]


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Run]:
    head = load_head("human")
    cal = head_calibration(head)
    specs = servo_specs(head, cal)
    chain = ServoChain.create([(s.servo_id, s.model) for s in specs], baud=1_000_000, wire_time=True)
    for s in specs:  # the head powers up at rest (Face.open does this itself only with emulate=True)
        chain.servo(s.servo_id).move_by_hand(cal.by_id(s.servo_id).neutral_tick)
    port = chain.serve_pty()
    script = tmp_path_factory.mktemp("script") / "smile_brows.toml"
    script.write_text(SCRIPT)
    face = Face.open(head, port=port, baud=1_000_000)
    try:
        perf = face.play(script)
        face.hold(0.8)  # settle: the servos reach the last goals
        positions = {sid: chain.servo(sid).position_tick for sid in chain.ids}
        yield Run(chain, face, perf, port, positions)
    finally:
        face.close(ease_s=0.0)
        chain.close()


def test_the_stock_sdk_talked_to_the_pty(run: Run) -> None:
    from servoface.hardware.dynamixel_bus import DynamixelBus

    bus = run.face.bus
    assert isinstance(bus, DynamixelBus)
    import dynamixel_sdk as sdk

    # a path-opened port: the SDK's own PortHandler (serial.Serial on the pty), not the in-process shortcut
    assert isinstance(bus._port, sdk.PortHandler)
    assert type(bus._port.ser).__module__.startswith("serial")
    assert run.port.startswith("/dev/")
    assert bus.stats.corrupt == 0
    # a timeout (the pty thread descheduled on a busy machine) is retried by the driver; keep them rare
    assert bus.stats.timeouts <= max(1, bus.stats.transactions // 100), vars(bus.stats)
    # the chain heard sync writes of goals for every servo of the head, frame after frame
    goal_ids = {sid for _, sid, _ in run.chain.goal_writes()}
    assert goal_ids == set(run.chain.ids)
    assert len(run.perf.traces) >= 20


def test_the_script_moved_the_face(run: Run) -> None:
    cal = run.face.pipeline.calibration
    last = run.face.pipeline.last_goals_tick
    neutral = cal.neutral_goals()
    moved = {cal.role_of(sid) for sid in last if abs(last[sid] - neutral[sid]) > 10}
    assert {"brow_inner_l", "brow_inner_r"} <= moved  # the brow raise is held at the end
    smiled = [t for t in run.perf.traces if t.aus.get("AU12", 0.0) > 0.35]
    assert smiled, "the smile never reached its apex"
    lip = cal.id_of("lip_corner_l")
    assert any(abs(t.goals_sent[lip] - neutral[lip]) > 10 for t in smiled)
    # a frame the gate rejects holds the previous command; the others go out as the gate passed them
    prev = None
    for t in run.perf.traces:
        assert t.verdict in ("accept", "clip", "reject")
        if t.verdict == "reject" and prev is not None:
            assert t.goals_sent == prev
        if t.verdict == "accept":
            assert t.goals_sent == t.goals_requested
        prev = t.goals_sent


def test_servos_end_where_the_gate_last_sent(run: Run) -> None:
    goals = run.face.pipeline.last_goals_tick
    assert set(goals) == set(run.chain.ids)
    errors = {sid: abs(run.positions_tick[sid] - goals[sid]) for sid in goals}
    assert max(errors.values()) <= 1, f"present vs goal (tick): {errors}"
    # and the driver's own read over the pty agrees with the emulator's registers
    assert run.face.driver is not None
    with run.face.service.paused_loop():  # the bus is the head service's; borrow it for one read
        snap = run.face.driver.read_state()
    read = snap.positions_tick()
    assert all(abs(read[sid] - run.positions_tick[sid]) <= 1 for sid in goals)


def test_the_twin_pose_of_the_last_goals_is_the_calibrations(run: Run) -> None:
    face = run.face
    goals = face.pipeline.last_goals_tick
    joint_deg, offsets_mm, targets = face.pipeline.gate.twin_pose(goals)
    cal_targets = face.pipeline.calibration.goals_to_targets(goals)
    assert set(targets) == set(cal_targets) == set(face.head.roles)
    for role, value in cal_targets.items():
        assert targets[role] == pytest.approx(value, abs=1e-9), role
    # the calibration's targets posed by the face model's twin give the same joints and skin
    expected = face.pipeline.face.pose_from_targets(cal_targets)
    for joint, deg in expected.joint_deg.items():
        assert joint_deg[joint] == pytest.approx(deg, abs=1e-6), joint
    assert offsets_mm.shape == expected.skin_offset_mm.shape
    np.testing.assert_allclose(offsets_mm, expected.skin_offset_mm, atol=1e-6)
    # and the posed servos stand within a tick of those goals: their present targets match the twin's
    present = face.pipeline.calibration.goals_to_targets(run.positions_tick, clip=True)
    for role, value in targets.items():
        res = face.pipeline.calibration[role].target_resolution()
        assert abs(present[role] - value) <= 1.5 * res + 1e-9, role


def test_torque_is_on_while_the_face_is_open(run: Run) -> None:
    assert all(run.chain.servo(sid).torque_on for sid in run.chain.ids)


def test_servo_side_limits_are_the_calibrations_backstop(run: Run) -> None:
    """Face.open wrote each servo's Min/Max Position Limit (EEPROM, over the pty) from the calibration,
    a little wider than the gate's limits so the backstop never fights a legal goal."""
    cal = run.face.pipeline.calibration
    specs = {s.servo_id: s for s in servo_specs(run.face.head, cal)}
    for sid in run.chain.ids:
        servo = run.chain.servo(sid)
        lo, hi = servo.read_register("Min Position Limit"), servo.read_register("Max Position Limit")
        c = cal.by_id(sid)
        assert (lo, hi) == (specs[sid].min_position_tick, specs[sid].max_position_tick)
        assert lo < c.min_tick <= c.max_tick < hi, (sid, lo, hi, c.min_tick, c.max_tick)
        assert servo.read_register("Return Delay Time") == specs[sid].return_delay_us // 2
