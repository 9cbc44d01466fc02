"""An unsafe script through the whole pipeline onto the emulated chain: the gate clips or rejects it with
reasons naming servo and check, and decoding every byte the emulator received shows no goal outside the
calibrated limits and no step between consecutive goals of a servo beyond the gate's per-frame cap."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from servoface.controller.face import Face
from servoface.controller.performance import Performance, play_timeline
from servoface.controller.pipeline import Pipeline
from servoface.controller.script import SCRIPTS_DIR
from servoface.controller.timeline import ChannelClip, Key, Timeline, min_jerk
from servoface.hardware.emulator import ServoChain
from servoface.sim.gate import GateConfig
from servoface.sim.gate.coupling import CouplingLimit

from tests.integration.wire_checks import check_wire

UNSAFE = SCRIPTS_DIR / "unsafe_pose.toml"

# Stronger than the shipped one: full antagonists and full head turns that flip side every 40 ms (two
# frames), so every frame asks for far more than a servo can travel, and against its last direction.
FLIP_FLOP = """
[script]
face = "human"
title = "integration: flip-flop between extremes every two frames"
end_s = 0.6

[poses]
left = { AU12L = 1.0, AU15R = 1.0, AU27 = 1.0, AU51 = 1.0, AU53 = 1.0, AU1 = 1.0, AU2 = 1.0, AU61 = 1.0 }
right = { AU12R = 1.0, AU15L = 1.0, AU43 = 1.0, AU52 = 1.0, AU54 = 1.0, AU4 = 1.0, AU62 = 1.0, AU24 = 1.0 }

[expressions.flip]
keyframes = [
  { t_s = 0.0, pose = "left" }, { t_s = 0.04, pose = "left" }, { t_s = 0.041, pose = "right" },
  { t_s = 0.08, pose = "right" }, { t_s = 0.081, pose = "left" }, { t_s = 0.12, pose = "left" },
  { t_s = 0.121, pose = "right" }, { t_s = 0.16, pose = "right" }, { t_s = 0.161, pose = "left" },
  { t_s = 0.2, pose = "left" }, { t_s = 0.201, pose = "right" }, { t_s = 0.24, pose = "right" },
]

[[play]]
at_s = 0.0
expression = "flip"

[[play]]
at_s = 0.3
expression = "flip"

[blink]
enabled = false

