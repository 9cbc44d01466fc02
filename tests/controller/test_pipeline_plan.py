"""A speculative clean accept checked for a planned elapsed time is what the gate gives after any longer
time (`Speculation.holds_for`): checked straight against the gate on random commands, memories and health, with
the elapsed time at, above and below the plan, and with the one accept that does not hold (a derated servo
at its narrowed limit, whose accept carries a limit finding)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator, Mapping

import numpy as np
import pytest
from servoface.controller.face import Face
from servoface.controller.pipeline_ahead import Speculation
from servoface.sim.gate import ServoHealth, TwinGate, Verdict
from servoface.sim.gate import limits as lim
from servoface.sim.gate.gate import GateMemory
from servoface.sim.gate.health import derate

from tests.controller.pipeline_pairs import au_names, face_pair, random_frames

HOT = ServoHealth(temperature_c=68.0, temperature_limit_c=70.0, load_ratio=0.2)  # strained: derated


@pytest.fixture
def face() -> Iterator[Face]:
    with face_pair() as (a, _):
        yield a


def _ahead(verdict: Verdict, plan_s: float | None) -> Speculation:
    return Speculation(verdict, b"", plan_s)


def _lo_step(gate: TwinGate, health: dict[int, ServoHealth], memory: GateMemory, elapsed_s: float) -> np.ndarray:
    """The lowest step each servo may take after ``elapsed_s`` (as the gate's rate checks bound it)."""
    table, _ = derate(gate.table, health, gate.config.health)
    caps, last_step = lim.per_time(table, memory.last_step, elapsed_s, gate.frame_period_s, memory.last_fraction)
    return lim.step_bounds(last_step, caps)[0]


def test_a_clean_accept_for_a_planned_time_is_the_verdict_after_any_longer_time(face: Face) -> None:
    gate = face.pipeline.gate
    table, period_s = gate.table, gate.frame_period_s
    ids, n = table.ids, table.n
    rng = np.random.default_rng(21)
    seen: Counter[str] = Counter()
    for _ in range(500):
        span = table.max_tick - table.min_tick
        last = table.neutral_tick + np.trunc(rng.uniform(-0.1, 0.1, n) * span).astype(np.int64)
        last = np.clip(last, table.min_tick, table.max_tick)
        health: dict[int, ServoHealth] = {}
        at_limit = None
        if rng.random() < 0.4:  # a derated servo, often beyond its narrowed range (it moves back at its rate)
            i = int(rng.integers(n))
            health[ids[i]] = HOT
            narrowed_hi = int(table.neutral_tick[i]) + int((int(table.max_tick[i]) - int(table.neutral_tick[i])) * 0.3)
            if rng.random() < 0.7 and narrowed_hi + 3 * int(table.max_step_tick[i]) < int(table.max_tick[i]):
                last[i] = narrowed_hi + 3 * int(table.max_step_tick[i])
                at_limit = i
        step_scale = rng.choice([0.0, 0.05, 0.2, 0.5])
        memory = GateMemory(
            last.copy() if rng.random() < 0.8 else None,
            np.trunc(rng.uniform(-1, 1, n) * step_scale * table.max_step_tick).astype(np.int64),
            float(rng.choice([1.0, 0.3, 0.6, 0.95])),
        )
        plan_s = float(rng.uniform(0.15, 1.1)) * period_s
        elapsed_s = plan_s * float(rng.choice([1.0, 1.0 + 1e-9, 1.002, 1.05, 1.4, 4.0, 0.97, 0.8]))
        req = last + np.trunc(rng.uniform(-1, 1, n) * rng.choice([0.02, 0.1, 0.3]) * table.max_step_tick).astype(
            np.int64
        )
        req = np.clip(req, table.min_tick, table.max_tick)
        if at_limit is not None and rng.random() < 0.7:  # the largest step back the planned caps allow
            req[at_limit] = last[at_limit] + _lo_step(gate, health, memory, plan_s)[at_limit]
        goals = dict(zip(ids, req.tolist(), strict=True))
        last_d = dict(zip(ids, last.tolist(), strict=True))
        gate.restore_step_state(memory)
        planned = gate.check(goals, last_d, health, elapsed_s=plan_s)
        gate.restore_step_state(memory)
        fresh = gate.check(goals, last_d, health, elapsed_s=elapsed_s)
        after_fresh = gate.step_state()
        seen[planned.kind] += 1
        if planned.kind == "accept" and set(planned.checks) - {"health"}:
            seen["accept with a rate finding"] += 1
            seen["... not the same later"] += fresh != planned
        if not _ahead(planned, plan_s).holds_for(elapsed_s):
            continue
        seen["holds"] += 1
        seen["holds, longer"] += elapsed_s > plan_s
        assert fresh == planned
        gate.restore_step_state(memory)
        gate.remember_check(planned, last_d, health, elapsed_s)
        assert gate.step_state().same(after_fresh)
    assert seen["holds"] > 100 and seen["holds, longer"] > 80 and seen["clip"] > 50
    assert seen["accept with a rate finding"] > 10 and seen["... not the same later"] > 3


def test_no_plan_no_elapsed_time_or_a_clip_never_holds(face: Face) -> None:
    """Without a planned time (a whole period), without the step's elapsed time (per-time caps off) or for
    a clip, the caller compares rate keys instead."""
    accept = Verdict("accept", {1: 2048}, (), 1.0, {1: 2048})
    clip = Verdict("clip", {1: 2040}, (), 0.5, {1: 2048})
    assert _ahead(accept, 0.005).holds_for(0.005) and _ahead(accept, 0.005).holds_for(0.03)
    assert not _ahead(accept, 0.005).holds_for(0.0049)
    assert not _ahead(accept, None).holds_for(0.03)
    assert not _ahead(accept, 0.005).holds_for(None)
    assert not _ahead(clip, 0.005).holds_for(0.03)


def test_every_speculation_used_back_to_back_on_the_real_clock_is_the_fresh_check(face: Face) -> None:
    """Per-time caps on, the real clock, frames back to back (clips included): the pipeline plans a short
    and a long elapsed time, waits for the long one when a frame comes before it, and uses a speculation
    when it holds. Every used one is what a fresh check with the step's own inputs, memory and elapsed time
    gives (checked after the run, from the memory recorded at each step, so the checks do not disturb the
    timing)."""
    p = face.pipeline
    p.per_time_caps = True
    p.temperature_limits_c = {}
    gate = p.gate
    frames = random_frames(au_names(p), 240, seed=31, jump=0.05, move=0.5, sigma=0.03)
    noted: list[tuple[object, ...]] = []
    remember = gate.remember_check

    def noting(
        verdict: Verdict,
        last: Mapping[int, int],
        health: Mapping[int, ServoHealth] | None = None,
        elapsed_s: float | None = None,
    ) -> None:
        noted.append((verdict, elapsed_s))
        remember(verdict, last, health, elapsed_s)

    gate.remember_check = noting  # type: ignore[method-assign]
    used: list[tuple[object, ...]] = []
    for k, aus in enumerate(frames):
        state, last, health = gate.step_state(), dict(p.last_goals_tick), p._health()
        noted.clear()
        trace = p.step(aus, next_frame=frames[k + 1] if k + 1 < len(frames) else None)
        if "ahead_ms" in trace.timings_ms:
            assert len(noted) == 1
            used.append((state, last, health, trace.goals_requested, *noted[0]))
    gate.remember_check = remember  # type: ignore[method-assign]
    kinds: Counter[str] = Counter()
    for state, last, health, requested, verdict, elapsed_s in used:
        gate.restore_step_state(state)  # type: ignore[arg-type]
        fresh = gate.check(requested, last, health, elapsed_s=elapsed_s)  # type: ignore[arg-type]
        assert fresh == verdict
        kinds[fresh.kind] += 1
    assert sum(kinds.values()) > 15, kinds  # (how many depends on the machine's timing; the equality does not)
