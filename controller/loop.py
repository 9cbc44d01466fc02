"""A fixed-rate loop on a monotonic clock, with deadline accounting.

Frame k is due at ``start + k * period``. The loop calls ``callback(tick)`` once per frame it runs; a
frame whose slot has passed entirely by the time the loop gets to it is **skipped** (counted in
``missed``), never queued or run late in a burst: the loop jumps to the newest due frame, so the callback
sees ``tick.t_s = k * period`` and samples a time-driven timeline on time. A frame started more than
``late_after_s`` (default: a quarter period) after its due time is counted ``late``; a callback that runs
past the next frame's due time is an ``overrun``.

Clock and sleep are injectable (``clock() -> seconds``, ``sleep(seconds)``) so tests use a fake clock. The
loop stops when ``stop()`` is called (from the callback, another thread or a signal handler), when the
callback returns False, or after ``max_frames`` / ``duration_s``. Sleeping happens in slices of at most
``max_sleep_s`` so a stop request or Ctrl-C is honoured promptly; a KeyboardInterrupt propagates to the
caller after the stats are closed (``stop_on_sigint`` turns Ctrl-C into a clean stop instead).
"""

from __future__ import annotations

import math
import signal
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

from servoface.controller.errors import LoopError

Clock = Callable[[], float]
Sleep = Callable[[float], None]


@dataclass
class RunningStat:
    """Count, mean, standard deviation and max of a stream (Welford)."""

    count: int = 0
    mean: float = 0.0
    _m2: float = 0.0
    max: float = 0.0

    def add(self, x: float) -> None:
        self.count += 1
        delta = x - self.mean
        self.mean += delta / self.count
        self._m2 += delta * (x - self.mean)
        self.max = x if self.count == 1 else max(self.max, x)

    @property
    def std(self) -> float:
        return math.sqrt(self._m2 / self.count) if self.count > 1 else 0.0


@dataclass
class LoopStats:
    """What the loop did. Times in seconds of the loop's clock."""

    rate_hz: float
    frames: int = 0  # callbacks run
    missed: int = 0  # frames skipped because their slot had passed
    late: int = 0  # frames started more than late_after_s after their due time
    overruns: int = 0  # callbacks that ended after the next frame was due
    elapsed_s: float = 0.0
    lateness_s: RunningStat = field(default_factory=RunningStat)  # start - due, per frame run
    callback_s: RunningStat = field(default_factory=RunningStat)
    stages_s: dict[str, RunningStat] = field(default_factory=dict)
    recent_lateness_s: deque[float] = field(default_factory=lambda: deque(maxlen=1000))

    @property
    def achieved_hz(self) -> float:
        """Frames run per second of elapsed loop time (0 before the first full period)."""
        return self.frames / self.elapsed_s if self.elapsed_s > 0 else 0.0

    @property
    def jitter_s(self) -> float:
        """Standard deviation of the start lateness of the frames that ran."""
        return self.lateness_s.std

    def percentile_lateness_s(self, q: float) -> float:
        """q-th percentile (0..100) of the start lateness over the last 1000 frames."""
        data = sorted(self.recent_lateness_s)
        if not data:
            return 0.0
        index = min(len(data) - 1, max(0, math.ceil(q / 100.0 * len(data)) - 1))
        return data[index]

    def summary(self) -> dict[str, Any]:
        return {
            "rate_hz": self.rate_hz,
            "achieved_hz": round(self.achieved_hz, 3),
            "frames": self.frames,
            "missed": self.missed,
            "late": self.late,
            "overruns": self.overruns,
            "jitter_ms": round(1e3 * self.jitter_s, 3),
            "lateness_p99_ms": round(1e3 * self.percentile_lateness_s(99), 3),
            "lateness_max_ms": round(1e3 * self.lateness_s.max, 3),
            "callback_mean_ms": round(1e3 * self.callback_s.mean, 3),
            "callback_max_ms": round(1e3 * self.callback_s.max, 3),
            "stages_mean_ms": {k: round(1e3 * v.mean, 3) for k, v in self.stages_s.items()},
        }


