"""A property over the emulated chain: whatever the call pattern — `Pipeline.step` back to back, after a
pause, with or without a speculative next frame, `hold()` in between — no Goal Position decoded by the
emulator is outside the calibrated limits, and no servo's goal moves faster per second of wire time than
the gate's speed cap allows (``max_step_tick`` per frame period). Checked from the emulator's side of the
wire: its packet log's time stamps (taken when a packet is parsed) and decoded goals.

Each example drives the real pipeline on the emulated bus, so examples are dear (up to ~1 s each):
``SERVOFACE_WIRE_EXAMPLES`` (default 25, about 20-30 s on a loaded 2-core machine) bounds the CI time; the
cheap entry points get 10^4 each (tests/fuzz/test_fuzz_api.py, test_fuzz_files.py). With the per-time caps
switched off (``Pipeline.per_time_caps = False``) this property fails within 30 examples."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from servoface.controller.face import Face

EXAMPLES = int(os.environ.get("SERVOFACE_WIRE_EXAMPLES", "25"))
WIRE = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck), database=None)

EXTREMES: list[dict[str, float]] = [
    {},
    {"AU26": 1.0, "AU1": 1.0, "AU2": 1.0, "AU12": 1.0, "AU51": 1.0, "AU53": 1.0, "AU61": 1.0},
    {"AU27": 1.0, "AU4": 1.0, "AU15": 1.0, "AU52": 1.0, "AU54": 1.0, "AU62": 1.0, "AU43": 1.0},
    {"AU12L": 1.0, "AU15R": 1.0, "AU51": 1.0},
    {"AU12R": 1.0, "AU15L": 1.0, "AU52": 1.0},
]
AU_NAMES = sorted({au for pose in EXTREMES for au in pose})

poses = st.one_of(
    st.sampled_from(EXTREMES),
    st.dictionaries(st.sampled_from(AU_NAMES), st.floats(0.0, 1.0), max_size=6),
)
calls = st.lists(  # segments: one pose asked for ``repeats`` calls running (the head has to travel)
    st.tuples(
        poses,
        st.integers(1, 12),  # repeats
        st.sampled_from([0.0, 0.0, 0.0, 0.001, 0.004, 0.012, 0.03, 0.06]),  # pause after each call, s
        st.sampled_from(["step", "step", "ahead", "hold"]),
    ),
    min_size=1,
    max_size=5,
)


@pytest.fixture(scope="module")
def face() -> Iterator[Face]:
    f = Face.open("human", emulate=True, wire_time=False)
    try:
        yield f
    finally:
        f.close(ease_s=0.0)


def _per_second_violations(face: Face, start: int) -> list[tuple[Any, ...]]:
    """(t, servo, |step|, allowed) for each goal write from index ``start`` of the log that moved further
    than the speed cap allows for the wire time since that servo's previous goal write."""
    table = face.pipeline.gate.table
    period = face.pipeline.gate.frame_period_s
    cap_per_s = {sid: int(table.max_step_tick[i]) / period for i, sid in enumerate(table.ids)}
    writes = face.chain.goal_writes()
    last: dict[int, tuple[float, int]] = {}
    for t, sid, goal in writes[:start][-4 * len(table.ids) :]:  # the goals just before: where each servo was
        last[sid] = (t, goal)
    bad = []
    for t, sid, goal in writes[start:]:
        if sid in last:
            t0, g0 = last[sid]
            # 5 % + 1 tick: the emulator stamps a packet when it parses it, not when the host wrote it
            allowed = 1.05 * cap_per_s[sid] * (t - t0) + 1.0
            if abs(goal - g0) > allowed:
                bad.append((round(t, 4), sid, abs(goal - g0), round(allowed, 1)))
        last[sid] = (t, goal)
    return bad


def _outside_limits(face: Face, start: int) -> list[tuple[Any, ...]]:
    lo_hi = face.pipeline.calibration.position_limits_tick()
    return [(t, sid, g) for t, sid, g in face.chain.goal_writes()[start:] if not lo_hi[sid][0] <= g <= lo_hi[sid][1]]


@pytest.mark.slow
@WIRE
@given(calls)
def test_no_call_pattern_beats_the_speed_cap_per_second_or_the_limits(face: Face, pattern: Any) -> None:
    start = len(face.chain.goal_writes())
    pipeline = face.pipeline
    for k, (aus, repeats, pause_s, how) in enumerate(pattern):
        for r in range(repeats):
            if how == "hold" and r == repeats - 1:
                pipeline.hold()
            else:
                last = r == repeats - 1
                nxt = (pattern[k + 1][0] if k + 1 < len(pattern) else None) if last else aus
                pipeline.step(aus, next_frame=nxt if how == "ahead" else None)
            if pause_s:
                time.sleep(pause_s)
    assert _outside_limits(face, start) == []
    over = _per_second_violations(face, start)
    assert over == [], over[:5]
