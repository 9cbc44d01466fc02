"""Per-second rate caps (`limits.per_time`): calls much faster than the frame rate add up to what one call a
frame period later allows — never more (a person stands next to the head), and they do not stall (the
speed-up cap scaled by f² and floored to whole ticks per call could never start a motion)."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.sim.gate import GateConfig, TwinGate
from servoface.sim.gate import limits as lim
from servoface.sim.gate.demo_rig import demo_calibration, demo_head

PERIOD_S = 1 / 60


def _table(step: list[int], speedup: list[int]) -> lim.ServoTable:
    n = len(step)
    return lim.ServoTable(
        tuple(range(1, n + 1)),
        tuple(f"s{i}" for i in range(n)),
        np.zeros(n, dtype=np.int64),
        np.full(n, 4095, dtype=np.int64),
        np.full(n, 2048, dtype=np.int64),
        np.array(step, dtype=np.int64),
        np.array(speedup, dtype=np.int64),
    )


def _drive(table: lim.ServoTable, targets: np.ndarray, elapsed_s: list[float]) -> tuple[list[np.ndarray], list[float]]:
    """A caller that asks for ``targets`` at every call, ``elapsed_s[i]`` after the previous call; each
    command is the nearest one inside the caps (`clamp`). Returns (commands sent, call times)."""
    last = table.neutral_tick.copy()
    last_step = np.zeros(table.n, dtype=np.int64)
    fraction = 1.0
    window = None
    sent, times, t = [last.copy()], [0.0], 0.0
    for e in elapsed_s:
        caps, rate_last, rate_step, window = lim.per_time(table, last, last_step, e, PERIOD_S, fraction, window)
        fraction = window.fraction
        goal = lim.clamp(targets, rate_last, rate_step, caps)
        assert lim.rate_ok(goal, rate_last, rate_step, caps)[1].all()
        window = window.sent(goal)
        last_step, last = goal - last, goal
        t += e
        sent.append(goal.copy())
        times.append(t)
    return sent, times


def _per_frame(table: lim.ServoTable, targets: np.ndarray, frames: int) -> list[np.ndarray]:
    """The same caller one call per frame period (the per-frame caps)."""
    return _drive(table, targets, [PERIOD_S] * frames)[0]


@pytest.mark.parametrize("calls_per_frame", [1, 3, 7, 50, 1000])
def test_fast_calls_add_up_to_one_frame_call(calls_per_frame: int) -> None:
    table = _table([51, 93, 41, 12], [17, 31, 13, 4])
    targets = np.array([4000, 100, 3000, 2100], dtype=np.int64)
    frames = 12
    sent, _ = _drive(table, targets, [PERIOD_S / calls_per_frame] * (frames * calls_per_frame))
    reference = _per_frame(table, targets, frames)
    ends = [sent[k * calls_per_frame] for k in range(frames + 1)]
    for k in range(frames + 1):  # at every frame boundary exactly where the one-call-per-frame caller is
        assert np.array_equal(ends[k], reference[k]), (k, ends[k], reference[k])
    assert not np.array_equal(ends[1], ends[0]), "fast calls never started the motion"
    steps = np.diff(np.array(ends), axis=0)
    assert np.all(np.abs(steps) <= table.max_step_tick)  # speed per frame period
    grow = np.abs(steps[1:]) - np.abs(steps[:-1])
    assert np.all(grow <= table.max_speedup_tick) and np.all(np.abs(steps[0]) <= table.max_speedup_tick)


@pytest.mark.parametrize("calls_per_frame", [3, 50, 1000])
def test_a_small_speedup_cap_is_never_beaten_and_still_moves(calls_per_frame: int) -> None:
    """With a speed-up cap of two or three ticks per frame the call-to-call caps can leave a fast caller a
    tick behind the one-call-per-frame caller at a frame boundary: never ahead of it, and it moves. (With a
    cap of one tick a fast caller's speed stays at one tick per frame: safe, slow.)"""
    table = _table([5, 7], [2, 3])
    targets = np.array([4000, 100], dtype=np.int64)
    sent, _ = _drive(table, targets, [PERIOD_S / calls_per_frame] * (10 * calls_per_frame))
    reference = _per_frame(table, targets, 10)
    start = table.neutral_tick
    for k in range(11):
        fast, ref = np.abs(sent[k * calls_per_frame] - start), np.abs(reference[k] - start)
        assert np.all(fast <= ref) and np.all(fast >= ref - k), (k, fast, ref)
    assert np.all(sent[-1] != start)


@pytest.mark.parametrize("seed", range(6))
def test_random_call_patterns_never_beat_the_caps_per_second(seed: int) -> None:
    """Random gaps (microseconds to two periods) and random targets: over any span of calls lasting at most
    ``m`` periods the motion is at most ``m + 1`` frames' steps (as for one call per frame, where a span can
    hold ``m + 1`` calls); from call to call the per-frame caps hold as well (step and speed-up against the
    previous call's step); and motion does start."""
    rng = np.random.default_rng(seed)
    table = _table([51, 93, 41, 7], [17, 31, 13, 2])
    elapsed = (rng.choice([1e-6, 1e-4, 1e-3, 4e-3, 0.017, 0.03], size=600) * rng.uniform(0.5, 1.5, 600)).tolist()
    last = table.neutral_tick.copy()
    last_step = np.zeros(table.n, dtype=np.int64)
    fraction, window = 1.0, None
    sent, times, t = [last.copy()], [0.0], 0.0
    for i, e in enumerate(elapsed):
        if i % 40 == 0:
            targets = rng.integers(0, 4096, table.n).astype(np.int64)
        caps, rate_last, rate_step, window = lim.per_time(table, last, last_step, e, PERIOD_S, fraction, window)
        fraction = window.fraction
        goal = lim.clamp(targets, rate_last, rate_step, caps)
        window = window.sent(goal)
        lo, hi = lim.step_bounds(last_step, table)  # call to call, the per-frame caps hold too
        assert np.all((goal - last >= lo) & (goal - last <= hi)), (i, goal - last, last_step)
        last_step, last = goal - last, goal
        t += e
        sent.append(goal.copy())
        times.append(t)
    pos = np.array(sent)
    tt = np.array(times)
    assert np.any(pos[1:] != pos[0]), "no motion at all"
    for i in range(len(pos)):
        for m in (1, 2, 5):
            j = int(np.searchsorted(tt, tt[i] + m * PERIOD_S, side="right"))
            span = pos[i:j]
            travel = np.abs(np.diff(span, axis=0)).sum(axis=0) if len(span) > 1 else np.zeros(table.n)
            assert np.all(travel <= (m + 1) * table.max_step_tick), (i, m, travel)


def test_a_caller_microseconds_apart_starts_a_motion_through_the_gate(tmp_path_factory: pytest.TempPathFactory) -> None:
    """The gate itself, checked every 20 µs (a zero-wire-time emulator): the head moves, and by each frame
    boundary it is where a caller once per frame would have it."""
    head = demo_head()
    cache = tmp_path_factory.getbasetemp() / "tss-demo"
    gate = TwinGate(head, demo_calibration(head), PERIOD_S, GateConfig(cache_dir=cache))
    ref = TwinGate(head, demo_calibration(head), PERIOD_S, GateConfig(cache_dir=cache))
    t = gate.table
    target = t.neutral_tick.copy()
    col = list(t.roles).index("neck_yaw") if "neck_yaw" in t.roles else 0
    target[col] = t.max_tick[col]
    goals = dict(zip(t.ids, target.tolist(), strict=True))
    last = ref_last = gate.neutral_goals()
    calls = int(round(PERIOD_S / 20e-6))
    for _ in range(4):
        for _ in range(calls):
            last = gate.check(goals, last, elapsed_s=PERIOD_S / calls).goals_tick
        ref_last = ref.check(goals, ref_last, elapsed_s=PERIOD_S).goals_tick
        assert last == ref_last
    assert last[t.ids[col]] != t.neutral_tick[col], "the gate never started the motion"
