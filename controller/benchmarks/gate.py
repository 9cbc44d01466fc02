"""`servoface bench gate`: the twin gate's cost per frame, batch throughput, and the TSS figures.

Figures (human head unless named): the cold TSS build of each built-in head (goal <= 5 s); median (goal
<= 1 ms) and p99 (goal <= 3 ms) gate time per frame on a stream of small steps, for both heads; clipped
requests; batched commands per second through ``check_batch``
(goal >= 10,000); the TSS reduction (share of sphere pairs never tested, goal >= 0.95) and misses over a
dense random sweep (goal 0); the same for the dog head; the cold TSS build time.
"""

from __future__ import annotations

import gc
import statistics
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from servoface.controller.benchmarks.figure import Figure
from servoface.controller.benchmarks.interleave import load_text

COLD_BUILD_GOAL_S = 5.0
P99_GOAL_MS = 3.0


def _gate(name: str, cache: Path | None) -> Any:
    from servoface.calibration.fileformat import load_calibration
    from servoface.sim.gate import GateConfig, TwinGate
    from servoface.sim.heads import load_head

    head = load_head(name)
    if head.calibration_path is None:
        raise FileNotFoundError(f"head '{name}' has no calibration file")
    return TwinGate(head, load_calibration(head.calibration_path), 1 / 60, GateConfig(cache_dir=cache))


def _frame_times_ms(gate: Any, frames: int, clip: bool, seed: int = 0) -> list[float]:
    """Gate wall time per frame on a random walk from neutral (small steps, or oversized ones to clip)."""
    return _frame_costs_ms(gate, frames, clip, seed)[0]


def _frame_costs_ms(gate: Any, frames: int, clip: bool, seed: int = 0) -> tuple[list[float], list[float]]:
    """(wall, CPU) ms per frame of ``gate.check`` on a random walk from neutral. CPU is this thread's
    (`time.thread_time_ns`): wall minus CPU is time the scheduler gave to others (or GC pauses, which
    count as CPU)."""
    rng = np.random.default_rng(seed)
    t = gate.table
    last = t.neutral_tick.copy()
    wall, cpu = [], []
    gate.reset()
    for _ in range(frames):
        size = t.max_step_tick * (3 if clip else 0.25)
        req = np.clip(last + rng.uniform(-1, 1, t.n) * size, t.min_tick, t.max_tick).astype(np.int64)
        goals = dict(zip(t.ids, req.tolist(), strict=True))
        prev = dict(zip(t.ids, last.tolist(), strict=True))
        c0 = time.thread_time_ns()
        t0 = time.perf_counter_ns()
        v = gate.check(goals, prev)
        wall.append((time.perf_counter_ns() - t0) * 1e-6)
        cpu.append((time.thread_time_ns() - c0) * 1e-6)
        last = np.array([v.goals_tick[i] for i in t.ids])
    return wall, cpu


def _batch_rate(gate: Any, k: int, repeats: int) -> float:
    rng = np.random.default_rng(1)
    t = gate.table
    goals = (t.neutral_tick + rng.integers(-60, 60, size=(k, t.n))).astype(np.int64)
    gate.check_batch(goals[:8], t.neutral_tick)
    best = min(_timed(lambda: gate.check_batch(goals, t.neutral_tick)) for _ in range(repeats))
    return k / best


def _timed(fn: Any) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def _misses(gate: Any, samples: int, seed: int = 3) -> tuple[int, int]:
    """(missed, found) exact collisions over random poses of every pair's joints."""
    col = gate.collisions
    tree = col.tree
    rng = np.random.default_rng(seed)
    q = rng.uniform(tree.lower_deg, tree.upper_deg, size=(samples, len(tree.names)))
    world = tree.world(q)
    flags = col.broad.flag(world, q)
    missed = found = 0
    for k in range(samples):
        for p, spec in enumerate(col.specs):
            if col._collide(spec, world[k]):
                found += 1
                missed += int(not flags[k, p])
    return missed, found


