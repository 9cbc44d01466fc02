"""The per-check work every frame pays (goal maps, rate caps, limit findings, the memory of the last
command) done with fewer Python and numpy steps gives what the straightforward code gives, on seeded random
inputs for both built-in heads."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pytest
from servoface.sim.gate import TwinGate
from servoface.sim.gate import limits as lim
from servoface.sim.gate.health import ServoHealth
from servoface.sim.gate.verdict import Finding

from tests.sim.gate_setup import builtin_gate

FRAME_PERIOD_S = 1 / 50


@pytest.fixture(scope="module", params=["human", "dog"])
def gate(request: pytest.FixtureRequest) -> TwinGate:
    return builtin_gate(request.param, FRAME_PERIOD_S)


def _plain_step_bounds(last_step: np.ndarray, table: lim.ServoTable) -> tuple[np.ndarray, np.ndarray]:
    up = np.where(last_step > 0, last_step + table.max_speedup_tick, table.max_speedup_tick)
    down = np.where(last_step < 0, last_step - table.max_speedup_tick, -table.max_speedup_tick)
    hi = np.minimum(up, table.max_step_tick)
    lo = np.maximum(down, -table.max_step_tick)
    return lo.astype(np.int64), hi.astype(np.int64)


def _plain_findings(goals: np.ndarray, last: np.ndarray, last_step: np.ndarray, table: lim.ServoTable) -> list[Finding]:
    """`limits.findings` before its shortcuts (the speed test of its own, no early return)."""
    out: list[Finding] = []
    step = goals - last
    lo, hi = _plain_step_bounds(last_step, table)
    bad = (goals < table.min_tick) | (goals > table.max_tick) | (step < lo) | (step > hi)
    bad |= np.abs(step) > table.max_step_tick
    for i in np.flatnonzero(bad).tolist():
        sid, role, g = table.ids[i], table.roles[i], int(goals[i])
        if g < table.min_tick[i] or g > table.max_tick[i]:
            side, lm = ("below min", table.min_tick[i]) if g < table.min_tick[i] else ("above max", table.max_tick[i])
            out.append(
                Finding(
                    "limit",
                    f"{table.label(i)}: goal {g} tick {side} {int(lm)} tick",
                    role,
                    sid,
                    float(g),
                    float(lm),
                    "tick",
                )
            )
        s = int(step[i])
        if abs(s) > table.max_step_tick[i]:
            out.append(
                Finding(
                    "speed",
                    f"{table.label(i)}: step {s} tick/frame exceeds {int(table.max_step_tick[i])} tick/frame",
                    role,
                    sid,
                    float(abs(s)),
                    float(table.max_step_tick[i]),
                    "tick/frame",
                )
            )
        elif s < lo[i] or s > hi[i]:
            out.append(
                Finding(
                    "accel",
                    f"{table.label(i)}: step {s} tick/frame after {int(last_step[i])} "
                    f"speeds up by more than {int(table.max_speedup_tick[i])} tick/frame^2",
                    role,
                    sid,
                    float(s - last_step[i]),
                    float(table.max_speedup_tick[i]),
                    "tick/frame^2",
                )
            )
    return out


def _plain_per_time(
    table: lim.ServoTable, last_step: np.ndarray, elapsed_s: float, period_s: float, last_fraction: float
) -> tuple[lim.ServoTable, np.ndarray, float]:
    f = 0.0 if not np.isfinite(elapsed_s) or elapsed_s <= 0 else min(1.0, float(elapsed_s) / period_s)
    if f >= 1.0 and last_fraction >= 1.0:
        return table, last_step, 1.0
    step = np.floor(table.max_step_tick * f).astype(np.int64)
    speedup = np.floor(table.max_speedup_tick * f * f).astype(np.int64)
    ratio = min(1.0, f / last_fraction) if last_fraction > 0 else 0.0
    scaled_last = np.trunc(last_step * ratio).astype(np.int64)
    scaled = copy.copy(table)
    object.__setattr__(scaled, "max_step_tick", step)
    object.__setattr__(scaled, "max_speedup_tick", speedup)
    return scaled, scaled_last, f


def _tables(gate: TwinGate, rng: np.random.Generator) -> list[lim.ServoTable]:
    """The gate's table, a derated one and per-time scaled ones (caps down to 0)."""
    from servoface.sim.gate.health import derate

    t = gate.table
    hot = {int(i): ServoHealth(80.0, 80.0, 0.2) for i in rng.choice(t.ids, size=3, replace=False)}
    out = [t, derate(t, hot, gate.config.health)[0]]
    for f in (0.0, 0.05, 0.5, 0.97):
        out.append(lim.per_time(t, np.zeros(t.n, dtype=np.int64), f * gate.frame_period_s, gate.frame_period_s, 1.0)[0])
    return out


