"""One measured figure, printed by `servoface bench` next to what it is measured against."""

from __future__ import annotations

import json
import os
import platform
from dataclasses import dataclass
from typing import Any, Literal


class SuiteUnavailable(RuntimeError):
    """A suite cannot run on this machine (an optional dependency is missing); the message says why."""


@dataclass(frozen=True)
class Figure:
    """A benchmark result.

    ``limit`` is what the value is compared with (a wire limit, a frame budget, a peer), ``ratio`` = value /
    limit (or limit / value for "lower is better" figures, see ``better``: a ratio is always "higher is
    better"). A goal is a threshold the figure should meet: ``goal`` on the value itself (in ``unit``) or
    ``goal_ratio`` on the ratio. It is a **floor** when higher is better and a **ceiling** when lower is.
    A "lower is better" figure with a limit and no goal has its limit as its ceiling (a budget).
    """

    name: str
    value: float
    unit: str
    limit: float | None = None
    goal: float | None = None
    better: Literal["higher", "lower"] = "higher"
    note: str = ""
    goal_ratio: float | None = None

    @property
    def ratio(self) -> float | None:
        if self.limit is None or self.limit == 0 or self.value == 0:
            return None
        return self.value / self.limit if self.better == "higher" else self.limit / self.value

    @property
    def goal_kind(self) -> Literal["floor", "ceiling"]:
        return "floor" if self.better == "higher" else "ceiling"

    def goal_text(self) -> str | None:
        """The goal in words, e.g. ``ratio >= 0.9 (floor)`` or ``<= 1 ms (ceiling)``; None without one."""
        op = ">=" if self.better == "higher" else "<="
        if self.goal_ratio is not None:
            return f"ratio >= {self.goal_ratio:g} (floor)"
        goal = self._value_goal()
        if goal is None:
            return None
        return f"{op} {goal:g} {self.unit} ({self.goal_kind})"

    def _value_goal(self) -> float | None:
        if self.goal is not None:
            return self.goal
        if self.better == "lower" and self.limit is not None:
            return self.limit
        return None

    @property
    def meets(self) -> bool | None:
        """True/False against the goal; None when the figure has no goal."""
        if self.goal_ratio is not None:
            ratio = self.ratio
            return ratio is not None and ratio >= self.goal_ratio
        goal = self._value_goal()
        if goal is None:
            return None
        return self.value >= goal if self.better == "higher" else self.value <= goal

    @property
    def verdict(self) -> str:
        meets = self.meets
        return "-" if meets is None else "meets" if meets else "short"

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name, "value": round(self.value, 6), "unit": self.unit}
        if self.limit is not None:
            out["limit"] = round(self.limit, 6)
        if self.goal is not None:
            out["goal"] = self.goal
        if self.goal_ratio is not None:
            out["goal_ratio"] = self.goal_ratio
        ratio = self.ratio
        if ratio is not None:
            out["ratio"] = round(ratio, 4)
        if (text := self.goal_text()) is not None:
            out["goal_kind"] = self.goal_kind if self.goal_ratio is None else "floor"
            out["goal_text"] = text
            out["verdict"] = self.verdict
        if self.note:
            out["note"] = self.note
        return out

    def to_json(self) -> str:
        return json.dumps(self.as_dict())


def machine_description() -> str:
    """A one-line description of the machine, printed with every bench run."""
    return f"{platform.machine()} {os.cpu_count()} cpu, Python {platform.python_version()}, {platform.system()}"