[idle]
enabled = false
"""


@dataclass
class Played:
    face: Face
    chain: ServoChain
    unsafe: Performance
    flip_flop: Performance


@pytest.fixture(scope="module")
def played(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Played]:
    face = Face.open("human", emulate=True, wire_time=False)
    try:
        unsafe = face.play(UNSAFE)
        script = tmp_path_factory.mktemp("unsafe") / "flip_flop.toml"
        script.write_text(FLIP_FLOP)
        flip_flop = face.play(script)
        yield Played(face, face.chain, unsafe, flip_flop)
    finally:
        face.close(ease_s=0.0)


def test_the_gate_table_is_the_calibrations(played: Played) -> None:
    table = played.face.pipeline.gate.table
    cal = played.face.pipeline.calibration
    for i, sid in enumerate(table.ids):
        assert (int(table.min_tick[i]), int(table.max_tick[i])) == (
            cal.by_id(sid).min_tick,
            cal.by_id(sid).max_tick,
        )
        assert 1 <= int(table.max_step_tick[i]) < cal.by_id(sid).max_tick - cal.by_id(sid).min_tick


@pytest.mark.parametrize("which", ["unsafe", "flip_flop"])
def test_unsafe_frames_are_clipped_with_reasons(played: Played, which: str) -> None:
    perf: Performance = getattr(played, which)
    bad = perf.clipped()
    assert len(bad) >= 3, perf.summary()
    assert all(t.verdict in ("clip", "reject") for t in bad)
    checks = {c for t in bad for c in t.checks}
    assert {"speed"} & checks or {"accel"} & checks, checks
    ids = played.face.pipeline.gate.table.ids
    for t in bad:
        assert t.reasons and t.checks
        assert t.goals_sent != t.goals_requested
        # every reason names its check, and a per-servo check names the servo by id and role
        for reason in t.reasons:
            check = reason[1 : reason.index("]")]
            assert check in t.checks, reason
            if check in ("limit", "speed", "accel"):
                assert any(f"servo {sid} '" in reason for sid in ids), reason


def test_no_goal_on_the_wire_breaks_limits_or_rate_caps(played: Played) -> None:
    n = check_wire(played.face.pipeline, played.chain)
    frames = len(played.unsafe.traces) + len(played.flip_flop.traces)
    assert n >= frames * len(played.face.head.actuators)  # one sync write of every servo per frame


def test_what_the_gate_sent_is_what_the_wire_carried(played: Played) -> None:
    """Every frame the gate sent during the flip-flop reached the wire, in order, as one Sync Write. (The head
    service's loop goes on holding the pose after the call returns, so the wire may hold later frames too.)"""
    by_packet: dict[float, dict[int, int]] = {}
    for t_s, sid, tick in played.chain.goal_writes():  # one Sync Write: one arrival time for every servo
        by_packet.setdefault(t_s, {})[sid] = tick
    n_servos = len(played.face.head.actuators)
    frames = [goals for goals in by_packet.values() if len(goals) == n_servos]
    sent = [trace.goals_sent for trace in played.flip_flop.traces]
    assert len(sent) > 20
    k = 0
    for goals in frames:  # the gate's frames are a subsequence of the wire's
        if k < len(sent) and goals == sent[k]:
            k += 1
    assert k == len(sent), f"frame {k} of {len(sent)} the gate sent is not on the wire after the ones before it"


AU_NAMES = [
    "AU1",
    "AU2",
    "AU4",
    "AU5",
    "AU6",
    "AU9",
    "AU12L",
    "AU12R",
    "AU15",
    "AU20",
    "AU26",
    "AU27",
    "AU43",
    "AU51",
    "AU52",
    "AU53",
    "AU54",
    "AU61",
    "AU62",
]


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    frames=st.lists(st.dictionaries(st.sampled_from(AU_NAMES), st.floats(0.0, 1.0), max_size=6), min_size=2, max_size=5)
)
def test_any_sequence_of_au_frames_stays_safe_on_the_wire(played: Played, frames: list[dict[str, float]]) -> None:
    """Property: whatever valid AU frames come in, back to back (no easing), the wire stays safe."""
    face = played.face
    chain = played.chain
    with face.service.paused_loop():  # frames by hand: the head service lends us the bus
        before = len(chain.goal_writes())
        for aus in frames:
            trace = face.pipeline.step(aus)
            assert trace.verdict in ("accept", "clip", "reject")
        assert len(chain.goal_writes()) == before + len(frames) * len(face.head.actuators)
        check_wire(face.pipeline, chain)


def test_a_coupling_rule_given_to_the_gate_clips_and_is_named(played: Played) -> None:
    """A stricter coupling rule (GateConfig: explicit arguments win over the head profile) on a pipeline over
    the same bus: a brow raise with a smile is held at the rule, the reasons name it, the wire stays safe."""
    face = played.face
    rule = CouplingLimit(
        "integration: no big smile under raised brows",
        ("brow_inner_l", "lip_corner_l"),
        0.6,
        "sum_at_most",
        "any",
    )
    face.neutral(transition_s=0.3)  # a defined start: the face track would hold the flip-flop's last extreme
    strict = Pipeline(
        face.head, face.pipeline.calibration, driver=face.driver, gate_config=GateConfig(coupling=(rule,))
    )
    face.service.pause()  # a second pipeline on the same bus: the head service lends it (resumed below)
    strict.pin_to(face.pipeline.last_goals_tick)
    start = len(played.chain.goal_writes())
    timeline = Timeline("human")
    pose = {"AU1": 0.8, "AU2": 0.6, "AU12": 0.8}
    timeline.play(
        ChannelClip(
            {au: (Key(0.0, 0.0), Key(0.4, v, min_jerk), Key(0.6, v)) for au, v in pose.items()},
            0.6,
            name="brows_and_smile",
        )
    )
    try:
        perf = play_timeline(strict, timeline, 0.6)
    finally:
        face.service.resume()
    coupled = [t for t in perf.traces if "coupling" in t.checks]
    assert coupled, perf.summary()
    assert all(any(f"rule '{rule.name}'" in r for r in t.reasons) for t in coupled)
    last = perf.traces[-1]
    assert last.goals_sent != last.goals_requested  # held short of the request
    assert not [f for f in strict.gate.audit(strict.last_goals_tick) if f.check == "coupling"]
    check_wire(strict, played.chain, start)
