"""The twin gate on the synthetic demo head: verdicts, reasons, clamps, scale-back, health, input checks."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from servoface.sim.gate import GateConfig, ServoHealth, TwinGate
from servoface.sim.gate.demo_rig import demo_calibration, demo_head
from servoface.sim.gate.errors import GateConfigError, GateInputError
from servoface.sim.gate.strain import StrainLimits


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.getbasetemp() / "tss-demo"  # shared by the demo-head modules: built once


@pytest.fixture(scope="module")
def gate(cache: Path) -> TwinGate:
    head = demo_head()
    return TwinGate(head, demo_calibration(head), 1 / 60, GateConfig(cache_dir=cache))


@pytest.fixture(scope="module")
def fast_gate(cache: Path) -> TwinGate:
    """Rate caps wide open, so limits/collision/strain checks can be reached in one frame."""
    head = demo_head()
    roles = [a.role for a in head.actuators]
    cfg = GateConfig(cache_dir=cache, max_step_tick={r: 4000 for r in roles}, max_speedup_tick={r: 4000 for r in roles})
    return TwinGate(head, demo_calibration(head), 1 / 60, cfg)


def tick_for(gate: TwinGate, role: str, target: float) -> int:
    """The goal tick for an actuator target, clipped into the calibrated range."""
    s = gate.poser.calibration[role]
    return int(s.to_tick(float(np.clip(target, s.min_target, s.max_target))))


def test_neutral_is_accepted(gate: TwinGate) -> None:
    n = gate.neutral_goals()
    v = gate.check(n, n)
    assert v.kind == "accept" and v.goals_tick == n and v.findings == ()


def test_small_step_is_accepted_and_sends_the_request(gate: TwinGate) -> None:
    n = gate.neutral_goals()
    req = dict(n)
    req[1] += 20
    v = gate.check(req, n)
    assert v.kind == "accept" and v.goals_tick == req


def test_speed_and_accel_clip_per_servo_with_numbers(gate: TwinGate) -> None:
    n = gate.neutral_goals()
    req = dict(n)
    req[1] += 300
    v = gate.check(req, n)
    assert v.kind == "clip"
    step = v.goals_tick[1] - n[1]
    assert 0 < step <= gate.table.max_speedup_tick[0]  # from rest: the acceleration cap binds first
    speed = [f for f in v.findings if f.check == "speed"]
    assert speed and speed[0].servo_id == 1 and speed[0].role == "neck_pan" and "300" in speed[0].message
    assert speed[0].limit == gate.table.max_step_tick[0]


def test_acceleration_uses_the_previous_step(gate: TwinGate) -> None:
    n = gate.neutral_goals()
    a = int(gate.table.max_speedup_tick[0])
    first = dict(n)
    first[1] += a // 2
    assert gate.check(first, n).kind == "accept"
    second = dict(first)
    second[1] += a // 2 + a  # speeding up by exactly the cap is allowed
    assert gate.check(second, first).kind == "accept"
    third = dict(second)
    third[1] += a // 2 + 2 * a + 5  # speeding up by more is not (while still under the speed cap)
    assert a // 2 + 2 * a + 5 <= gate.table.max_step_tick[0]
    v = gate.check(third, second)
    assert v.kind == "clip" and v.checks == ("accel",) and v.goals_tick[1] - second[1] == a // 2 + 2 * a


def test_position_limit_clamps_to_the_servo_max(fast_gate: TwinGate) -> None:
    n = fast_gate.neutral_goals()
    req = dict(n)
    req[3] = 4000  # ear_pan_l far past its max
    v = fast_gate.check(req, n)
    assert v.kind == "clip" and "limit" in v.checks
    i = fast_gate.table.index()[3]
    assert v.goals_tick[3] <= fast_gate.table.max_tick[i]
    f = next(f for f in v.findings if f.check == "limit")
    assert f.servo_id == 3 and "ear_pan_l" in f.message and "4000" in f.message


def test_jaw_into_skull_is_clipped_to_a_collision_free_command_closer_than_holding(
    fast_gate: TwinGate,
) -> None:
    n = fast_gate.neutral_goals()
    req = dict(n)
    req[2] = tick_for(fast_gate, "jaw", -8.0)  # closing 8 deg drives the jaw plate into the skull
    v = fast_gate.check(req, n)
    assert v.kind == "clip" and "collision" in v.checks
    f = next(f for f in v.findings if f.check == "collision")
    assert set(f.parts) == {"skull", "jaw"}
    assert fast_gate.audit(v.goals_tick) == []
    assert abs(v.goals_tick[2] - req[2]) < abs(n[2] - req[2])
    assert 0.0 < v.step_fraction < 1.0


def test_reject_holds_the_last_safe_command(fast_gate: TwinGate) -> None:
    n = fast_gate.neutral_goals()
    # the last command has the jaw already at the contact angle; closing further has no safe fraction
    last = dict(n)
    last[2] = tick_for(fast_gate, "jaw", -1.2)
    req = dict(last)
    req[2] = tick_for(fast_gate, "jaw", -6.0)
    v = fast_gate.check(req, last)
    assert v.kind == "reject" and v.goals_tick == last and v.step_fraction == 0.0
    assert "collision" in v.checks and v.requested_tick == req


def test_coupling_rule_fires_with_roles_and_shares(fast_gate: TwinGate) -> None:
    n = fast_gate.neutral_goals()
    req = dict(n)
    req[6] = tick_for(fast_gate, "lip_corner_l", 12.0)
    req[7] = tick_for(fast_gate, "lip_depressor_l", 12.0)
    v = fast_gate.check(req, n)
    assert v.kind == "clip" and "coupling" in v.checks
    f = next(f for f in v.findings if f.check == "coupling")
    assert "lip_corner_l" in f.message and "lip_depressor_l" in f.message and f.value is not None and f.value > 1.0
    _, _, targets = fast_gate.twin_pose(v.goals_tick)
    assert targets["lip_corner_l"] / 12.0 + targets["lip_depressor_l"] / 12.0 <= 1.0 + 1e-9


def test_skin_strain_and_flip_findings(cache: Path) -> None:
    head = demo_head()
    roles = [a.role for a in head.actuators]
    cfg = GateConfig(
        cache_dir=cache,
        strain=StrainLimits(max_stretch=1.05, min_compression=0.95),
        max_step_tick={r: 4000 for r in roles},
        max_speedup_tick={r: 4000 for r in roles},
    )
    g = TwinGate(head, demo_calibration(head), 1 / 60, cfg)
    n = g.neutral_goals()
    req = dict(n)
    req[2] = tick_for(g, "jaw", 25.0)  # wide open jaw stretches the lower skin rows
    v = g.check(req, n)
    assert "strain" in v.checks and v.kind == "clip"
    f = next(f for f in v.findings if f.check == "strain")
    assert f.value is not None and f.value > 1.05 and "rest" in f.message
    assert g.audit(v.goals_tick) == []


def test_a_hot_servo_gets_a_narrow_range_and_less_speed(fast_gate: TwinGate) -> None:
    n = fast_gate.neutral_goals()
    req = dict(n)
    req[3] = fast_gate.table.max_tick[2]
    hot = {3: ServoHealth(temperature_c=68.0, temperature_limit_c=70.0, load_ratio=0.2, hot=True)}
    v = fast_gate.check(req, n, health=hot)
    assert v.kind == "clip" and "health" in v.checks and "limit" in v.checks
    span = fast_gate.table.max_tick[2] - n[3]
    assert v.goals_tick[3] - n[3] <= 0.3 * span + 1
    f = next(f for f in v.findings if f.check == "health")
    assert f.servo_id == 3 and "hot" in f.message
    cool = {3: ServoHealth(temperature_c=40.0, temperature_limit_c=70.0, load_ratio=0.2)}
    assert fast_gate.check(req, n, health=cool).kind == "accept"


def test_overload_flag_derates_too(fast_gate: TwinGate) -> None:
    n = fast_gate.neutral_goals()
    req = dict(n)
    req[1] = fast_gate.table.max_tick[0]
    v = fast_gate.check(req, n, health={1: ServoHealth(35.0, 70.0, 1.2, overloaded=True)})
    assert "overloaded" in next(f for f in v.findings if f.check == "health").message
    assert v.goals_tick[1] < req[1]


@pytest.mark.parametrize("bad", [2048.5, float("nan"), math.inf, "2048", True, None])
def test_bad_goal_values_are_rejected_with_a_reason(gate: TwinGate, bad: object) -> None:
    n = gate.neutral_goals()
    req: dict[object, object] = dict(n)
    req[2] = bad
    v = gate.check(req, n)  # type: ignore[arg-type]
    assert v.kind == "reject" and v.goals_tick == n
    f = next(f for f in v.findings if f.check == "input")
    assert f.servo_id == 2 and "jaw" in f.message


def test_unknown_id_is_rejected(gate: TwinGate) -> None:
    n = gate.neutral_goals()
    v = gate.check({**n, 99: 2048}, n)
    assert v.kind == "reject" and "99" in v.findings[0].message and v.goals_tick == n


def test_partial_command_keeps_other_servos(gate: TwinGate) -> None:
    n = gate.neutral_goals()
    v = gate.check({1: n[1] + 10}, n)
    assert v.kind == "accept" and v.goals_tick == {**n, 1: n[1] + 10}


def test_numpy_integers_are_accepted(gate: TwinGate) -> None:
    n = gate.neutral_goals()
    v = gate.check({k: np.int64(t) for k, t in n.items()}, n)
    assert v.kind == "accept" and all(type(t) is int for t in v.goals_tick.values())


def test_bad_last_goals_is_a_contract_error(gate: TwinGate) -> None:
    n = gate.neutral_goals()
    partial = dict(n)
    del partial[5]
    with pytest.raises(GateInputError, match="missing servo id"):
        gate.check(n, partial)
    with pytest.raises(GateInputError, match="not an integer"):
        gate.check(n, {**n, 4: 1.5})
    with pytest.raises(GateInputError, match="unknown servo id"):
        gate.check(n, n, health={42: ServoHealth(30.0, 70.0, 0.1)})


def test_check_batch_matches_check_on_limits_and_rates(gate: TwinGate) -> None:
    n = np.array([gate.neutral_goals()[i] for i in gate.table.ids])
    rng = np.random.default_rng(3)
    goals = n + rng.integers(-120, 120, size=(200, gate.table.n))
    rep = gate.check_batch(goals, n)
    assert rep.ok.shape == (200,)
    for k in range(0, 200, 20):
        v = gate.check(
            dict(zip(gate.table.ids, goals[k].tolist(), strict=True)),
            dict(zip(gate.table.ids, n.tolist(), strict=True)),
        )
        rate_fired = bool({"limit", "speed", "accel"} & set(v.checks))
        assert rate_fired == (not (rep.limit_ok[k] and rep.speed_ok[k] and rep.accel_ok[k]))
    with pytest.raises(GateInputError):
        gate.check_batch(goals.astype(float), n)


def test_calibration_that_does_not_match_the_head_is_refused() -> None:
    head = demo_head()
    other = demo_head()
    cal = demo_calibration(other)
    from dataclasses import replace

    trimmed = replace(head, actuators=head.actuators[:-1])
    with pytest.raises(GateConfigError, match="lip_depressor_l"):
        TwinGate(trimmed, cal, 1 / 60, GateConfig(use_cache=False))


def test_servo_held_at_its_narrowed_limit_is_a_clip_not_a_reject(fast_gate: TwinGate) -> None:
    """The overload scenario: a derated servo already sits at its narrowed limit, the request still asks
    for more and everything else has arrived. The clamp is the last command: a clip at the limit (same
    goals as holding), not 'no safe command found'."""
    fast_gate.reset()
    n = fast_gate.neutral_goals()
    over = {1: ServoHealth(35.0, 70.0, 1.2, overloaded=True)}
    req = dict(n)
    req[1] = int(fast_gate.table.max_tick[0])
    last = dict(n)
    for _ in range(200):  # walk servo 1 up to its narrowed limit
        v = fast_gate.check(req, last, health=over)
        if v.goals_tick == last:
            break
        last = v.goals_tick
    assert v.goals_tick == last and last[1] < req[1]
    assert v.kind == "clip" and v.step_fraction == 1.0
    assert "limit" in v.checks and "health" in v.checks and "hold" not in v.checks
    assert fast_gate.audit(v.goals_tick) == []


def test_request_beyond_the_max_from_the_max_is_a_clip(fast_gate: TwinGate) -> None:
    fast_gate.reset()
    last = fast_gate.neutral_goals()
    last[1] = int(fast_gate.table.max_tick[0])
    req = dict(last)
    req[1] += 40
    v = fast_gate.check(req, last)
    assert v.kind == "clip" and v.goals_tick == last and v.checks == ("limit",)
