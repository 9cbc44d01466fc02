"""Easing curves u -> e(u) on [0, 1] with e(0) = 0, e(1) = 1, monotone non-decreasing.

- ``linear``: Barker's piecewise-linear interpolation (muscle-models.md §2: no easing).
- ``ease_in_out``: cosine ease, 0.5 - 0.5 cos(pi u); zero velocity at both ends.
- ``min_jerk``: Flash & Hogan minimum-jerk profile 10u^3 - 15u^4 + 6u^5; zero velocity and acceleration
  at both ends (the natural choice for servos: no step in commanded acceleration).
- ``step``: holds 0 until u = 1 (a cut).
"""

from __future__ import annotations

import math
from collections.abc import Callable

from servoface.controller.errors import TimelineError

Easing = Callable[[float], float]


def _clamp01(u: float) -> float:
    return 0.0 if u <= 0.0 else 1.0 if u >= 1.0 else u


def linear(u: float) -> float:
    return 0.0 if u <= 0.0 else 1.0 if u >= 1.0 else u  # (`_clamp01` inline: called per AU per frame)


def ease_in_out(u: float) -> float:
    return 0.5 - 0.5 * math.cos(math.pi * _clamp01(u))


def min_jerk(u: float) -> float:
    u = 0.0 if u <= 0.0 else 1.0 if u >= 1.0 else u  # (`_clamp01` inline)
    return u * u * u * (10.0 + u * (-15.0 + 6.0 * u))


def step(u: float) -> float:
    return 1.0 if u >= 1.0 else 0.0


EASINGS: dict[str, Easing] = {
    "linear": linear,
    "ease_in_out": ease_in_out,
    "min_jerk": min_jerk,
    "step": step,
}


def easing_by_name(name: str, *, field: str = "easing") -> Easing:
    """Look up an easing by name; TimelineError names the field and the known names."""
    try:
        return EASINGS[name]
    except (KeyError, TypeError):
        raise TimelineError(f"{field}: unknown easing {name!r}; expected one of {', '.join(EASINGS)}") from None


def easing_name(fn: Easing) -> str:
    """The registered name of an easing function (``"custom"`` if not registered)."""
    for name, candidate in EASINGS.items():
        if candidate is fn:
            return name
    return "custom"
