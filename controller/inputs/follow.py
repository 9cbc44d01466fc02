"""Follow a live source through the pipeline on the fixed-rate loop, until a duration, a stop condition or
Ctrl-C. Like :func:`servoface.controller.performance.play_timeline` (same :class:`Performance` result), plus
``until``: a predicate checked every frame (e.g. "stdin reached end of file and the face is neutral").

For a recording (a file) use ``play_timeline(pipeline, recording, recording.duration_s)`` directly.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from servoface.controller.loop import FixedRateLoop, Tick, stop_on_sigint
from servoface.controller.performance import Performance, Samples
from servoface.controller.pipeline import FrameTrace, Pipeline


def follow(
    pipeline: Pipeline,
    source: Samples,
    duration_s: float | None = None,
    *,
    rate_hz: float | None = None,
    until: Callable[[], bool] | None = None,
    on_frame: Callable[[FrameTrace], None] | None = None,
    keep_traces: bool = True,
    stop_on_interrupt: bool = False,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> Performance:
    """Sample ``source`` every frame and run it through ``pipeline``; ``duration_s`` None = until stopped."""
    rate = float(rate_hz or pipeline.rate_hz)
    result = Performance(rate_hz=rate)

    def frame(tick: Tick) -> bool | None:
        trace = pipeline.step(source.sample(tick.t_s), tick.t_s, late_s=tick.late_s)
        if keep_traces:
            result.traces.append(trace)
        if on_frame is not None:
            on_frame(trace)
        return False if until is not None and until() else None

    loop = FixedRateLoop(frame, rate, clock=clock, sleep=sleep)
    if stop_on_interrupt and threading.current_thread() is threading.main_thread():
        with stop_on_sigint(loop):
            result.stats = loop.run(duration_s=duration_s)
    else:
        result.stats = loop.run(duration_s=duration_s)
    result.interrupted = loop.stopping
    return result