def test_step_bounds_and_findings_equal_the_plain_rules(gate: TwinGate) -> None:
    rng = np.random.default_rng(21)
    fired = 0
    for table in _tables(gate, rng):
        cap = np.maximum(table.max_step_tick, 1)
        for _ in range(150):
            last = rng.integers(table.min_tick - 40, table.max_tick + 40)
            last_step = (rng.uniform(-1.5, 1.5, table.n) * cap).astype(np.int64)
            goals = last + (rng.uniform(-2.5, 2.5, table.n) * cap * (rng.random(table.n) < 0.5)).astype(np.int64)
            for got, want in zip(lim.step_bounds(last_step, table), _plain_step_bounds(last_step, table), strict=True):
                assert np.array_equal(got, want) and got.dtype == want.dtype
            assert lim.findings(goals, last, last_step, table) == _plain_findings(goals, last, last_step, table)
            fired += bool(_plain_findings(goals, last, last_step, table))
        batch = (rng.uniform(-1.5, 1.5, (7, table.n)) * cap).astype(np.int64)  # (k, n): broadcasts alike
        for got, want in zip(lim.step_bounds(batch, table), _plain_step_bounds(batch, table), strict=True):
            assert np.array_equal(got, want)
    assert fired > 100


def test_per_time_equals_the_copied_table(gate: TwinGate) -> None:
    rng = np.random.default_rng(22)
    t = gate.table
    period = gate.frame_period_s
    for _ in range(200):
        last_step = (rng.uniform(-1, 1, t.n) * t.max_step_tick).astype(np.int64)
        elapsed = float(rng.choice([0.0, -1.0, np.inf, np.nan, period * rng.uniform(0, 1.3)]))
        frac = float(rng.choice([1.0, 0.0, rng.uniform(0, 1)]))
        got = lim.per_time(t, last_step, elapsed, period, frac)
        want = _plain_per_time(t, last_step, elapsed, period, frac)
        # the fraction the gate notes for the next check (per_time used to return it too)
        assert lim.time_fraction(elapsed, period) == want[2] and np.array_equal(got[1], want[1])
        assert type(got[0]) is type(want[0]) and got[0].__dict__.keys() == want[0].__dict__.keys()
        for name, value in want[0].__dict__.items():
            mine = got[0].__dict__[name]
            assert np.array_equal(mine, value) if isinstance(value, np.ndarray) else mine == value


def _checked_map(goals: dict[int, int], rng: np.random.Generator) -> dict[Any, Any]:
    """The same goals as a map the fast path refuses (numpy ints, or another order): the checked path."""
    if rng.random() < 0.5:
        return {k: np.int64(v) for k, v in goals.items()}
    return dict(reversed(list(goals.items())))


