"""Per-servo position limits and rate caps, as arrays over the head's servos (vectorised).

Rates are per control frame. ``max_step_tick`` caps |goal - last| (speed). ``max_speedup_tick`` caps how
much |step| may grow from one frame to the next in the same direction (acceleration); a step against the
previous direction may be at most ``max_speedup_tick`` (as if from rest). Slowing down is never limited:
the servo's own controller stops at its goal, and refusing to slow down would overshoot the request.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.errors import GateConfigError
from servoface.sim.gate.verdict import Finding

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]

# No-load speed in rpm at the nominal voltage (ROBOTIS e-manual); the gate uses a share of it.
NO_LOAD_SPEED_RPM: dict[str, float] = {
    "XL330-M288": 103.0,
    "XL330-M077": 383.0,
    "XC330-M288": 81.0,
    "XC330-T288": 114.0,
    "XL430-W250": 57.0,
    "XC430-W150": 106.0,
    "XM430-W350": 46.0,
    "XM430-W210": 77.0,
}
TICKS_PER_REV = 4096


@dataclass(frozen=True)
class ServoTable:
    """Limits of every servo of a head, index-aligned arrays of shape (n,)."""

    ids: tuple[int, ...]
    roles: tuple[str, ...]
    min_tick: IntArray
    max_tick: IntArray
    neutral_tick: IntArray
    max_step_tick: IntArray
    max_speedup_tick: IntArray
    # a per-time window (`per_time`) part-way through: the step from its start may not turn back on the
    # motion already made in it (the window moves one way, as one frame's step does), nor change the last
    # call's step by more than the per-frame caps allow; None elsewhere
    window_lo_tick: IntArray | None = None
    window_hi_tick: IntArray | None = None

    def __post_init__(self) -> None:
        n = len(self.ids)
        for name in ("min_tick", "max_tick", "neutral_tick", "max_step_tick", "max_speedup_tick"):
            arr = getattr(self, name)
            if arr.shape != (n,):
                raise GateConfigError(f"ServoTable.{name}: expected shape ({n},), got {arr.shape}")
        bad = [self.label(i) for i in range(n) if not self.min_tick[i] <= self.neutral_tick[i] <= self.max_tick[i]]
        if bad:
            raise GateConfigError(f"servo limits need min_tick <= neutral_tick <= max_tick; broken for {bad}")
        if np.any(self.max_step_tick < 1) or np.any(self.max_speedup_tick < 1):
            raise GateConfigError("max_step_tick and max_speedup_tick must be >= 1 tick per frame")

    @property
    def n(self) -> int:
        return len(self.ids)

    def label(self, i: int) -> str:
        return f"servo {self.ids[i]} '{self.roles[i]}'"

    def index(self) -> dict[int, int]:
        return {sid: i for i, sid in enumerate(self.ids)}

    def with_rates(self, max_step_tick: IntArray, max_speedup_tick: IntArray) -> ServoTable:
        return replace(self, max_step_tick=max_step_tick, max_speedup_tick=max_speedup_tick)


def rate_caps_tick(
    models: list[str], frame_period_s: float, speed_share: float, accel_time_s: float
) -> tuple[IntArray, IntArray]:
    """(max_step_tick, max_speedup_tick) per servo from its model's no-load speed.

    ``speed_share`` of the no-load speed is allowed; full allowed speed may be reached in ``accel_time_s``.
    """
    if frame_period_s <= 0 or not np.isfinite(frame_period_s):
        raise GateConfigError(f"frame_period_s must be a positive number, got {frame_period_s}")
    unknown = sorted({m for m in models if m not in NO_LOAD_SPEED_RPM})
    if unknown:
        raise GateConfigError(f"no speed known for servo model(s) {unknown}; known: {sorted(NO_LOAD_SPEED_RPM)}")
    rpm = np.array([NO_LOAD_SPEED_RPM[m] for m in models])
    tick_per_s = rpm / 60.0 * TICKS_PER_REV * speed_share
    step = np.maximum(1, np.floor(tick_per_s * frame_period_s)).astype(np.int64)
    frames_to_full = max(1.0, accel_time_s / frame_period_s)
    speedup = np.maximum(1, np.floor(step / frames_to_full)).astype(np.int64)
    return step, speedup


@dataclass(frozen=True)
class RateWindow:
    """What `per_time` carries from one timed check to the next: the calls of one *window* (consecutive
    calls less than a frame period apart in all) share one frame's allowance, measured from where the
    window started.

    ``start_tick``: the command the window's motion is measured from; ``end_tick``: the last command sent
    in it (the next call must start there, else the window is void); ``fraction``: share of a frame period
    the window has lasted so far; ``base_step_tick`` / ``base_fraction``: the previous window's whole step
    and the share of a period it lasted (its speed is what the speed-up cap builds on)."""

    start_tick: IntArray
    end_tick: IntArray
    fraction: float
    base_step_tick: IntArray
    base_fraction: float

    def sent(self, goals_tick: IntArray) -> RateWindow:
        """The window after ``goals_tick`` went on the wire."""
        return replace(self, end_tick=np.asarray(goals_tick, dtype=np.int64).copy())


_FULL = 1.0 - 1e-9  # a window this close to one period is a whole one (sums of many short elapsed times)


def per_time(
    table: ServoTable,
    last_tick: IntArray,
    last_step: IntArray,
    elapsed_s: float,
    frame_period_s: float,
    last_fraction: float,
    window: RateWindow | None = None,
) -> tuple[ServoTable, IntArray, IntArray, RateWindow]:
    """Rate caps for a command sent ``elapsed_s`` after ``last_tick`` went on the wire (caps are per
    ``frame_period_s``), so that the caps hold per second whatever the call pattern.

    Calls that follow each other by less than a frame period in all form one window: the window's motion
    (from its start, not from the last call) is checked against the caps of one call that came the
    window's whole time ``f`` (share of a period) after the window's start: the step cap shrinks to ``f`` of
    its own (speed per second), the speed-up cap to ``f²`` (the step's rate may grow by ``f`` of the
    per-frame speed-up: acceleration per second), and the previous window's step is taken at the same speed
    over the shorter time (never scaled up). Those caps grow with ``f``, so many calls microseconds apart
    add up to what one call a period later allows — never more (the window's caps at ``f = 1`` are the
    per-frame caps), and, unlike caps floored to whole ticks per call, they do not stall. A call that
    would take the window past a whole period starts the next window (a call a period or more after the
    last one is a window of its own: the per-frame caps). ``window`` is void (a fresh one starts, building on
    ``last_step`` over ``last_fraction`` of a period) unless it ended at ``last_tick``.

    Returns (table, rate_last_tick, rate_last_step, window): check the command's step from
    ``rate_last_tick`` (the window's start) against ``table`` after ``rate_last_step``
    (`rate_ok`, `clamp`, `findings`); store the window with `RateWindow.sent` once the command is sent."""
    if not np.isfinite(elapsed_s) or elapsed_s <= 0:
        f = 0.0
    else:
        f = min(1.0, float(elapsed_s) / frame_period_s)
    last = np.asarray(last_tick, dtype=np.int64)
    # each call also keeps the per-frame caps against the previous call's step (as one call per frame does),
    # so a window's motion comes out in steps that never speed up by more than a frame's speed-up per call
    call_lo, call_hi = step_bounds(np.asarray(last_step, dtype=np.int64), table)
    valid = window is not None and window.start_tick.shape == last.shape and np.array_equal(window.end_tick, last)
    if valid and window is not None and window.fraction < _FULL and window.fraction + f <= 2.0 - _FULL:
        grown_f = min(1.0, window.fraction + f)  # the call falls inside the window's period
        caps = _window_caps(table, window.base_step_tick, window.base_fraction, grown_f)
        moved = last - window.start_tick
        lo, hi = step_bounds(caps[1], caps[0])
        if bool(np.all((moved >= lo) & (moved <= hi))):  # (a derated servo may close it early)
            fraction = 1.0 if grown_f >= _FULL else grown_f
            lo_w = np.maximum(np.where(moved > 0, moved, np.iinfo(np.int64).min), moved + call_lo)
            hi_w = np.minimum(np.where(moved < 0, moved, np.iinfo(np.int64).max), moved + call_hi)
            return _bounded(caps[0], lo_w, hi_w), window.start_tick, caps[1], replace(window, fraction=fraction)
        base, base_fraction = moved, window.fraction
    elif valid and window is not None:
        base, base_fraction = last - window.start_tick, window.fraction  # the window closed with the last call
    else:
        base, base_fraction = np.asarray(last_step, dtype=np.int64), last_fraction
    fraction = 1.0 if f >= _FULL else f
    scaled, scaled_last = _window_caps(table, base, base_fraction, fraction)
    if not np.array_equal(base, last_step):  # (else the caps are inside the call bounds already)
        scaled = _bounded(scaled, call_lo, call_hi)
    return scaled, last, scaled_last, RateWindow(last.copy(), last.copy(), fraction, base.copy(), base_fraction)


def _bounded(table: ServoTable, lo_tick: IntArray, hi_tick: IntArray) -> ServoTable:
    """``table`` with the step (from the rate base) also kept inside [lo_tick, hi_tick] (both contain 0)."""
    out = copy.copy(table)
    object.__setattr__(out, "window_lo_tick", np.asarray(lo_tick, dtype=np.int64))
    object.__setattr__(out, "window_hi_tick", np.asarray(hi_tick, dtype=np.int64))
    return out


def _window_caps(
    table: ServoTable, base_step: IntArray, base_fraction: float, fraction: float
) -> tuple[ServoTable, IntArray]:
    """(caps, previous step) for a window lasting ``fraction`` of a period after one of ``base_fraction``."""
    f = 1.0 if fraction >= _FULL else fraction
    if f >= 1.0 and base_fraction >= _FULL:
        return table, np.asarray(base_step, dtype=np.int64)
    step = np.floor(table.max_step_tick * f).astype(np.int64)
    speedup = np.floor(table.max_speedup_tick * f * f).astype(np.int64)
    ratio = min(1.0, f / base_fraction) if base_fraction > 0 else 0.0
    scaled_last = np.trunc(base_step * ratio).astype(np.int64)
    scaled = copy.copy(table)  # caps below 1 tick are legal here (0 = hold): bypass the per-frame check
    object.__setattr__(scaled, "max_step_tick", step)
    object.__setattr__(scaled, "max_speedup_tick", speedup)
    return scaled, scaled_last


def step_bounds(last_step: IntArray, table: ServoTable) -> tuple[IntArray, IntArray]:
    """Allowed step interval [lo, hi] per servo (arrays broadcast like ``last_step``); always contains 0."""
    up = np.where(last_step > 0, last_step + table.max_speedup_tick, table.max_speedup_tick)
    down = np.where(last_step < 0, last_step - table.max_speedup_tick, -table.max_speedup_tick)
    hi = np.minimum(up, table.max_step_tick)
    lo = np.maximum(down, -table.max_step_tick)
    if table.window_lo_tick is not None and table.window_hi_tick is not None:
        lo = np.maximum(lo, table.window_lo_tick)
        hi = np.minimum(hi, table.window_hi_tick)
    return lo.astype(np.int64), hi.astype(np.int64)


def rate_ok(
    goals: IntArray, last: IntArray, last_step: IntArray, table: ServoTable
) -> tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]:
    """(limit_ok, speed_ok, accel_ok), each shaped like ``goals`` ((n,) or (k, n))."""
    step = goals - last
    limit_ok = (goals >= table.min_tick) & (goals <= table.max_tick)
    speed_ok = np.abs(step) <= table.max_step_tick
    lo, hi = step_bounds(last_step, table)
    accel_ok = (step >= lo) & (step <= hi)
    return limit_ok, speed_ok, accel_ok


def clamp(goals: IntArray, last: IntArray, last_step: IntArray, table: ServoTable) -> IntArray:
    """The nearest command per servo inside the limits and rate caps.

    When ``last`` lies outside the limits (a derated servo), the servo moves towards them at the
    allowed rate: rate caps win over position limits.
    """
    lo, hi = step_bounds(last_step, table)
    step = np.clip(goals - last, lo, hi)
    step = np.clip(step, table.min_tick - last, table.max_tick - last)
    step = np.clip(step, lo, hi)
    return np.asarray(last + step, dtype=np.int64)


def findings(goals: IntArray, last: IntArray, last_step: IntArray, table: ServoTable) -> list[Finding]:
    """One finding per servo and violated limit, with numbers."""
    out: list[Finding] = []
    step = goals - last
    lo, hi = step_bounds(last_step, table)
    bad = (goals < table.min_tick) | (goals > table.max_tick) | (step < lo) | (step > hi)
    bad |= np.abs(step) > table.max_step_tick
    for i in np.flatnonzero(bad).tolist():
        sid, role, g = table.ids[i], table.roles[i], int(goals[i])
        if g < table.min_tick[i] or g > table.max_tick[i]:
            side, lim = ("below min", table.min_tick[i]) if g < table.min_tick[i] else ("above max", table.max_tick[i])
            out.append(
                Finding(
                    "limit",
                    f"{table.label(i)}: goal {g} tick {side} {int(lim)} tick",
                    role,
                    sid,
                    float(g),
                    float(lim),
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
        elif table.window_lo_tick is not None and (s < lo[i] or s > hi[i]) and _turns_back(s, i, last_step, table):
            out.append(
                Finding(
                    "accel",
                    f"{table.label(i)}: step {s} tick turns back within one frame period or speeds up"
                    f" by more than one frame's speed-up since the last call",
                    role,
                    sid,
                    float(s),
                    float(table.window_lo_tick[i] if s < lo[i] else table.window_hi_tick[i]),  # type: ignore[index]
                    "tick",
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


def _turns_back(step: int, i: int, last_step: IntArray, table: ServoTable) -> bool:
    """True when ``step`` keeps the rate caps of servo ``i`` but not its window's direction."""
    plain = copy.copy(table)
    object.__setattr__(plain, "window_lo_tick", None)
    object.__setattr__(plain, "window_hi_tick", None)
    lo, hi = step_bounds(last_step, plain)
    return bool(lo[i] <= step <= hi[i])
