"""The gate is given only the strained servos' health (`telemetry.StrainedHealth`), and a speculative
verdict is used after a whole period even when the last frame's caps were shrunk. Both must give exactly
what the straightforward path gives: the verdicts for the full health, the steps without speculation."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator

import numpy as np
import pytest
from servoface.controller.face import Face
from servoface.controller.telemetry import StrainedHealth, gate_health
from servoface.hardware.snapshot import ChainSnapshot

from tests.controller.pipeline_pairs import au_names, changed_state, face_pair, random_frames


@pytest.fixture
def faces() -> Iterator[tuple[Face, Face]]:
    with face_pair() as pair:
        yield pair


def _snapshot(face: Face) -> ChainSnapshot:
    snap = face.pipeline.hold()
    assert snap is not None
    return snap


def _random_telemetry(snap: ChainSnapshot, limits: dict[int, float], rng: np.random.Generator) -> ChainSnapshot:
    """Some servos changed: temperature near or under its limit, load anywhere, a fault or none, derated."""
    servos = dict(snap.servos)
    for sid in rng.choice(sorted(servos), size=int(rng.integers(1, 6)), replace=False):
        servos[int(sid)] = changed_state(servos[int(sid)], limits.get(int(sid), 70.0), rng)
    return dataclasses.replace(snap, servos=servos)


def test_strained_health_is_the_strained_part_of_the_full_health_frame_after_frame(faces: tuple[Face, Face]) -> None:
    face, _ = faces
    p = face.pipeline
    policy = p.gate.config.health
    strained = StrainedHealth(p._ids)
    snap = _snapshot(face)
    rng = np.random.default_rng(3)
    seen = 0
    for _ in range(300):
        snap = _random_telemetry(snap, p.temperature_limits_c, rng)
        full = gate_health(snap, p.temperature_limits_c, p._ids)
        expected = {sid: h for sid, h in full.items() if h.strained(policy.hot_margin_c, policy.load_limit)}
        got = strained(snap, p.temperature_limits_c, policy)
        assert got == expected
        seen += bool(expected) and len(expected) < len(full)
    assert seen > 100  # strained and unstrained servos side by side, most frames


def test_the_gate_gives_the_same_verdict_for_the_strained_health_as_for_the_full_one(faces: tuple[Face, Face]) -> None:
    face, _ = faces
    p = face.pipeline
    gate, policy = p.gate, p.gate.config.health
    snap = _snapshot(face)
    rng = np.random.default_rng(4)
    frames = random_frames(au_names(p), 120, seed=4)
    last = dict(p.last_goals_tick)
    kinds, narrowed = set(), 0
    for aus in frames:
        snap = _random_telemetry(snap, p.temperature_limits_c, rng)
        full = gate_health(snap, p.temperature_limits_c, p._ids)
        cut = StrainedHealth(p._ids)(snap, p.temperature_limits_c, policy)
        requested = p._solve(aus, {})[3]
        elapsed_s = None if rng.random() < 0.5 else float(rng.uniform(0.3, 1.5)) * gate.frame_period_s
        before = gate.step_state()
        a = gate.check(requested, last, full, elapsed_s=elapsed_s)
        after_a = gate.step_state()
        gate.restore_step_state(before)
        b = gate.check(requested, last, cut, elapsed_s=elapsed_s)
        assert a == b
        assert after_a.same(gate.step_state())
        kinds.add(a.kind)
        narrowed += "health" in a.checks
        last = dict(a.goals_tick)
    assert narrowed > 50 and {"accept", "clip"} <= kinds


def test_speculation_after_a_shrunk_frame_gives_the_plain_steps(faces: tuple[Face, Face]) -> None:
    """Per-time caps on, a manual clock: frames mostly a period apart, some early (their caps shrink), some
    late. The pipeline stepped with the next frame computed during the wait sends exactly what the plain
    one sends, and uses its speculation on the frames after a shrunk one."""
    plain, ahead = faces
    now = [100.0]
    for face in faces:
        face.pipeline.per_time_caps = True
        face.pipeline.temperature_limits_c = {}  # the two chains' telemetry is read at different instants
        face.pipeline.clock = lambda: now[0]
    period_s = plain.pipeline.gate.frame_period_s
    rng = np.random.default_rng(8)
    frames = random_frames(au_names(plain.pipeline), 150, seed=8)
    after_shrunk = 0
    shrunk = False
    for k, aus in enumerate(frames):
        gap = float(rng.choice([1.0, 1.0, 1.0, 0.6, 0.8, 1.3]))
        t0 = now[0]
        now[0] = t0 + gap * period_s + 1e-9  # (+1 ns: a whole period despite the float sum)
        x = plain.pipeline.step(aus)
        now[0] = t0 + gap * period_s + 1e-9  # the same instants for both
        y = ahead.pipeline.step(aus, next_frame=frames[k + 1] if k + 1 < len(frames) else None)
        assert (x.verdict, x.goals_sent, x.checks, x.reasons) == (y.verdict, y.goals_sent, y.checks, y.reasons), k
        assert plain.pipeline.gate.step_state().same(ahead.pipeline.gate.step_state()), k
        after_shrunk += shrunk and "ahead_ms" in y.timings_ms
        shrunk = gap < 1.0
    assert after_shrunk > 12
    assert [g[1:] for g in plain.chain.goal_writes()] == [g[1:] for g in ahead.chain.goal_writes()]


def test_speculation_for_a_planned_interval_gives_the_plain_steps(faces: tuple[Face, Face]) -> None:
    """Frames back to back (well under a period apart, per-time caps shrink), their intervals jittering: the
    speculation is checked for the planned interval (the shortest of the last `PLAN_HISTORY` elapsed times)
    and used when the real interval reaches it (a clean accept) or gives exactly its caps; the pipeline with
    it sends exactly what the plain one sends, and the gate notes the same fraction."""
    plain, ahead = faces
    now = [100.0]
    for face in faces:
        face.pipeline.per_time_caps = True
        face.pipeline.temperature_limits_c = {}
        face.pipeline.clock = lambda: now[0]
    period_s = plain.pipeline.gate.frame_period_s
    rng = np.random.default_rng(9)
    frames = random_frames(au_names(plain.pipeline), 160, seed=9, jump=0.04, sigma=0.04)  # small moves: accepts
    base = 0.35 * period_s
    used = longer = 0
    for k, aus in enumerate(frames):
        if rng.random() < 0.1:
            base = float(rng.uniform(0.2, 0.6)) * period_s
        gap = base * (1.0 + float(rng.choice([-0.15, -0.05, -0.01, -1e-6, 0.0, 1e-6, 0.01, 0.04, 0.2])))
        plan = ahead.pipeline._plans_s()[0]
        t0 = now[0]
        now[0] = t0 + gap
        x = plain.pipeline.step(aus)
        now[0] = t0 + gap
        y = ahead.pipeline.step(aus, next_frame=frames[k + 1] if k + 1 < len(frames) else None)
        assert (x.verdict, x.goals_sent, x.checks, x.reasons) == (y.verdict, y.goals_sent, y.checks, y.reasons), k
        assert plain.pipeline.gate.step_state().same(ahead.pipeline.gate.step_state()), k
        used += "ahead_ms" in y.timings_ms
        longer += "ahead_ms" in y.timings_ms and plan is not None and gap > plan * 1.005
    assert 60 < used < len(frames) - 10  # used on most frames, checked afresh on the others
    assert longer > 30  # mostly for an interval longer than the planned one (clean accepts)
    assert [g[1:] for g in plain.chain.goal_writes()] == [g[1:] for g in ahead.chain.goal_writes()]


def test_strained_health_of_the_drivers_own_snapshots_equals_the_full_health_cut(faces: tuple[Face, Face]) -> None:
    """On the driver's lazy snapshots (states not built: `peek_state`), with the emulated servos heating up
    and pushing against obstacles, StrainedHealth is the strained part of `gate_health` of the built states."""
    face, _ = faces
    p = face.pipeline
    policy = p.gate.config.health
    strained = StrainedHealth(p._ids)
    rng = np.random.default_rng(5)
    ids = sorted(p._ids)
    seen = 0
    for step in range(240):
        if step % 60 == 0:  # (temperatures are read round-robin: a servo's every few dozen cycles)
            for sid in rng.choice(ids, size=8, replace=False).tolist():
                limit = p.temperature_limits_c.get(sid, 70.0)
                face.chain.servo(sid).temperature_c = float(limit - rng.choice([1, 3, 8, 30]))
        if step % 25 == 0:
            obstacle = face.chain.servo(int(rng.choice(ids)))
            obstacle.set_obstacle(None if rng.random() < 0.3 else float(rng.integers(1500, 2500)))
        snap = _snapshot(face)
        got = strained(snap, p.temperature_limits_c, policy)  # peeks first: no state built yet
        full = gate_health(snap, p.temperature_limits_c, p._ids)
        assert got == {sid: h for sid, h in full.items() if h.strained(policy.hot_margin_c, policy.load_limit)}
        seen += bool(got)
    assert seen > 50  # strained servos were there to be found