def test_plain_goal_maps_give_the_checked_paths_verdicts(gate: TwinGate) -> None:
    """Two gates walk the same commands, one given plain int maps (the fast path), one the same goals as
    maps the fast path refuses: equal verdicts and memories every frame, with per-time caps, health and
    partial maps in the mix."""
    other = builtin_gate(gate.head.name, FRAME_PERIOD_S)
    t = gate.table
    rng = np.random.default_rng(23)
    last = t.neutral_tick.copy()
    gate.reset()
    kinds = set()
    for k in range(160):
        size = t.max_step_tick * float(rng.choice([0.3, 1.0, 3.0]))
        req = np.clip(last + rng.uniform(-1, 1, t.n) * size, t.min_tick, t.max_tick).astype(np.int64)
        goals = dict(zip(t.ids, req.tolist(), strict=True))
        if k % 7 == 3:
            goals = {i: v for i, v in list(goals.items())[::2]}  # a subset: the checked path for both
        prev = dict(zip(t.ids, last.tolist(), strict=True))
        kw: dict[str, Any] = {}
        if rng.random() < 0.6:
            kw["elapsed_s"] = gate.frame_period_s * float(rng.uniform(0.3, 1.4))
        if rng.random() < 0.2:
            kw["health"] = {int(rng.choice(t.ids)): ServoHealth(79.0, 80.0, 0.1)}
        v = gate.check(goals, prev, **kw)
        w = other.check(_checked_map(goals, rng), _checked_map(prev, rng), **kw)
        assert v == w
        assert gate.step_state().same(other.step_state())
        kinds.add(v.kind)
        last = np.array([v.goals_tick[i] for i in t.ids])
    assert {"accept", "clip"} <= kinds


def test_memory_compares_ticks_by_value(gate: TwinGate) -> None:
    """A memory restored with another integer dtype still matches the same last command (the previous step
    is kept), as `np.array_equal` would say."""
    from servoface.sim.gate.gate import GateMemory

    t = gate.table
    last = t.neutral_tick.copy()
    step = np.ones(t.n, dtype=np.int64)
    for dtype in (np.int64, np.int32):
        gate.restore_step_state(GateMemory(last.astype(dtype), step, 1.0))
        _, _, last_step = gate._rate_inputs(last, t, None, 1.0)
        assert np.array_equal(last_step, step)
        gate.restore_step_state(GateMemory((last + 1).astype(dtype), step, 1.0))
        _, _, last_step = gate._rate_inputs(last, t, None, 1.0)
        assert not last_step.any()
    gate.reset()


def test_a_command_at_rest_gives_the_full_checks_verdict(gate: TwinGate) -> None:
    """A request equal to the last command (the servos sit at it) is accepted on its position limits and
    state checks alone: the same verdicts and memories as the full check (rate caps, clamp, scale-back) on
    walks that hold often, with health narrowing the limits under a held servo, per-time caps down to 0,
    and held commands anywhere in the range (colliding, strained or outside narrowed limits)."""
    from servoface.calibration.fileformat import load_calibration

    class Straight(TwinGate):
        def _at_rest_ok(self, goal: np.ndarray, table: lim.ServoTable) -> bool:
            return False

    head = gate.head
    assert head.calibration_path is not None
    straight = Straight(head, load_calibration(head.calibration_path), gate.frame_period_s)
    t = gate.table
    rng = np.random.default_rng(29)
    last = t.neutral_tick.copy()
    gate.reset()
    held = kinds_at_rest = 0
    seen = set()
    for k in range(240):
        r = rng.random()
        if r < 0.45:
            req = last.copy()
        elif r < 0.55:
            req = last = rng.integers(t.min_tick, t.max_tick + 1).astype(np.int64)  # at rest anywhere
        else:
            size = t.max_step_tick * float(rng.choice([0.3, 1.0, 3.0]))
            req = np.clip(last + rng.uniform(-1, 1, t.n) * size, t.min_tick, t.max_tick).astype(np.int64)
        goals = dict(zip(t.ids, req.tolist(), strict=True))
        prev = dict(zip(t.ids, last.tolist(), strict=True))
        kw: dict[str, Any] = {}
        if rng.random() < 0.7:
            kw["elapsed_s"] = gate.frame_period_s * float(rng.choice([0.0, 0.5, 0.95, 1.0, 1.3]))
        if rng.random() < 0.25:
            kw["health"] = {int(i): ServoHealth(79.5, 80.0, 0.1) for i in rng.choice(t.ids, size=4, replace=False)}
        v, w = gate.check(goals, prev, **kw), straight.check(goals, prev, **kw)
        assert v == w, k
        assert gate.step_state().same(straight.step_state()), k
        if np.array_equal(req, last):
            held += 1
            kinds_at_rest += v.kind != "accept"
            seen.add(v.kind)
        last = np.array([v.goals_tick[i] for i in t.ids])
    assert held > 80 and kinds_at_rest > 3 and "accept" in seen
