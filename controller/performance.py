"""Playing a timeline through the pipeline on the fixed-rate loop, and what came of it.

Time-driven: frame k samples the timeline at ``start_s + k / rate`` whatever time it really is, so a late
frame is skipped (counted), never lagged. One thread (the caller's) runs the loop and owns the bus.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from servoface.controller.frame import AUFrame
from servoface.controller.loop import FixedRateLoop, LoopStats, Tick, stop_on_sigint
from servoface.controller.pipeline import FrameTrace, Pipeline
from servoface.controller.safe_stop import bus_problem
from servoface.controller.trace_ring import TraceRing


class Samples(Protocol):
    """Anything that yields an AU frame for a time: a Timeline, a Script."""

    def sample(self, t_s: float) -> AUFrame: ...


@dataclass
class Performance:
    """Traces and loop statistics of one played timeline."""

    traces: TraceRing = field(default_factory=TraceRing)  # the newest frames; counts cover every frame
    stats: LoopStats | None = None
    rate_hz: float = 50.0
    interrupted: bool = False
    bus_failure: str | None = None  # why the loop stopped early because the chain was gone

    def __post_init__(self) -> None:
        if not isinstance(self.traces, TraceRing):
            self.traces = TraceRing(self.traces)

    def __repr__(self) -> str:
        """A line a REPL can show (the frames and loop statistics are counted, not listed)."""
        achieved = "" if self.stats is None else f", achieved_hz={self.stats.achieved_hz:.1f}"
        ended = "".join(
            [
                ", interrupted=True" if self.interrupted else "",
                f", bus_failure={self.bus_failure!r}" if self.bus_failure else "",
            ]
        )
        counts = f"frames={self.traces.total}, verdicts={self.verdicts}"
        return f"Performance({counts}, rate_hz={self.rate_hz:g}{achieved}{ended})"

    @property
    def verdicts(self) -> dict[str, int]:
        counts = self.traces.verdict_counts
        return {k: counts.get(k, 0) for k in ("accept", "clip", "reject")}

    def clipped(self) -> list[FrameTrace]:
        return [t for t in self.traces if t.verdict != "accept"]

    def summary(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "frames": self.traces.total,
            "verdicts": self.verdicts,
            "target_rate_hz": self.rate_hz,
        }
        if self.stats is not None:
            out["loop"] = self.stats.summary()
        if self.traces:
            stages = self.traces[0].timings_ms.keys()
            out["median_stage_ms"] = {
                s: round(sorted(t.timings_ms[s] for t in self.traces)[len(self.traces) // 2], 4) for s in stages
            }
            out["bytes_written"] = self.traces.bytes_written
        return out


def play_timeline(
    pipeline: Pipeline,
    source: Samples,
    duration_s: float,
    *,
    rate_hz: float | None = None,
    start_s: float = 0.0,
    on_frame: Callable[[FrameTrace], None] | None = None,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
    keep_traces: bool = True,
    stop_on_interrupt: bool = False,
) -> Performance:
    """Run ``source`` through ``pipeline`` at ``rate_hz`` (default: the pipeline's) for ``duration_s``."""
    rate = float(rate_hz or pipeline.rate_hz)
    result = Performance(rate_hz=rate)
    _pace(pipeline, rate, sleep)  # the gate's caps are per frame: never two bus frames within one period

    ahead: list[tuple[float, AUFrame]] = []  # the next slot's sample, taken a frame early

    def frame(tick: Tick) -> bool | None:
        t_s = start_s + tick.t_s
        aus = ahead[0][1] if ahead and abs(ahead[0][0] - t_s) < 1e-9 else source.sample(t_s)
        t_next = start_s + tick.t_s + 1.0 / rate
        ahead[:] = [(t_next, source.sample(t_next))]
        # the next frame is computed while this one's replies are on the wire (Pipeline.step(next_frame=))
        trace = pipeline.step(aus, t_s, late_s=tick.late_s, next_frame=ahead[0][1])
        if keep_traces:
            result.traces.append(trace)
        if on_frame is not None:
            on_frame(trace)
        if (problem := bus_problem(pipeline.last_snapshot)) is not None:
            result.bus_failure = problem  # driving blind helps nobody: stop, and let the stop path report
            return False
        return None

    loop = FixedRateLoop(frame, rate, clock=clock, sleep=sleep)
    speculate = getattr(pipeline, "speculate_gate", None)
    if speculate is not None:  # paced frames have time to spare: one gate check each, never a wasted one
        pipeline.speculate_gate = False
    try:
        if stop_on_interrupt and threading.current_thread() is threading.main_thread():
            with stop_on_sigint(loop):
                result.stats = loop.run(duration_s=duration_s + 0.5 / rate)
        else:
            result.stats = loop.run(duration_s=duration_s + 0.5 / rate)
    finally:
        if speculate is not None:
            pipeline.speculate_gate = speculate
    result.interrupted = loop.stopping and result.bus_failure is None
    last_t = result.traces[-1].t_s if result.traces else None
    if (
        not result.interrupted
        and result.bus_failure is None
        and (last_t is None or last_t < start_s + duration_s - 1e-9)
    ):
        # the loop skipped the last slot(s): land the final keyframe anyway, so a motion always ends
        # where it was asked to (late, and counted as such)
        t_end = start_s + duration_s
        _pace(pipeline, rate, sleep)
        trace = pipeline.step(source.sample(t_end), t_end, late_s=0.0)
        if keep_traces:
            result.traces.append(trace)
        if on_frame is not None:
            on_frame(trace)
    return result


def _pace(pipeline: Pipeline, rate_hz: float, sleep: Callable[[float], None]) -> None:
    """Wait until one frame period has passed since the pipeline last cycled the bus (a new timeline right
    after another, or the landing frame right after the loop's last one, would otherwise double a step)."""
    last = getattr(pipeline, "last_cycle_s", None)
    if last is None:
        return
    wait_s = last + 1.0 / rate_hz - time.monotonic()
    if wait_s > 0:
        sleep(min(wait_s, 1.0 / rate_hz))