def run(quick: bool = False) -> Iterator[Figure]:
    from servoface.sim.gate.tss_build import summed_reduction

    frames = 60 if quick else 400
    for name in ("human", "dog"):
        yield _cold_build(name)
    human = _gate("human", None)  # the user cache: warm after the first run
    yield from _frame_figures("human", human, frames)
    times = _frame_times_ms(human, frames // 2, clip=True)
    yield Figure(
        "human gate time per frame (median, clipped requests)",
        statistics.median(times),
        "ms",
        better="lower",
        note=f"limits + rate clamps + scale-back search; p95 {np.percentile(times, 95):.3f} ms",
    )
    rate = _batch_rate(human, 200 if quick else 2000, 2 if quick else 5)
    yield Figure(
        "human check_batch commands per second",
        rate,
        "cmd/s",
        limit=10_000.0,
        goal=10_000.0,
        note="limits, rates, coupling, TSS broad phase",
    )
    tables = [b.table for b in human.collisions.built]
    yield Figure(
        "human TSS reduction (sphere pairs avoided)",
        summed_reduction(tables),
        "share",
        limit=0.95,
        goal=0.95,
        note=f"{human.collisions.n_tests} tests/frame of {human.collisions.n_all_sphere_pairs};"
        f" {len(human.collisions.exact_always)} pairs exact-only",
    )
    missed, found = _misses(human, 150 if quick else 1500)
    yield Figure(
        "human TSS misses (dense random sweep)",
        float(missed),
        "collisions",
        goal=0.0,
        better="lower",
        note=f"{found} exact collisions found",
    )
    dog = _gate("dog", None)
    tables = [b.table for b in dog.collisions.built]
    yield Figure(
        "dog TSS reduction (sphere pairs avoided)",
        summed_reduction(tables),
        "share",
        limit=0.95,
        goal=0.95,
        note=f"{dog.collisions.n_tests} tests/frame",
    )
    missed, found = _misses(dog, 150 if quick else 1500)
    yield Figure(
        "dog TSS misses (dense random sweep)",
        float(missed),
        "collisions",
        goal=0.0,
        better="lower",
        note=f"{found} exact collisions found",
    )
    yield from _frame_figures("dog", dog, frames)


def _cold_build(name: str) -> Figure:
    with tempfile.TemporaryDirectory() as tmp:
        t0, c0 = time.perf_counter(), time.process_time()
        gate = _gate(name, Path(tmp))
        build_s, cpu_s = time.perf_counter() - t0, time.process_time() - c0
    return Figure(
        f"{name} TSS build, cold (tables + gate)",
        build_s,
        "s",
        goal=COLD_BUILD_GOAL_S,
        better="lower",
        note=f"{len(gate.collisions.specs)} pairs tabulated, {len(gate.collisions.skipped)} proven apart, "
        f"{int(gate.collisions.clearance.proven.sum())} proven apart in their joint box by clearance tables"
        f" ({len(gate.collisions.clearance)} tables), {len(gate.collisions.plane_proven)} by a separating plane;"
        f" {len(gate.collisions.distance)} distance tables; joint-only skin proven inside the strain limits:"
        f" {gate.skin_proven[0]} edges, {gate.skin_proven[1]} triangles; process CPU {cpu_s:.2f} s;"
        f" cached afterwards; {load_text()}",
    )


def _frame_figures(name: str, gate: Any, frames: int) -> Iterator[Figure]:
    """Median and p99 gate time per frame on small steps (the accept path, plus the clips they cause):
    wall time (the goals) and this thread's CPU time beside it (what the scheduler did not take)."""
    before = sum(s["collections"] for s in gc.get_stats())
    times, cpu = _frame_costs_ms(gate, frames, clip=False)
    collections = sum(s["collections"] for s in gc.get_stats()) - before
    load = load_text()
    yield Figure(
        f"{name} gate time per frame (median, small steps)",
        statistics.median(times),
        "ms",
        limit=1.0,
        goal=1.0,
        better="lower",
        note=f"p95 {np.percentile(times, 95):.3f} ms over {frames} frames; CPU median {statistics.median(cpu):.3f} ms;"
        f" {load}",
    )
    yield Figure(
        f"{name} gate time per frame (p99, small steps)",
        float(np.percentile(times, 99)),
        "ms",
        goal=P99_GOAL_MS,
        better="lower",
        note=f"99th percentile over {frames} frames (max {max(times):.3f} ms); {load}",
    )
    yield Figure(
        f"{name} gate CPU time per frame (p99, small steps)",
        float(np.percentile(cpu, 99)),
        "ms",
        goal=P99_GOAL_MS,
        better="lower",
        note=f"this thread's CPU (time.thread_time_ns), max {max(cpu):.3f} ms: wall p99 above it is the scheduler;"
        f" {collections} garbage collections during the frames",
    )
