"""Typed readers for muscle fields in a head profile: each error names the key path and what was expected."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from servoface.sim.errors import HeadProfileError

Vec3 = tuple[float, float, float]


def _fail(where: str, key: str, expected: str, got: object) -> HeadProfileError:
    return HeadProfileError(f"{where}.{key}: expected {expected}, got {got!r}")


def _number(value: object) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    out = float(value)
    return out if math.isfinite(out) else None


def require_keys(data: Mapping[str, Any], where: str, required: set[str], optional: set[str]) -> None:
    """Reject missing keys and unknown keys (a typo must not silently fall back to a default)."""
    if not isinstance(data, Mapping):
        raise HeadProfileError(f"{where}: expected a table of muscle fields, got {data!r}")
    missing = sorted(required - set(data))
    if missing:
        raise HeadProfileError(f"{where}: missing required key(s) {missing}")
    unknown = sorted(set(data) - required - optional - {"type"})
    if unknown:
        allowed = sorted(required | optional | {"type"})
        raise HeadProfileError(f"{where}: unknown key(s) {unknown}; allowed keys are {allowed}")


def vec3(data: Mapping[str, Any], key: str, where: str) -> Vec3:
    """A point or direction: a list of 3 finite numbers."""
    value = data[key]
    if not isinstance(value, list | tuple) or len(value) != 3:
        raise _fail(where, key, "a list of 3 finite numbers (mm)", value)
    nums = [_number(v) for v in value]
    if any(n is None for n in nums):
        raise _fail(where, key, "a list of 3 finite numbers (mm)", value)
    return (float(nums[0]), float(nums[1]), float(nums[2]))  # type: ignore[arg-type]


def unit3(data: Mapping[str, Any], key: str, where: str, default: Vec3) -> Vec3:
    """A direction normalised to length 1 (default when the key is absent)."""
    if key not in data:
        return default
    x, y, z = vec3(data, key, where)
    norm = math.sqrt(x * x + y * y + z * z)
    if norm < 1e-9:
        raise _fail(where, key, "a non-zero direction", data[key])
    return (x / norm, y / norm, z / norm)


def number(
    data: Mapping[str, Any],
    key: str,
    where: str,
    *,
    default: float | None = None,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
) -> float:
    """A finite number within [low, high] (or (low, high] with ``low_open``)."""
    if key not in data:
        if default is None:
            raise HeadProfileError(f"{where}: missing required key {key!r}")
        return default
    value = _number(data[key])
    lo = low if low is not None else "-inf"
    hi = high if high is not None else "inf"
    bound = f"{'(' if low_open else '['}{lo}, {hi}]"
    if value is None:
        raise _fail(where, key, f"a finite number in {bound}", data[key])
    if low is not None and (value < low or (low_open and value <= low)):
        raise _fail(where, key, f"a finite number in {bound}", data[key])
    if high is not None and value > high:
        raise _fail(where, key, f"a finite number in {bound}", data[key])
    return value


def distance(a: Vec3, b: Vec3) -> float:
    return math.sqrt(sum((p - q) ** 2 for p, q in zip(a, b, strict=True)))
