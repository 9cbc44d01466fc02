"""`Pipeline.step(next_frame=...)`: the next frame computed during this frame's wait gives exactly the
verdicts and goals of the straightforward step, on random AU frames (clips, holds and telemetry included)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from servoface.controller.face import Face
from servoface.controller.pipeline import FrameTrace, Pipeline

from tests.controller.pipeline_pairs import au_names, face_pair, random_frames


def _frames(pipeline: Pipeline, n: int, seed: int) -> list[dict[str, float]]:
    """Random AU frames: mostly small moves, some jumps (clips), some repeats (held commands)."""
    return random_frames(au_names(pipeline), n, seed)


@pytest.fixture
def faces() -> Iterator[tuple[Face, Face]]:
    with face_pair() as pair:
        yield pair


def _same(x: FrameTrace, y: FrameTrace) -> None:
    assert (x.verdict, x.goals_sent, x.checks, x.reasons) == (y.verdict, y.goals_sent, y.checks, y.reasons)
    assert x.goals_requested == y.goals_requested and x.target_clamps == y.target_clamps


def test_lookahead_matches_the_plain_step_frame_by_frame(faces: tuple[Face, Face]) -> None:
    """Two heads, the same frames: one stepped plainly, one with the next frame computed during the wait.
    Health is left out of this comparison (the two chains' telemetry is read at different instants);
    the next test covers it."""
    plain, ahead = faces
    for face in faces:
        face.pipeline.temperature_limits_c = {}
    frames = _frames(plain.pipeline, 160, seed=7)
    used, kinds = 0, set()
    for k, aus in enumerate(frames):
        if k == 80:
            plain.pipeline.hold()
            ahead.pipeline.hold()
        x = plain.pipeline.step(aus)
        y = ahead.pipeline.step(aus, next_frame=frames[k + 1] if k + 1 < len(frames) else None)
        _same(x, y)
        used += "ahead_ms" in y.timings_ms
        kinds.add(x.verdict)
    assert used > 100  # the speculation was used on most frames (not just thrown away)
    assert "clip" in kinds and "accept" in kinds
    assert [g[1:] for g in plain.chain.goal_writes()] == [g[1:] for g in ahead.chain.goal_writes()]


def test_a_used_speculation_is_what_a_fresh_check_gives(faces: tuple[Face, Face]) -> None:
    """With health on (a hot servo, live telemetry): every time a step used the speculative verdict, a
    fresh gate check with the step's own inputs and the gate's own memory gives the same verdict."""
    face, _ = faces
    p = face.pipeline
    jaw = p.calibration.id_of("jaw")
    face.chain.servo(jaw).temperature_c = p.temperature_limits_c[jaw] - 2.0  # derated: health findings
    frames = _frames(p, 120, seed=11)
    used = fresh = 0
    for k, aus in enumerate(frames):
        state, last, health = p.gate.step_state(), dict(p.last_goals_tick), p._health()
        trace = p.step(aus, next_frame=frames[k + 1] if k + 1 < len(frames) else None)
        if "ahead_ms" not in trace.timings_ms:
            fresh += 1
            continue
        used += 1
        after = p.gate.step_state()
        p.gate.restore_step_state(state)
        check = p.gate.check(trace.goals_requested, last, health)
        p.gate.restore_step_state(after)
        assert dict(check.goals_tick) == trace.goals_sent
        assert trace.verdict == ("clip" if check.kind == "accept" and trace.target_clamps else check.kind)
        assert tuple(check.checks) == tuple(c for c in trace.checks if c != "target")
    assert used > 50 and fresh > 1  # both paths ran: new telemetry invalidates some speculations


def test_an_invalid_next_frame_raises_at_its_own_step_before_anything_is_sent(faces: tuple[Face, Face]) -> None:
    face, _ = faces
    p = face.pipeline
    p.step({"AU12": 0.2}, next_frame={"AU12": float("nan")})
    writes = len(face.chain.goal_writes())
    with pytest.raises(Exception, match="AU12"):
        p.step({"AU12": float("nan")})
    assert len(face.chain.goal_writes()) == writes


def test_without_the_gate_speculation_the_next_frame_is_solved_ahead_and_checked_once(
    faces: tuple[Face, Face],
) -> None:
    """`speculate_gate = False` (what `play_timeline` sets): the next frame's muscle model and calibration
    still run during the wait, the gate checks every frame once at its step, and the goals are the plain
    step's."""
    plain, ahead = faces
    for face in faces:
        face.pipeline.temperature_limits_c = {}
    ahead.pipeline.speculate_gate = False
    checks = [0]
    check = ahead.pipeline.gate.check

    def counted(*args: object, **kwargs: object) -> object:
        checks[0] += 1
        return check(*args, **kwargs)  # type: ignore[arg-type]

    ahead.pipeline.gate.check = counted  # type: ignore[method-assign]
    frames = _frames(plain.pipeline, 80, seed=17)
    for k, aus in enumerate(frames):
        x = plain.pipeline.step(aus)
        y = ahead.pipeline.step(aus, next_frame=frames[k + 1] if k + 1 < len(frames) else None)
        _same(x, y)
        assert "ahead_ms" not in y.timings_ms
    assert checks[0] == len(frames)
    assert [g[1:] for g in plain.chain.goal_writes()] == [g[1:] for g in ahead.chain.goal_writes()]
