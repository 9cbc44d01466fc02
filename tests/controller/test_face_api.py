"""The `Face` API on the emulated chain: good calls move the head through the gate; bad input raises a
clear error naming the field, and NOTHING reaches the bus (no goal write, no packet at all)."""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from servoface.controller.errors import ControllerError
from servoface.controller.face import Face
from servoface.controller.script import SCRIPTS_DIR
from servoface.hardware.emulator import ServoChain


@pytest.fixture(scope="module")
def face() -> Iterator[Face]:
    f = Face.open("human", emulate=True, wire_time=False)
    yield f
    f.close(ease_s=0.0)


def _bus_state(face: Face) -> tuple[int, int, int]:
    chain: ServoChain = face.chain
    assert face.bus is not None
    return len(chain.goal_writes()), len(chain.log), face.bus.stats.transactions


BAD_CALLS: list[tuple[str, Any, str]] = [
    ("non-finite AU", lambda f: f.set_aus({"AU12": math.nan}), "AU12"),
    ("infinite AU", lambda f: f.set_aus({"AU1": math.inf}), "AU1"),
    ("unknown AU", lambda f: f.set_aus({"AU99": 0.5}), "AU99"),
    ("dog AU on a human face", lambda f: f.set_aus({"AD101": 0.5}), "AD101"),
    ("AU above 1", lambda f: f.set_aus({"AU12": 1.5}), "AU12"),
    ("negative human AU", lambda f: f.set_aus({"AU2": -0.2}), "AU2"),
    ("AU not a number", lambda f: f.set_aus({"AU12": "high"}), "AU12"),
    ("negative transition", lambda f: f.set_aus({"AU12": 0.3}, transition_s=-1.0), "transition_s"),
    ("non-finite hold", lambda f: f.set_aus({"AU12": 0.3}, hold_s=math.nan), "hold_s"),
    ("unknown expression", lambda f: f.express("glee"), "glee"),
    ("intensity above 1", lambda f: f.express("happiness", intensity=1.5), "intensity"),
    ("negative intensity", lambda f: f.express("happiness", intensity=-0.1), "intensity"),
    ("non-finite intensity", lambda f: f.express("happiness", intensity=math.nan), "intensity"),
    ("look_at two numbers", lambda f: f.look_at((100.0, 0.0)), "point_mm"),
    ("look_at nan", lambda f: f.look_at((math.nan, 0.0, 500.0)), "point_mm"),
    ("look_at text", lambda f: f.look_at(("a", "b", "c")), "point_mm"),
    ("look_at a bare number", lambda f: f.look_at(5.0), "point_mm"),
    ("look_at None", lambda f: f.look_at(None), "point_mm"),
    ("look_at bools", lambda f: f.look_at((True, False, True)), "point_mm"),
    ("dog script on a human head", lambda f: f.play(SCRIPTS_DIR / "dog_performance.toml"), "dog"),
    ("missing script", lambda f: f.play(Path("/nonexistent/script.toml")), "script.toml"),
    ("negative hold", lambda f: f.hold(-1.0), "hold_s"),
]


@pytest.mark.parametrize("what,call,named", BAD_CALLS, ids=[c[0] for c in BAD_CALLS])
def test_bad_input_raises_and_sends_nothing(face: Face, what: str, call: Any, named: str) -> None:
    face.hold(0.0)  # the head service runs; paused, its loop sends nothing while we watch the wire
    with face.service.paused_loop():
        before = _bus_state(face)
        last = dict(face.pipeline.last_goals_tick)
        pose = dict(face.pose)
        n_traces = len(face.traces)
        with pytest.raises(ControllerError) as err:
            call(face)
        assert named in str(err.value), f"{what}: message does not name {named!r}: {err.value}"
        assert _bus_state(face) == before, f"{what}: something reached the bus"
        assert face.pipeline.last_goals_tick == last and face.pose == pose and len(face.traces) == n_traces
        assert not face.service._inbox, f"{what}: a command was queued"


def test_set_aus_moves_through_the_gate_and_the_bus(face: Face) -> None:
    writes0, _, _ = _bus_state(face)
    perf = face.set_aus({"AU1": 0.4, "AU2": 0.4}, transition_s=0.2, hold_s=0.06)
    assert perf.traces and face.pose == {"AU1": 0.4, "AU2": 0.4}
    n = len(face.head.actuators)
    wire: dict[float, dict[int, int]] = {}  # one Sync Write per frame: the goals of each, by arrival time
    for t, sid, tick in face.chain.goal_writes()[writes0:]:
        wire.setdefault(t, {})[sid] = tick
    assert all(len(g) == n for g in wire.values())
    sent = list(wire.values())
    assert all(trace.goals_sent in sent for trace in perf.traces)  # every frame of the call went out whole
    last = perf.traces[-1]
    assert last.aus["AU1"] == pytest.approx(0.4) and last.goals_sent == face.pipeline.last_goals_tick
    brow = face.pipeline.calibration.id_of("brow_inner_l")
    assert abs(last.goals_sent[brow] - face.pipeline.calibration.neutral_goals()[brow]) > 10
    # everything was written as the gate passed it: the bus's last goals are the traces'
    tail = {sid: tick for _, sid, tick in face.chain.goal_writes()[-n:]}
    assert tail == last.goals_sent


