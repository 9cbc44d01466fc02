"""The pipeline's cheap paths give what the straightforward step gives.

- `Pipeline._solve` keeps the last muscle model + calibration result: a pipeline with it and one that
  solves every frame afresh, on random AU frames with many repeats, send the same goals with the same
  verdicts (the same bytes reach the emulator);
- `Pipeline._slot_deficit`: a frame that comes a little less than a frame period after the last write is
  checked with the caps of a whole period and held to its slot, so the speculative verdict computed during
  the last wait is used (checked for the step's shorter elapsed time, it would be void).
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest
from servoface.controller.face import Face
from servoface.controller.pipeline import PAY_BACK_SHARE, FrameTrace

from tests.controller.pipeline_pairs import au_names, face_pair, random_frames


def _frames(names: list[str], n: int, seed: int) -> list[dict[str, float]]:
    """Random AU frames; about half repeat the previous one exactly (a held expression)."""
    return random_frames(names, n, seed, jump=0.1, move=0.5, sigma=0.2)


@pytest.fixture
def faces() -> Iterator[tuple[Face, Face]]:
    with face_pair() as pair:
        for face in pair:  # the two chains' telemetry is read at different instants
            face.pipeline.temperature_limits_c = {}
        yield pair


def _key(t: FrameTrace) -> tuple[object, ...]:
    return (t.verdict, t.goals_sent, t.checks, t.reasons, t.goals_requested, t.target_clamps, t.targets)


@pytest.mark.parametrize("ahead", [False, True])
def test_cached_solve_gives_the_same_goals_and_verdicts_as_solving_every_frame(
    faces: tuple[Face, Face], ahead: bool
) -> None:
    cached, fresh = faces
    names = au_names(cached.pipeline)
    frames = _frames(names, 140, seed=5)
    hits = 0
    for k, aus in enumerate(frames):
        nxt = frames[k + 1] if ahead and k + 1 < len(frames) else None
        fresh.pipeline._solved = None  # the reference solves every frame
        y = fresh.pipeline.step(aus, next_frame=nxt)
        x = cached.pipeline.step(aus, next_frame=nxt)
        hits += x.timings_ms.get("calibration_ms", 1.0) == 0.0
        assert _key(x) == _key(y), k
    assert hits > 20  # repeats were served from the cache
    assert [g[1:] for g in cached.chain.goal_writes()] == [g[1:] for g in fresh.chain.goal_writes()]


def test_cached_solve_still_refuses_bad_aus_before_anything_is_sent(faces: tuple[Face, Face]) -> None:
    face, _ = faces
    p = face.pipeline
    p.step({"AU12": 0.3})
    p.step({"AU12": 0.3})  # a cache hit
    writes = len(face.chain.goal_writes())
    for bad in ({"AU12": float("nan")}, {"AU12": 7.0}, {"NOPE": 0.1}):
        with pytest.raises(Exception):  # noqa: B017 - the muscle model's own typed error
            p.step(bad)
    assert len(face.chain.goal_writes()) == writes


def test_a_frame_just_short_of_a_period_is_held_to_its_slot_and_uses_the_speculation(faces: tuple[Face, Face]) -> None:
    face, _ = faces
    p = face.pipeline
    p.per_time_caps = True
    period_s = p.gate.frame_period_s
    names = au_names(p)
    frames = _frames(names, 30, seed=9)
    used = 0
    for k, aus in enumerate(frames):
        if p.last_write_s is not None:  # as if this frame came a little early within a paced loop (not so
            p.last_write_s = time.monotonic() - (p._slot() - 0.5 * PAY_BACK_SHARE * period_s)  # early: `_pay_back`)
        t0 = time.monotonic()
        trace = p.step(aus, next_frame=frames[k + 1] if k + 1 < len(frames) else None)
        if k > 0:
            assert time.monotonic() - t0 >= 0.5 * PAY_BACK_SHARE * period_s * 0.999  # it waited (never less)
        used += "ahead_ms" in trace.timings_ms
    assert used >= len(frames) - 3  # every frame but the first (and any the first speculation missed)
