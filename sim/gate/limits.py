"""Per-servo position limits and rate caps, as arrays over the head's servos (vectorised).

Rates are per control frame. ``max_step_tick`` caps |goal - last| (speed). ``max_speedup_tick`` caps how
much |step| may grow from one frame to the next in the same direction (acceleration); a step against the
previous direction may be at most ``max_speedup_tick`` (as if from rest). Slowing down is never limited:
the servo's own controller stops at its goal, and refusing to slow down would overshoot the request.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.errors import GateConfigError
from servoface.sim.gate.verdict import Finding
from servoface.sim.rig import SERVO_MODEL_ALIASES

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
    "MX-28": 55.0,  # MX-28(2.0) at 12 V; head profiles name it "MX-28" (sim.rig.SERVO_MODELS)
}
NO_LOAD_SPEED_RPM |= {alias: NO_LOAD_SPEED_RPM[name] for alias, name in SERVO_MODEL_ALIASES.items()}
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


def per_time(
    table: ServoTable, last_step: IntArray, elapsed_s: float, frame_period_s: float, last_fraction: float
) -> tuple[ServoTable, IntArray]:
    """Rate caps for a frame that follows the last one on the wire after ``elapsed_s`` (caps are per
    ``frame_period_s``): with ``f = min(1, elapsed / period)`` the step cap shrinks to ``f`` of its own (speed
    per second), the speed-up cap to ``f²`` (the step's rate may grow by ``f`` of the per-frame speed-up:
    acceleration per second), and the previous step is taken at the same speed over the shorter time (never
    scaled up), so frames sent back to back cannot add up to more than either cap per second.
    Returns (table, last_step); the gate notes ``f`` for the next check from `time_fraction`."""
    f = time_fraction(elapsed_s, frame_period_s)
    if f >= 1.0 and last_fraction >= 1.0:
        return table, last_step
    step = np.floor(table.max_step_tick * f).astype(np.int64)
    speedup = np.floor(table.max_speedup_tick * f * f).astype(np.int64)
    ratio = min(1.0, f / last_fraction) if last_fraction > 0 else 0.0
    scaled_last = np.trunc(last_step * ratio).astype(np.int64)
    # caps below 1 tick are legal here (0 = hold): bypass the per-frame check (what copy.copy does, directly)
    scaled = object.__new__(ServoTable)
    scaled.__dict__.update(table.__dict__, max_step_tick=step, max_speedup_tick=speedup)
    return scaled, scaled_last


def time_fraction(elapsed_s: float, frame_period_s: float) -> float:
    """`per_time`'s ``f``: ``min(1, elapsed / period)``, 0 for a non-finite or non-positive elapsed time."""
    if not math.isfinite(elapsed_s) or elapsed_s <= 0:
        return 0.0
    return min(1.0, float(elapsed_s) / frame_period_s)


def step_bounds(last_step: IntArray, table: ServoTable) -> tuple[IntArray, IntArray]:
    """Allowed step interval [lo, hi] per servo (arrays broadcast like ``last_step``); always contains 0.

    In integers ``where(s > 0, s + a, a)`` is ``max(s, 0) + a`` and ``where(s < 0, s - a, -a)`` is
    ``min(s, 0) - a``."""
    a, cap = table.max_speedup_tick, table.max_step_tick
    hi = np.minimum(np.maximum(last_step, 0) + a, cap)
    lo = np.maximum(np.minimum(last_step, 0) - a, -cap)
    return lo.astype(np.int64, copy=False), hi.astype(np.int64, copy=False)


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
    # |step| > max_step_tick needs no test of its own: it is outside [lo, hi] (-max_step <= lo, hi <= max_step)
    bad = (goals < table.min_tick) | (goals > table.max_tick) | (step < lo) | (step > hi)
    if not bad.any():
        return out
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
