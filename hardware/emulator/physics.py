"""The mechanical and thermal model of one servo, integrated lazily between two clock readings.

Motion: the output follows its target with the velocity-based profile (bounded velocity, bounded
acceleration, decelerating to stop on target) or the time-based profile (total move time and ramp time,
Drive Mode bit 2). Units inside: ticks, ticks/s, ticks/s², seconds, amperes, °C.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

STEP_S = 0.002  # integration step while moving (exact for constant-velocity profiles)
HOLD_LOAD = 0.03  # fraction of stall current while holding position
MOVE_LOAD = 0.12  # fraction of stall current while moving unloaded
STALL_FULL_ERROR_TICK = 64.0  # position error at which a blocked servo draws stall current
THERMAL_RISE_C = 120.0  # steady-state rise above ambient at stall current
THERMAL_TAU_S = 60.0  # thermal time constant
OVERLOAD_LOAD = 0.9  # load fraction counted as overload
OVERLOAD_TRIP_S = 1.0  # sustained overload before the overload bit trips


@dataclass(slots=True)
class MotionProfile:
    """Limits of one move: ``v_max`` (ticks/s) and ``a_max`` (ticks/s², ``inf`` = step change)."""

    v_max: float
    a_max: float


@dataclass(slots=True)
class MotorState:
    """Output shaft state (raw ticks, i.e. present position minus homing offset)."""

    pos: float = 2048.0
    vel: float = 0.0
    target: float = 2048.0
    load: float = 0.0  # signed fraction of stall (-1..1)
    temperature_c: float = 25.0
    overload_s: float = 0.0  # how long load has stayed above OVERLOAD_LOAD
    stalled: bool = False

    @property
    def at_rest(self) -> bool:
        return self.vel == 0.0 and self.pos == self.target


Obstacle = tuple[float, float]  # (raw tick of the wall, side: +1 the shaft must stay above, -1 below)


def step_motion(state: MotorState, profile: MotionProfile, dt: float, obstacle: Obstacle | None) -> None:
    """Advance position/velocity by ``dt`` towards ``state.target`` under ``profile``; stop at a wall."""
    d = state.target - state.pos
    v = state.vel
    a = profile.a_max
    v_max = profile.v_max
    if d == 0.0 and v == 0.0:
        return
    direction = 1.0 if d > 0 else -1.0 if d < 0 else (-1.0 if v > 0 else 1.0)
    # fastest velocity from which we can still stop on target
    v_stop = math.sqrt(2.0 * a * abs(d)) if math.isfinite(a) else math.inf
    v_des = direction * min(v_max, v_stop)
    if math.isfinite(a):
        dv = a * dt
        v_new = min(v_des, v + dv) if v_des > v else max(v_des, v - dv)
        new_pos = state.pos + 0.5 * (v + v_new) * dt
    else:
        v_new = v_des
        new_pos = state.pos + v_new * dt
    # arrive exactly (no overshoot oscillation)
    if (state.target - new_pos) * d <= 0.0 or abs(state.target - new_pos) < 1e-6:
        new_pos = state.target
        v_new = 0.0
    if obstacle is not None and (new_pos - obstacle[0]) * obstacle[1] < 0.0:
        new_pos = obstacle[0]
        v_new = 0.0
    state.pos = new_pos
    state.vel = v_new


def blocked_by(state: MotorState, obstacle: Obstacle | None) -> bool:
    """True when the target lies beyond an obstacle the shaft is resting against."""
    if obstacle is None or abs(state.pos - obstacle[0]) > 1e-6:
        return False
    return (state.target - obstacle[0]) * obstacle[1] < -1e-6


def load_fraction(state: MotorState, torque_on: bool, obstacle: Obstacle | None, accel: float) -> float:
    """Signed load as a fraction of stall: holding, moving or pushing against an obstacle."""
    if not torque_on:
        return 0.0
    error = state.target - state.pos
    if blocked_by(state, obstacle):
        return math.copysign(min(1.0, abs(error) / STALL_FULL_ERROR_TICK), error)
    if state.vel != 0.0:
        return math.copysign(MOVE_LOAD, state.vel) + max(-0.5, min(0.5, accel * 1e-5))
    return HOLD_LOAD if error >= 0 else -HOLD_LOAD


def free_load(vel: float, error: float, accel: float) -> float:
    """``load_fraction(state, True, None, accel)`` with no obstacle, from the numbers it reads (hot path)."""
    if vel != 0.0:
        return math.copysign(MOVE_LOAD, vel) + max(-0.5, min(0.5, accel * 1e-5))
    return HOLD_LOAD if error >= 0 else -HOLD_LOAD


def step_thermal(temperature_c: float, ambient_c: float, load: float, dt: float) -> float:
    """Exact first-order response over ``dt`` at constant ``load`` (heating ∝ current²)."""
    target = ambient_c + THERMAL_RISE_C * load * load
    return target + (temperature_c - target) * math.exp(-dt / THERMAL_TAU_S)


def time_based_profile(distance: float, move_ms: int, ramp_ms: int, v_cap: float) -> MotionProfile:
    """Velocity/acceleration limits that make a trapezoid of ``move_ms`` total with ``ramp_ms`` ramps."""
    if move_ms <= 0:
        return MotionProfile(v_cap, math.inf)
    total = move_ms / 1000.0
    ramp = min(ramp_ms, move_ms // 2) / 1000.0
    d = abs(distance)
    if d == 0.0:
        return MotionProfile(v_cap, math.inf)
    v = d / (total - ramp) if total > ramp else v_cap
    v = min(v, v_cap)
    a = v / ramp if ramp > 0 else math.inf
    return MotionProfile(v, a)