def test_express_and_neutral(face: Face) -> None:
    perf = face.express("surprise", intensity=0.5, transition_s=0.2, hold_s=0.0)
    assert face.pose and all(v <= 0.5 + 1e-9 for v in face.pose.values())
    assert perf.verdicts["accept"] + perf.verdicts["clip"] + perf.verdicts["reject"] == len(perf.traces)
    face.neutral(transition_s=0.3)
    assert face.pose == {} or all(abs(v) < 1e-9 for v in face.pose.values())
    cal = face.pipeline.calibration
    assert face.pipeline.last_goals_tick == cal.targets_to_goals(face.pipeline.face.solve({}).actuator_targets)


def test_a_motion_faster_than_the_servos_still_arrives(face: Face) -> None:
    """One frame to turn the head fully: the gate caps every step, and the call keeps walking the servos
    (each step within the cap) until the frame passes whole; it does not return half way."""
    p = face.pipeline
    pan = p.calibration.id_of("neck_pan")
    cap = int(p.gate.table.max_step_tick[p.gate.table.index()[pan]])
    perf = face.set_aus({"AU51": 1.0}, transition_s=0.0)
    last = perf.traces[-1]
    assert last.goals_sent == last.goals_requested == p.last_goals_tick
    ticks = [t.goals_sent[pan] for t in perf.traces]
    assert abs(ticks[-1] - p.calibration.neutral_goals()[pan]) > 3 * cap  # a long way: many capped frames
    assert all(abs(b - a) <= cap for a, b in zip(ticks, ticks[1:], strict=False))
    face.neutral(transition_s=0.0)
    assert p.last_goals_tick[pan] == p.calibration.neutral_goals()[pan]


def test_look_at_turns_eyes_to_the_side_of_the_point(face: Face) -> None:
    face.look_at((300.0, 0.0, 600.0), transition_s=0.3)  # to the head's left
    assert face.pose.get("AU61", 0.0) > 0 or face.pose.get("AU51", 0.0) > 0, face.pose
    face.look_at((0.0, 0.0, 600.0), transition_s=0.3)
    assert not any(face.pose.get(au, 0.0) > 0.05 for au in ("AU61", "AU62", "AU51", "AU52"))


def test_open_needs_exactly_one_of_port_or_emulate() -> None:
    with pytest.raises(ControllerError, match="exactly one"):
        Face.open("human")
    with pytest.raises(ControllerError, match="exactly one"):
        Face.open("human", port="/dev/null", emulate=True)


def test_closed_face_refuses_and_torque_is_off() -> None:
    f = Face.open("human", emulate=True, wire_time=False)
    chain = f.chain
    f.set_aus({"AU12": 0.3}, transition_s=0.1)
    f.close(ease_s=0.2)
    assert all(not chain.servo(sid).torque_on for sid in chain.ids)
    # closing eased back to neutral first
    neutral = f.pipeline.calibration.neutral_goals()
    assert max(abs(f.pipeline.last_goals_tick[s] - neutral[s]) for s in neutral) <= 2
    f.close()  # twice is fine
    with pytest.raises(ControllerError, match="closed"):
        f.set_aus({"AU12": 0.3})


def test_open_on_a_missing_port_names_it() -> None:
    from servoface.hardware.errors import HardwareError

    with pytest.raises(HardwareError, match="/dev/does-not-exist"):
        Face.open("human", port="/dev/does-not-exist")


def test_open_with_a_servo_missing_names_it_and_switches_no_torque_on() -> None:
    from servoface.controller.face import head_calibration
    from servoface.controller.head_servos import servo_specs
    from servoface.hardware.errors import HardwareError
    from servoface.sim.heads import load_head

    head = load_head("human")
    specs = [s for s in servo_specs(head, head_calibration(head)) if s.servo_id != 9]
    chain = ServoChain.create([(s.servo_id, s.model) for s in specs], baud=1_000_000, wire_time=False)
    try:
        with pytest.raises(HardwareError) as err:
            Face.open(head, port=chain.serve_pty())
        assert re.search(r"\b9\b", str(err.value)), err.value  # names the missing servo
        assert all(not chain.servo(sid).torque_on for sid in chain.ids)
        assert chain.goal_writes() == []
    finally:
        chain.close()
