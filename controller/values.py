"""Checking numbers that came from outside (a caller, a file, a message) without ever raising anything but
the controller's typed errors: huge integers (``10**400``) overflow ``float()``, ``True`` is an ``int``,
``math.isfinite`` of a huge int raises ``OverflowError``."""

from __future__ import annotations

import math
import numbers
from typing import Any

from servoface.controller.errors import ControllerError

MAX_SECONDS = 24 * 3600.0  # no single motion, hold or duration is longer than a day


def as_finite(value: Any) -> float | None:
    """``value`` as a finite float if it is a real number (not a bool) that fits, else None."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return None
    try:
        number = float(value)
    except (OverflowError, ValueError, TypeError):
        return None
    return number if math.isfinite(number) else None


def check_seconds(
    value: Any, field: str, *, minimum: float = 0.0, maximum: float = MAX_SECONDS, error: type = ControllerError
) -> float:
    """A duration in seconds within ``minimum..maximum``, else ``error`` naming ``field``."""
    number = as_finite(value)
    if number is None or not minimum <= number <= maximum:
        raise error(f"{field}: expected a number of seconds within {minimum:g}..{maximum:g}, got {_short(value)}")
    return number


def _short(value: Any) -> str:
    try:
        text = repr(value)
    except (RecursionError, ValueError):
        text = f"<{type(value).__name__} nested too deeply>"
    return text if len(text) <= 60 else text[:57] + "..."


def printable_repr(value: Any, limit: int = 60) -> str:
    """A short repr for messages, control characters and lone surrogates escaped (repr does both)."""
    return _short(value)
