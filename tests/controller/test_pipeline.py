"""`Pipeline.step`: one frame through muscle model, calibration, twin gate and driver, as a `FrameTrace`."""

from __future__ import annotations

import json
import math
import time
from collections.abc import Iterator

import numpy as np
import pytest
from servoface.controller.benchmarks.pipeline import wire_limit_hz
from servoface.controller.errors import ControllerError
from servoface.controller.face import Face
from servoface.controller.pipeline import Pipeline
from servoface.hardware.wire import cycle_budget
from servoface.sim.errors import SimError
from servoface.sim.gate import limits as lim


@pytest.fixture(scope="module")
def face() -> Iterator[Face]:
    f = Face.open("human", emulate=True, wire_time=False)
    yield f
    f.close(ease_s=0.0)


@pytest.fixture(scope="module")
def offline() -> Pipeline:
    return Face.offline("human").pipeline


def test_a_frame_trace_tells_what_happened(face: Face) -> None:
    p = face.pipeline
    before = face.bus.stats.bytes_written  # type: ignore[union-attr]
    trace = p.step({"AU1": 0.3, "AU2": 0.3}, t_s=1.25)
    assert trace.t_s == 1.25 and trace.aus == {"AU1": 0.3, "AU2": 0.3}
    assert set(trace.targets) == set(face.head.roles)
    assert trace.targets["brow_inner_l"] > face.pipeline.calibration["brow_inner_l"].neutral_target
    assert trace.goals_requested == p.calibration.targets_to_goals(p.clamp_targets(trace.targets)[0])
    assert trace.verdict in ("accept", "clip")
    assert trace.goals_sent == p.last_goals_tick
    assert trace.bytes_written == face.bus.stats.bytes_written - before > 0  # type: ignore[union-attr]
    assert set(trace.timings_ms) == {"muscle_ms", "calibration_ms", "gate_ms", "bus_ms", "total_ms"}
    assert all(v >= 0 for v in trace.timings_ms.values())
    d = json.loads(json.dumps(trace.as_dict()))
    assert d["verdict"] == trace.verdict and d["goals_sent"] == {str(k): v for k, v in trace.goals_sent.items()}


@pytest.mark.parametrize(
    "aus",
    [{"AU12": math.nan}, {"AU12": 2.0}, {"AU99": 0.1}, {"AU12": -0.5}],
    ids=["nan", "over", "unknown", "neg"],
)
def test_invalid_frames_raise_before_anything_is_sent(face: Face, aus: dict[str, float]) -> None:
    p = face.pipeline
    n_log, last, index = len(face.chain.log), dict(p.last_goals_tick), p._index
    with pytest.raises((ControllerError, SimError)):
        p.step(aus)
    assert len(face.chain.log) == n_log and p.last_goals_tick == last and p._index == index


def test_targets_outside_the_calibrated_range_are_clamped_with_reasons(offline: Pipeline) -> None:
    cal = offline.calibration
    asked = {"jaw": cal["jaw"].max_target + 10.0, "lip_corner_l": cal["lip_corner_l"].min_target - 3.0}
    clamped, reasons = offline.clamp_targets(asked)
    assert clamped["jaw"] == cal["jaw"].max_target and clamped["lip_corner_l"] == cal["lip_corner_l"].min_target
    assert len(reasons) == 2 and any("jaw" in r and "[target]" in r for r in reasons)
    assert clamped["neck_pan"] == cal["neck_pan"].neutral_target  # unnamed roles sit at neutral
    with pytest.raises(ControllerError, match="jaw"):
        offline.clamp_targets({"jaw": math.inf})


def test_offline_pipeline_runs_the_gate_without_a_bus(offline: Pipeline) -> None:
    trace = offline.step({"AU51": 1.0})  # a full head turn from neutral in one frame: too fast
    assert trace.verdict == "clip" and "speed" in trace.checks and trace.bytes_written == 0
    pan = offline.calibration.id_of("neck_pan")
    i = offline.gate.table.index()[pan]
    assert abs(trace.goals_sent[pan] - offline.calibration.neutral_goals()[pan]) <= offline.gate.table.max_step_tick[i]
    assert offline.hold() is None


def test_pin_to_unknown_servo_is_refused(offline: Pipeline) -> None:
    with pytest.raises(SimError, match="99"):
        offline.pin_to({99: 2048})


def test_hold_then_move_respects_the_acceleration_cap_on_the_wire(face: Face) -> None:
    """After `hold` re-sends the last goals (a zero step on the wire), the next step starts from rest."""
    p = face.pipeline
    pan = p.calibration.id_of("neck_pan")
    i = p.gate.table.index()[pan]
    for _ in range(6):  # accelerate the neck to its speed cap
        p.step({"AU51": 1.0})
    p.hold()
    p.step({"AU51": 1.0})
    ticks = [tick for _, sid, tick in face.chain.goal_writes() if sid == pan][-3:]
    steps = np.diff(ticks)
    assert steps[0] == 0  # the hold
    lo, hi = lim.step_bounds(np.zeros(p.gate.table.n, dtype=np.int64), p.gate.table)
    assert lo[i] <= steps[1] <= hi[i], f"neck_pan jumped {steps[1]} tick from rest (cap {hi[i]})"
    p.step({})  # back towards neutral for the next tests


def test_a_hot_servo_reaches_the_gate_as_health(face: Face) -> None:
    p = face.pipeline
    jaw = p.calibration.id_of("jaw")
    servo = face.chain.servo(jaw)
    limit = p.temperature_limits_c[jaw]
    old = servo.temperature_c
    servo.temperature_c = limit - 1.0
    try:
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline:  # thermal telemetry is read at its own (slower) rate
            p.hold()
            state = p.last_snapshot[jaw] if p.last_snapshot is not None else None
            if state is not None and state.temperature_c is not None and state.temperature_c >= limit - 2:
                break
            time.sleep(0.02)
        assert state is not None and state.temperature_c is not None and state.temperature_c >= limit - 2
        trace = p.step({"AU26": 0.3})
        assert "health" in trace.checks, trace.reasons
        assert any(f"servo {jaw} 'jaw'" in r for r in trace.reasons)
    finally:
        servo.temperature_c = old


def test_wire_limit_matches_hardware_wire_for_a_full_chain() -> None:
    hz, n_bytes = wire_limit_hz(24, 24, 1_000_000)
    budget = cycle_budget(24, 1_000_000)
    assert n_bytes == budget.bytes_total and hz == pytest.approx(budget.limit_hz)
    hz_21, _ = wire_limit_hz(21, 24, 1_000_000)
    assert hz_21 > hz  # fewer goals written, same reads
