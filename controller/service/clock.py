"""The service clock: one monotonic time base for a running head.

``now_s()`` is seconds since the service was created, from ``time.monotonic`` (never jumps, never goes
backwards). Commands may carry an absolute start time on this clock (``at_s``); frame ``k`` of the loop is
scheduled at ``start_s + k / rate_hz`` on it, and every source is sampled at its frame's scheduled time,
so two heads whose clocks are aligned (see ``offset_s``) play a cue on the same frame.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from servoface.controller.service.errors import ServiceError
from servoface.controller.values import MAX_SECONDS, as_finite, printable_repr

MAX_TIME_S = 10 * 365 * 24 * 3600.0  # a service time (``at_s``) beyond ten years is a mistake


class ServiceClock:
    """Seconds since creation on a monotonic base (injectable for tests: ``base`` returns seconds)."""

    def __init__(self, base: Callable[[], float] = time.monotonic) -> None:
        self._base = base
        self._epoch_s = base()

    def __call__(self) -> float:
        return self._base() - self._epoch_s

    def now_s(self) -> float:
        return self._base() - self._epoch_s

    def to_monotonic_s(self, t_s: float) -> float:
        """Service time -> the base clock (``time.monotonic`` by default), e.g. to line up two heads."""
        return self._epoch_s + t_s

    def from_monotonic_s(self, monotonic_s: float) -> float:
        return monotonic_s - self._epoch_s


def check_time_s(value: object, *, field: str) -> float:
    """A finite time in seconds (a real number, not a bool, within +-10 years), else ServiceError naming
    ``field`` (never OverflowError / TypeError, whatever ``value`` is)."""
    number = as_finite(value)
    if number is None or abs(number) > MAX_TIME_S:
        raise ServiceError(f"{field}: expected a finite time in seconds, got {printable_repr(value)}")
    return number


def check_duration_s(value: object, *, field: str, allow_zero: bool = True) -> float:
    """A finite duration >= 0 (or > 0), at most a day, in seconds, else ServiceError naming ``field``."""
    number = as_finite(value)
    if number is None or number < 0 or (not allow_zero and number == 0) or number > MAX_SECONDS:
        bound = ">= 0" if allow_zero else "> 0"
        raise ServiceError(
            f"{field}: expected a duration {bound} s (at most {MAX_SECONDS:g} s), got {printable_repr(value)}"
        )
    return number
