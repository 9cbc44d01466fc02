"""Timeline and loop figures: cost of sampling a scripted performance per frame, and the fixed-rate loop's
lateness on the real monotonic clock (both against the 50 Hz frame budget of 20 ms)."""

from __future__ import annotations

import time
from collections.abc import Iterator

from servoface.controller.benchmarks.figure import Figure

FRAME_BUDGET_S = 1.0 / 50.0


def _sample_cost(name: str, quick: bool) -> Figure:
    from servoface.controller.script import SCRIPTS_DIR, load_script

    script = load_script(SCRIPTS_DIR / f"{name}.toml")
    times = [k / 50.0 for k in range(int(script.end_s * 50.0))]
    if quick:
        times = times[::5]
    script.sample(0.0)  # warm caches (blink and idle knots)
    t0 = time.perf_counter()
    for t in times:
        script.sample(t)
    per_frame_s = (time.perf_counter() - t0) / len(times)
    layers = ", ".join(script.timeline.layer_names)
    return Figure(
        f"timeline.sample {name}",
        per_frame_s * 1e6,
        "us/frame",
        limit=FRAME_BUDGET_S * 1e6,
        better="lower",
        note=f"{len(times)} frames, layers: {layers}; limit = the whole 50 Hz frame",
    )


def _loop_figures(quick: bool) -> Iterator[Figure]:
    from servoface.controller.loop import FixedRateLoop

    duration_s = 0.5 if quick else 2.0
    stats = FixedRateLoop(lambda tick: None, 50.0).run(duration_s=duration_s)
    yield Figure("loop achieved rate (idle callback)", stats.achieved_hz, "Hz", limit=50.0, goal_ratio=0.99)
    yield Figure(
        "loop start lateness p99",
        stats.percentile_lateness_s(99) * 1e3,
        "ms",
        limit=FRAME_BUDGET_S * 1e3 / 4,
        better="lower",
        note=f"{stats.frames} frames, {stats.missed} missed, jitter {stats.jitter_s * 1e3:.3f} ms; "
        "limit = the late threshold (a quarter period)",
    )


def run(quick: bool = False) -> Iterator[Figure]:
    yield _sample_cost("human_performance", quick)
    yield _sample_cost("dog_performance", quick)
    yield from _loop_figures(quick)
