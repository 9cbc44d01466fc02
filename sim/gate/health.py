"""Thermal and load state of the servos (from the driver's telemetry) and how it narrows the gate.

``sim`` never imports ``hardware``: the controller converts the driver's snapshot into `ServoHealth`
records keyed by servo id. A hot or overloaded servo keeps only a share of its range around neutral and a
share of its speed, so it can rest near neutral instead of straining at the end of its travel.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
from servoface.sim.gate.errors import GateInputError
from servoface.sim.gate.limits import ServoTable
from servoface.sim.gate.verdict import Finding


@dataclass(frozen=True)
class ServoHealth:
    """One servo's state. ``load_ratio`` = |present load| / rated load (0..1+); ``overloaded`` and ``hot``
    are the driver's flags (hardware-error overload bit, temperature at or near the limit)."""

    temperature_c: float
    temperature_limit_c: float
    load_ratio: float
    overloaded: bool = False
    hot: bool = False

    def __post_init__(self) -> None:
        for name in ("temperature_c", "temperature_limit_c", "load_ratio"):
            if not math.isfinite(getattr(self, name)):
                raise GateInputError(f"ServoHealth.{name} must be finite, got {getattr(self, name)}")

    def strained(self, hot_margin_c: float, load_limit: float) -> bool:
        """True when the gate should derate this servo."""
        return (
            self.hot
            or self.overloaded
            or self.temperature_c >= self.temperature_limit_c - hot_margin_c
            or self.load_ratio >= load_limit
        )


@dataclass(frozen=True)
class HealthPolicy:
    """How much a strained servo keeps: ``range_share`` of each side of its travel around neutral and
    ``speed_share`` of its speed. Strained = flagged hot/overloaded, within ``hot_margin_c`` of the
    temperature limit, or ``load_ratio`` >= ``load_limit``."""

    range_share: float = 0.3
    speed_share: float = 0.5
    hot_margin_c: float = 5.0
    load_limit: float = 0.9


def derate(
    table: ServoTable, health: Mapping[int, ServoHealth] | None, policy: HealthPolicy
) -> tuple[ServoTable, list[Finding]]:
    """The table narrowed for strained servos, and one ``health`` finding per strained servo.

    Unknown ids in ``health`` are a contract violation (`GateInputError`): telemetry for a servo the head
    does not have means the controller wired the wrong head.
    """
    if not health:
        return table, []
    index = table.index()
    unknown = sorted(set(health) - set(index))
    if unknown:
        raise GateInputError(f"health given for unknown servo id(s) {unknown}; head servos are {list(table.ids)}")
    lo, hi = table.min_tick.copy(), table.max_tick.copy()
    step, speedup = table.max_step_tick.copy(), table.max_speedup_tick.copy()
    found: list[Finding] = []
    for sid, h in health.items():
        if not h.strained(policy.hot_margin_c, policy.load_limit):
            continue
        i = index[sid]
        n = int(table.neutral_tick[i])
        lo[i] = n - int(math.floor((n - int(lo[i])) * policy.range_share))
        hi[i] = n + int(math.floor((int(hi[i]) - n) * policy.range_share))
        step[i] = max(1, int(step[i] * policy.speed_share))
        speedup[i] = max(1, int(speedup[i] * policy.speed_share))
        why = ", ".join(
            w
            for w, on in (
                ("hot", h.hot or h.temperature_c >= h.temperature_limit_c - policy.hot_margin_c),
                ("overloaded", h.overloaded or h.load_ratio >= policy.load_limit),
            )
            if on
        )
        found.append(
            Finding(
                "health",
                f"{table.label(i)} {why} ({h.temperature_c:.0f}/{h.temperature_limit_c:.0f} C, load "
                f"{h.load_ratio:.2f}): range narrowed to {lo[i]}..{hi[i]} tick, speed {step[i]} tick/frame",
                table.roles[i],
                sid,
                h.temperature_c,
                h.temperature_limit_c,
                "C",
            )
        )
    narrowed = replace(table, min_tick=lo, max_tick=hi, max_step_tick=step, max_speedup_tick=np.maximum(1, speedup))
    return narrowed, found
