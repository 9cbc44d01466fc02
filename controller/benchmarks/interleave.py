"""Interleaved windows: every contender measured in turn, round after round, in the same run.

The machine is shared, so a rate measured alone says little; measured in short windows that alternate with a
reference (the plain stock-SDK loop, `servoface.hardware.stock_loop`), each round's ratio compares two runs
that saw the same load. A figure quotes the median window rate and the median of the per-round ratios; the
best window goes in the note.

A contender with a schedule of its own (the driver's slow telemetry: due times on its clock, read at a floor
rate when cycles run back to back) runs on an `OwnClock` that stands still while the others have their
windows: its windows then join up into one continuous run, as a loop running on its own would see them,
instead of each window opening after a long idle pause (when every group is read at once) and ending before
the next floor read comes due.
"""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

Step = Callable[[int], object]  # one cycle / frame; gets a running counter


class OwnClock:
    """Monotonic seconds that stop while paused: the time a contender has had the bus, not the wall's.

    Pass it as a `Driver`'s ``clock`` and to `interleaved` (``clocks``), which runs it only during that
    contender's windows (and its warm-up)."""

    def __init__(self) -> None:
        self._offset_s = 0.0  # paused time so far
        self._paused_at: float | None = None

    def __call__(self) -> float:
        at = self._paused_at
        return (time.monotonic() if at is None else at) - self._offset_s

    def pause(self) -> None:
        if self._paused_at is None:
            self._paused_at = time.monotonic()

    def resume(self) -> None:
        if self._paused_at is not None:
            self._offset_s += time.monotonic() - self._paused_at
            self._paused_at = None


@dataclass
class WindowStats:
    """Rates (per second) of one contender's windows, and its ratio to the reference in each round."""

    rates: list[float] = field(default_factory=list)
    ratios: list[float] = field(default_factory=list)
    count: int = 0

    @property
    def median(self) -> float:
        return float(statistics.median(self.rates)) if self.rates else 0.0

    @property
    def best(self) -> float:
        return max(self.rates, default=0.0)

    @property
    def median_ratio(self) -> float:
        return float(statistics.median(self.ratios)) if self.ratios else 0.0


def _window(step: Step, start: int, window_s: float, settle: int = 0) -> tuple[float, int]:
    for k in range(settle):  # untimed: what a contender catches up on after the others' windows
        step(start + k)
    start += settle
    n, t0 = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - t0) < window_s:
        step(start + n)
        n += 1
    return n / elapsed, n + settle


def interleaved(
    contenders: Mapping[str, Step],
    reference: str,
    rounds: int,
    window_s: float,
    warm: int = 3,
    settle: int = 0,
    clocks: Mapping[str, OwnClock] | None = None,
) -> dict[str, WindowStats]:
    """``rounds`` rounds of one ``window_s`` window per contender (order rotated each round, so no one
    always follows the same neighbour); ratios are to ``reference``'s window of the same round.

    ``settle``: untimed steps at the start of every window, for every contender alike. A driver idle
    while the others had the bus finds its slow telemetry overdue and catches up in its first cycles (two
    or three group reads per window, ~5 % of a 0.25 s window at 1 Mbps) — an artefact of taking turns
    that a loop running on its own pays once; settling measures the steady state (a contender on an `OwnClock`
    sees no pause, so has nothing to catch up).

    ``clocks``: a contender's `OwnClock`, run during its windows and warm-up only and paused otherwise (one
    clock may serve several contenders that step the same object). Every clock runs again on return."""
    names = list(contenders)
    if reference not in contenders:
        raise ValueError(f"reference {reference!r} is not among the contenders {names}")
    own = dict(clocks or {})
    for clock in own.values():
        clock.pause()
    out = {name: WindowStats() for name in names}
    for name in names:  # first cycles (group objects, caches) outside the measurement
        if name in own:
            own[name].resume()
        for k in range(warm):
            contenders[name](k)
        if name in own:
            own[name].pause()
    for r in range(rounds):
        order = names[r % len(names) :] + names[: r % len(names)]
        rates: dict[str, float] = {}
        for name in order:
            stats = out[name]
            if name in own:
                own[name].resume()
            rates[name], n = _window(contenders[name], stats.count, window_s, settle)
            if name in own:
                own[name].pause()
            stats.count += n
            stats.rates.append(rates[name])
        for name in names:
            out[name].ratios.append(rates[name] / rates[reference] if rates[reference] > 0 else 0.0)
    for clock in own.values():
        clock.resume()
    return out


def load_text() -> str:
    """The machine's load averages (1/5/15 min) and CPU count, for every figure's note."""
    try:
        one, five, fifteen = os.getloadavg()
    except OSError:
        return "load unknown"
    return f"load {one:.2f}/{five:.2f}/{fifteen:.2f} on {os.cpu_count()} cpu"