@dataclass
class Tick:
    """One frame handed to the callback. ``t_s`` = ``index * period_s``: sample the timeline here."""

    index: int
    t_s: float
    due_s: float  # absolute clock time the frame was due
    started_s: float
    missed_before: int  # frames skipped just before this one
    _clock: Clock
    _stages: dict[str, RunningStat]

    @property
    def late_s(self) -> float:
        return self.started_s - self.due_s

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time a stage of the frame: ``with tick.stage("gate"): ...`` (mean/max land in stats)."""
        t0 = self._clock()
        try:
            yield
        finally:
            self._stages.setdefault(name, RunningStat()).add(self._clock() - t0)


class FixedRateLoop:
    """Call ``callback(tick)`` at ``rate_hz`` (default 50 Hz) on a monotonic clock schedule."""

    def __init__(
        self,
        callback: Callable[[Tick], bool | None],
        rate_hz: float = 50.0,
        *,
        clock: Clock = time.monotonic,
        sleep: Sleep = time.sleep,
        late_after_s: float | None = None,
        max_sleep_s: float = 0.05,
    ) -> None:
        if isinstance(rate_hz, bool) or not isinstance(rate_hz, int | float) or not math.isfinite(rate_hz):
            raise LoopError(f"rate_hz: expected a finite rate in Hz, got {rate_hz!r}")
        if not 0 < rate_hz <= 10_000:
            raise LoopError(f"rate_hz: expected 0 < rate <= 10000 Hz, got {rate_hz!r}")
        self.callback = callback
        self.rate_hz = float(rate_hz)
        self.period_s = 1.0 / self.rate_hz
        self.late_after_s = self.period_s / 4 if late_after_s is None else float(late_after_s)
        if not self.late_after_s >= 0:
            raise LoopError(f"late_after_s: expected >= 0 s, got {late_after_s!r}")
        if not max_sleep_s > 0:
            raise LoopError(f"max_sleep_s: expected > 0 s, got {max_sleep_s!r}")
        self.max_sleep_s = float(max_sleep_s)
        self._clock = clock
        self._sleep = sleep
        self._stop = threading.Event()
        self._running = threading.Lock()
        self.stats = LoopStats(self.rate_hz)

    def stop(self) -> None:
        """Ask the loop to stop after the current frame (safe from any thread or a signal handler)."""
        self._stop.set()

    @property
    def stopping(self) -> bool:
        return self._stop.is_set()

    def _wait_until(self, when_s: float) -> None:
        while not self._stop.is_set():
            remaining = when_s - self._clock()
            if remaining <= 0:
                return
            self._sleep(min(remaining, self.max_sleep_s))

    def run(self, *, max_frames: int | None = None, duration_s: float | None = None) -> LoopStats:
        """Run until stopped; returns the stats (also kept in ``self.stats``)."""
        if not self._running.acquire(blocking=False):
            raise LoopError("this loop is already running; one run at a time")
        try:
            self._stop.clear()
            self.stats = stats = LoopStats(self.rate_hz)
            start = self._clock()
            k = 0
            try:
                while not self._stop.is_set():
                    if max_frames is not None and stats.frames >= max_frames:
                        break
                    due = start + k * self.period_s
                    if duration_s is not None and k * self.period_s >= duration_s:
                        break
                    self._wait_until(due)
                    if self._stop.is_set():
                        break
                    now = self._clock()
                    newest = int(math.floor((now - start) / self.period_s + 1e-9))
                    skipped = 0
                    if newest > k:  # frame k's slot has passed: skip to the newest due frame
                        skipped = newest - k
                        if duration_s is not None:
                            skipped = min(skipped, max(0, math.ceil(duration_s / self.period_s - 1e-9) - k))
                        k += skipped
                        stats.missed += skipped
                        if duration_s is not None and k * self.period_s >= duration_s:
                            break
                        due = start + k * self.period_s
                    tick = Tick(k, k * self.period_s, due, now, skipped, self._clock, stats.stages_s)
                    lateness = now - due
                    stats.lateness_s.add(lateness)
                    stats.recent_lateness_s.append(lateness)
                    if lateness > self.late_after_s:
                        stats.late += 1
                    keep_going = self.callback(tick)
                    end = self._clock()
                    stats.frames += 1
                    stats.callback_s.add(end - now)
                    if end > due + self.period_s:
                        stats.overruns += 1
                    stats.elapsed_s = end - start
                    if keep_going is False:
                        break
                    k += 1
            finally:
                stats.elapsed_s = max(stats.elapsed_s, self._clock() - start)
            return stats
        finally:
            self._running.release()


@contextmanager
def stop_on_sigint(loop: FixedRateLoop) -> Iterator[None]:
    """Within the block, Ctrl-C stops ``loop`` cleanly instead of raising (main thread only; restores the
    previous handler on exit). A second Ctrl-C raises KeyboardInterrupt as usual."""
    from servoface.controller import stop_signals

    installed = stop_signals.active()
    if installed is not None:  # the CLI's handlers (SIGINT, SIGTERM, SIGHUP) stop the loop; they never raise
        with installed.watching(loop):
            yield
        return
    previous = signal.getsignal(signal.SIGINT)

    def handler(signum: int, frame: Any) -> None:
        if loop.stopping:
            raise KeyboardInterrupt
        loop.stop()

    signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
