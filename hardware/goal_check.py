"""Goal validation: a frame is accepted whole or refused whole, before anything reaches the bus."""

from __future__ import annotations

import math
import operator
from collections.abc import Mapping

from servoface.hardware.errors import GoalRejectedError
from servoface.hardware.servo_config import ServoSpec


def check_goals(goals_tick: Mapping[int, int], specs: Mapping[int, ServoSpec]) -> dict[int, int]:
    """Every goal an integer tick (not a float, bool, NaN or inf) for a known servo, inside its configured
    ``min_position_tick..max_position_tick``; else `GoalRejectedError` naming the servo."""
    if not isinstance(goals_tick, Mapping):
        raise GoalRejectedError(None, goals_tick, f"goals must be a mapping servo id -> tick, got {type(goals_tick)}")
    out: dict[int, int] = {}
    for sid, goal in goals_tick.items():
        if type(sid) is int and type(goal) is int:  # the usual frame: plain ints, only the range to check
            spec = specs.get(sid)
            if spec is not None and spec.min_position_tick <= goal <= spec.max_position_tick:
                out[sid] = goal
                continue
        spec = specs.get(sid) if isinstance(sid, int) and not isinstance(sid, bool) else None
        if spec is None:
            raise GoalRejectedError(sid, goal, f"goal for unknown servo id {sid!r}; configured: {list(specs)}")
        if isinstance(goal, float) and not math.isfinite(goal):
            raise GoalRejectedError(sid, goal, f"{spec.label}: goal {goal!r} is not finite; nothing sent")
        if isinstance(goal, bool):
            raise GoalRejectedError(sid, goal, f"{spec.label}: goal {goal!r} is a bool, expected int ticks")
        try:
            tick = operator.index(goal)
        except TypeError:
            raise GoalRejectedError(
                sid,
                goal,
                f"{spec.label}: goal {goal!r} is not an integer tick (round it first); nothing sent",
            ) from None
        lo, hi = spec.min_position_tick, spec.max_position_tick
        if not lo <= tick <= hi:
            raise GoalRejectedError(
                sid, goal, f"{spec.label}: goal {tick} outside its limits {lo}..{hi} ticks; nothing sent"
            )
        out[sid] = tick
    return out
