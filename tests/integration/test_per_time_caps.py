"""The gate's speed cap holds per second of wire time, whatever the call pattern: `Pipeline.step` called back
to back (no loop, no pacing) may not put goals on the wire faster than the cap allows — checked on every
Goal Position the emulator decoded, against the time between those writes."""

from __future__ import annotations

import time

import numpy as np
from servoface.controller.face import Face


def _speeds(face: Face, steps: list[dict[str, float]], sleep_s: list[float]) -> list[tuple[int, float, float]]:
    """(servo, |step| ticks, allowed ticks) for every consecutive pair of goal writes of every servo."""
    chain = face.chain
    start = len(chain.goal_writes())
    for aus, pause in zip(steps, sleep_s, strict=True):
        face.pipeline.step(aus)
        if pause:
            time.sleep(pause)
    writes = chain.goal_writes()[max(0, start - len(face.pipeline.gate.table.ids)) :]
    table = face.pipeline.gate.table
    period = face.pipeline.gate.frame_period_s
    cap = {sid: int(table.max_step_tick[i]) / period for i, sid in enumerate(table.ids)}  # ticks per second
    last: dict[int, tuple[float, int]] = {}
    out = []
    for t, sid, goal in writes:
        if sid in last:
            t0, g0 = last[sid]
            # 5 % + 1 tick: the emulator stamps a packet when it parses it, not when the host wrote it
            out.append((sid, abs(goal - g0), 1.05 * cap[sid] * (t - t0) + 1.0))
        last[sid] = (t, goal)
    return out


def test_back_to_back_steps_stay_within_the_speed_cap_per_second() -> None:
    with Face.open("human", emulate=True, wire_time=False) as face:
        wide = {"AU26": 1.0, "AU1": 1.0, "AU2": 1.0, "AU12": 1.0, "AU51": 1.0}
        frames = [wide if (k // 10) % 2 == 0 else {} for k in range(120)]
        # each 10-frame segment: three calls a frame apart get the servos moving (from rest the speed may only
        # grow per second of wire time, so calls microseconds apart cannot start a motion), then back to back
        pauses = [0.02 if k % 10 < 3 else 0.0 for k in range(len(frames))]
        pairs = _speeds(face, frames, pauses)
        moved = [p for p in pairs if p[1] > 0]
        assert moved  # the jaw and brows did move
        over = [p for p in pairs if p[1] > p[2]]
        assert over == [], over[:5]


def test_a_late_frame_then_an_on_time_one_does_not_double_the_step() -> None:
    with Face.open("human", emulate=True, wire_time=False) as face:
        frames = [{"AU26": 1.0}] * 40
        pauses = [0.035 if k % 2 == 0 else 0.004 for k in range(40)]  # late, then "on time" right after
        pairs = _speeds(face, frames, pauses)
        over = [p for p in pairs if p[1] > p[2]]
        assert over == [], over[:5]
        assert max(np.array([p[1] for p in pairs])) > 0
